"""Make ``capture/data/view_shifts.json``: what the angle a face is seen at adds to its head-frame points.

    python benchmarks/view_shifts.py [--seeds 0-2,4,6-9,11-12] [--cache DIR]

ICT identities of tuning seeds (never the reporting seeds 100 and up), each rendered at rest (512 px,
``roundtrip_ict``'s portrait colouring) with the head turning, the camera still (``head_pose_ict``'s
turn: yaw to +-20 degrees and back, then pitch to +-12 and back), tracked and captured as ``animate``
does (neutral frames 0-9) without the correction this table makes and without the noise floor
(``capture.noisefloor``, which would drop the view's smaller shifts). The face does not move in its
head frame, so every displacement the capture reports is what the view adds: MediaPipe reconstructs
a face differently from different angles. A ridge fit (over every identity's frames) maps the
angle the camera sees the face at (``capture.headframe.view_features``: the direction to the camera in
the head frame, x, y and their squares and product, less their mean on the neutral frames) to each
landmark's displacement; ``capture.headframe.unview`` takes it out of every capture.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

RIDGE = 1e-2  # on the features' squared sums (~1000 frames); 1e-4 to 1e-2 alike on identities left out


def main(argv=None) -> int:
    import head_pose_ict as H
    from ict_scenario import ict_missing, load_ict

    import faceanim.capture.headframe as headframe
    from faceanim.errors import InputError

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="0-2,4,6-9,11-12")
    parser.add_argument("--ridge", type=float, default=RIDGE)
    parser.add_argument("--cache", type=Path, help="keep the seeds' tracks here")
    parser.add_argument("--output", type=Path,
                        default=Path(__file__).resolve().parents[1] / "src/faceanim/capture/data/view_shifts.json")
    args = parser.parse_args(argv)
    if ict_missing():
        return 0
    seeds = H.seeds_of(args.seeds)
    if any(s >= 100 for s in seeds):
        raise SystemExit("seeds 100 and up are the reporting pairs: not for making the table")
    if args.cache is not None:
        args.cache.mkdir(parents=True, exist_ok=True)
    model = load_ict()
    features, moves, used = [], [], []
    headframe._view_table = lambda: np.zeros((5, 478 * 3))  # the capture without the correction
    for seed in seeds:
        try:
            track = H.turned_track(model, seed, args.cache)
        except InputError as exc:  # the portrait's colouring places MediaPipe's points on A automatically
            print(f"seed {seed}: refused ({exc}), left out", flush=True)
            continue
        if not track.usable.all():
            print(f"seed {seed}: frames without a face, left out", flush=True)
            continue
        motion = headframe.track_to_motion(track, neutral=(0, 10), floor=False)  # the view's smaller shifts too
        f = headframe.view_features(np.asarray(motion.pose))
        features.append(f - f[:10].mean(axis=0))
        moves.append(np.asarray(motion.displacements).reshape(len(f), -1))
        used.append(seed)
        print(f"seed {seed}: tracked", flush=True)
    held = []  # each identity's displacements against a table made without it
    for k in range(len(used)):
        X = np.concatenate(features[:k] + features[k + 1:])
        Y = np.concatenate(moves[:k] + moves[k + 1:])
        left = moves[k] - features[k] @ _ridge(X, Y, args.ridge)
        held.append((np.sqrt((moves[k].reshape(len(left), -1, 3) ** 2).sum(-1).mean()),
                     np.sqrt((left.reshape(len(left), -1, 3) ** 2).sum(-1).mean())))
    held = np.array(held) * 10.0
    table = _ridge(np.concatenate(features), np.concatenate(moves), args.ridge)
    content = {"made_by": "python benchmarks/view_shifts.py --seeds " + args.seeds + f" --ridge {args.ridge:g}",
               "how": " ".join(__doc__.split("\n\n")[2].split()),
               "seeds": used, "frames": int(sum(map(len, features))), "ridge": args.ridge,
               "features": ["x", "y", "x*x", "y*y", "x*y"],
               "held_out_identity_rms_mm": {"before": [round(float(v), 3) for v in held[:, 0]],
                                            "after": [round(float(v), 3) for v in held[:, 1]]},
               "shift_cm_per_feature": [[round(float(v), 5) for v in row] for row in table]}
    args.output.write_text(json.dumps(content) + "\n")
    print(f"{len(used)} identities; RMS displacement of a still face turned, identities left out: "
          f"{np.median(held[:, 0]):.2f} mm -> {np.median(held[:, 1]):.2f} mm (median)")
    return 0


def _ridge(X, Y, ridge: float) -> np.ndarray:
    return np.linalg.solve(X.T @ X + ridge * np.eye(X.shape[1]), X.T @ Y)


if __name__ == "__main__":
    sys.exit(main())
