"""How far the skull's landmarks seem to move with expressions on a still head (``results/skull_shifts.json``).

    python benchmarks/skull_shifts.py [--seeds 0-2,4-12] [--cache DIR]

ICT identities of tuning seeds (never the reporting seeds 100 and up), each rendered (512 px, front,
``roundtrip_ict``'s portrait colouring) with a STILL head performing a long script of ICT's expressions
one at a time (each eased in and out over 12 frames), tracked by the Face Landmarker. The head is still,
so the true head frame on every frame is the one on the neutral frames: each frame's landmarks are
carried into that frame (MediaPipe's own per-frame geometry, then its pose against the mean pose on the
neutral frames; each frame's shift and size, which one image leaves loose, fitted on the skull's
landmarks and taken out). What is left is how far each skull landmark seems to move although the skull
did not: MediaPipe's depths shift with expressions. A linear map from the Face Landmarker's 52 scores
(less their mean on the neutral frames) to those moves is fitted (ridge), with each landmark's spread
(the RMS of its move). ``head_pose_ict.py --tried`` scores two head fits made from this table, tried
for issue 16 and NOT adopted (neither holds the head stiller than the capture's robust fit on the
tuning pairs): the skull's landmarks weighed by their spread, and the moves the scores call for taken
out of them before the fit.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

# ICT expressions performed one at a time (pairs L/R together); the eye's look directions are left
# out (the eyeballs turn, the skull landmarks do not move).
EXPRESSIONS = (("jawOpen",), ("mouthSmile_L", "mouthSmile_R"), ("eyeBlink_L", "eyeBlink_R"),
               ("browInnerUp_L", "browInnerUp_R", "browOuterUp_L", "browOuterUp_R"), ("browDown_L", "browDown_R"),
               ("eyeSquint_L", "eyeSquint_R"), ("eyeWide_L", "eyeWide_R"), ("cheekPuff_L", "cheekPuff_R"),
               ("cheekSquint_L", "cheekSquint_R"), ("mouthFunnel",), ("mouthPucker",),
               ("mouthStretch_L", "mouthStretch_R"),
               ("mouthFrown_L", "mouthFrown_R"), ("mouthPress_L", "mouthPress_R"), ("mouthRollLower", "mouthRollUpper"),
               ("mouthShrugLower", "mouthShrugUpper"), ("mouthUpperUp_L", "mouthUpperUp_R"),
               ("mouthLowerDown_L", "mouthLowerDown_R"), ("noseSneer_L", "noseSneer_R"), ("jawForward",),
               ("jawLeft",), ("mouthLeft",), ("mouthDimple_L", "mouthDimple_R"), ("eyeBlink_L",),
               ("browInnerUp_L", "browInnerUp_R"))
REST, LENGTH = 10, 12
RIDGE = 1.0  # on the scores' squared sums (~3000 frames): chosen by identities left out, 0.01-10 alike


def script(model) -> np.ndarray:
    """(T, 53) weights: rest, then each of EXPRESSIONS eased 0 -> 1 -> 0."""
    ease = np.sin(np.linspace(0, np.pi, LENGTH)) ** 2
    weights = [np.zeros((REST, len(model.expression_names)))]
    for names in EXPRESSIONS:
        w = np.zeros((LENGTH, len(model.expression_names)))
        for name in names:
            w[:, model.expression_names.index(name)] = ease
        weights.append(w)
    return np.concatenate(weights)


def still_track(model, seed: int, cache: Path | None):
    """The tracked render of identity A (of ``seed``) performing :func:`script` with a still head."""
    from head_pose_ict import performed_track

    return performed_track(model, seed, script(model), None if cache is None else cache / f"skull_{seed}.npz")

def seen_moves(track) -> np.ndarray:
    """``(T, L, 3)``: each frame's landmarks in the neutral frames' head frame, less their neutral (cm)."""
    from faceanim.capture.headframe import _skull_weights
    from faceanim.capture.metric import metric_geometry_frames

    points, pose = metric_geometry_frames(track.landmarks, track.width, track.height)
    # One image fits a face of any size at a matching distance: each frame's reconstruction is scaled
    # about the camera to the neutral frames' size before it is compared with them.
    size = np.cbrt(np.linalg.det(pose[:, :3, :3]))
    pose = pose.copy()
    pose[:, :3] *= (size[:REST].mean() / size)[:, None, None]
    reference = np.linalg.inv(pose[:REST].mean(axis=0))
    relative = reference @ pose
    carried = np.einsum("tij,tlj->tli", relative[:, :3, :3], points) + relative[:, None, :3, 3]
    rest = carried[:REST].mean(axis=0)
    # The depth MediaPipe's geometry gives a frame (and so its size) is loose: every point moves with
    # it. The turn is known (none); each frame's shift and size are fitted on the skull's landmarks
    # and taken out, and what is left is each landmark's own move.
    skull = np.flatnonzero(_skull_weights() > 0)
    for t in range(len(carried)):
        c, r = carried[t, skull], rest[skull]
        cc, rc = c - c.mean(axis=0), r - r.mean(axis=0)
        size = (cc * rc).sum() / (cc * cc).sum()
        carried[t] = (carried[t] - c.mean(axis=0)) * size + r.mean(axis=0)
    return carried - rest


def main(argv=None) -> int:
    from head_pose_ict import seeds_of
    from ict_scenario import ict_missing, load_ict

    from faceanim.capture.headframe import _skull_weights
    from faceanim.errors import InputError

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="0-2,4-12")
    parser.add_argument("--ridge", type=float, default=RIDGE)
    parser.add_argument("--cache", type=Path, help="keep the seeds' tracks here")
    parser.add_argument("--output", type=Path,
                        default=Path(__file__).resolve().parent / "results" / "skull_shifts.json")
    args = parser.parse_args(argv)
    if ict_missing():
        return 0
    seeds = seeds_of(args.seeds)
    if any(s >= 100 for s in seeds):
        raise SystemExit("seeds 100 and up are the reporting pairs: not for making the table")
    if args.cache is not None:
        args.cache.mkdir(parents=True, exist_ok=True)
    model = load_ict()
    skull = np.flatnonzero(_skull_weights() > 0)
    scores, moves, squares, used = [], [], [], []
    for seed in seeds:
        try:
            track = still_track(model, seed, args.cache)
        except InputError as exc:  # the portrait's colouring places MediaPipe's points on A automatically
            print(f"seed {seed}: refused ({exc}), left out", flush=True)
            continue
        if not track.usable.all() or track.blendshapes is None:
            print(f"seed {seed}: frames without a face or scores, left out", flush=True)
            continue
        scores.append(track.blendshapes - track.blendshapes[:REST].mean(axis=0))
        seen = seen_moves(track)[:, :468]
        moves.append(seen[:, skull].reshape(len(track), -1))
        squares.append((seen ** 2).sum(-1))
        used.append(seed)
        print(f"seed {seed}: tracked", flush=True)
    X, Y = np.concatenate(scores), np.concatenate(moves)
    held = []  # each identity's moves predicted by a table made without it
    for k in range(len(used)):
        out = np.zeros(len(X), bool)
        out[sum(map(len, scores[:k])):sum(map(len, scores[:k + 1]))] = True
        table = _ridge(X[~out], Y[~out], args.ridge)
        held.append((((Y[out] - X[out] @ table) ** 2).sum(), (Y[out] ** 2).sum()))
    explained = 1 - sum(h[0] for h in held) / sum(h[1] for h in held)
    table = _ridge(X, Y, args.ridge)
    spread = np.sqrt(np.concatenate(squares).mean(axis=0))
    content = {"made_by": "python benchmarks/skull_shifts.py --seeds " + args.seeds + f" --ridge {args.ridge:g}",
               "how": " ".join(__doc__.split("\n\n")[2].split()),
               "seeds": used, "frames": int(len(X)), "ridge": args.ridge,
               "explained_held_out_identity": round(float(explained), 4),
               "landmarks": [int(i) for i in skull], "scores": list(track.blendshape_names),
               "spread_all_cm": [round(float(v), 5) for v in spread],
               "shift_cm_per_score": [[round(float(v), 6) for v in row] for row in table]}
    args.output.write_text(json.dumps(content, indent=0) + "\n")
    print(f"{len(used)} identities, {len(X)} frames; moves explained on identities left out: {explained:.1%}")
    return 0


def _ridge(X, Y, ridge: float) -> np.ndarray:
    return np.linalg.solve(X.T @ X + ridge * np.eye(X.shape[1]), X.T @ Y)


if __name__ == "__main__":
    sys.exit(main())
