"""The speaker's articulatory model on the shared speech clips: held-out fit, PCA against guided, and
the interpretation's speed (issue 17, parts 1 and 5).

    flock /tmp/faceanim-bench.lock python benchmarks/speaker_model.py

For ``speech_man.mp4`` (125 frames) and ``speech_woman.mp4`` (199): the video is tracked as ``faceanim
speaker build`` tracks it and cut into 6 contiguous blocks. Each fold holds one block out and builds
the model on the frames more than 0.2 s away from it (a guard, so that neighbouring frames do not
leak into the measure). Fold 0 of each clip is the tuning fold (the only one looked at while choosing
the model's construction); folds 1-5 of both clips are the 10 reporting draws, of which the median and
the worst are given. Measures on the held-out frames, over the lip and jaw feature points (2.x, 8.x;
the goal's) and over all the mobile points:

* variance explained, two ways, with the same numerator (the squared residual: what the model's
  nearest shape, least squares over its K parameters, misses):
  - **about the block's own mean** (strict): the block's own variance as the denominator. A block
    is ~1 s here, so a shift of the lips' mean posture between blocks counts fully as a miss and
    little as variance;
  - **about the model's rest** (the building frames' mean, as for Q^2 / PRESS): the squared
    deviation from what a model of no parameters predicts, which explains 0% by construction;
* what the miss is made of: its share that is constant over the block (the block's mean miss) and
  the tracker's noise, from second differences (white noise of variance s^2 gives 1.5 s^2), as
  shares of the block's own variance;
* RMS point error (mm) over the mobile points;
* FAP error (FAPU, RMS) of the held-out frames' tracked FAPs (``motion_to_faps`` of the capture) decoded
  through the model from all 34 of its FAPs and from the 8 of the ICP figure (3, 14, 16, 17, 51-54).

Pooled: each clip's 5 reporting blocks taken together (the squared misses summed over their frames,
over the summed variances), the figure per clip; also over the lip and jaw points a FAP measures
(2.1-2.10, 8.1-8.8: MediaPipe's 2.11-2.14, the chin's and jaw's corners on the face's outline, have
no FAP).

What the miss constant over a block is made of (reporting draws): its RMS (mm); the share of it a
rigid motion of the lips and jaw explains (a head frame turned or shifted for the block); the share of
the whole miss on the jaw's corners 2.13/2.14; and, per clip over all frames, how much of the motion
of the nose's base 9.15 (a static point) and of 2.13/2.14 in the head frame follows the tracker's head
angles (R^2 of a linear fit on yaw, pitch and roll: head pose left in the head frame). Two corrections
of the head frame measured (not adopted; see the results): a per-frame rigid refit of every point onto
the steadier half of the static points (least spread over the building frames), and the part of every
point's motion linear in the head angles (fitted on the building frames) taken out.

Also the earlier protocol for comparison (alternate 2-second blocks, 2 folds a clip: 4 draws, half of
each clip held out, so the held-out mean is nearly the clip's).

Speed: ``SpeakerModel.regularise`` on 100,000 frames made by the model (all 34 FAPs; 4 subsets mixed
frame by frame: 34, 26, 8, 6 FAPs), frame by frame and with the temporal prior, median and worst of 5
runs; and as ``fap-decompress --speaker`` decodes by default, smoothed within 25-frame windows and
kept within the cells, on the same frames coded at quant 16 (3 runs). Writes ``benchmarks/results/speaker_model.md``.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from report import publish  # noqa: E402

os.environ.setdefault("GLOG_minloglevel", "2")
VIDEOS = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "videos"
CLIPS = ("speech_man", "speech_woman")
FOLDS = 6
GUARD_SECONDS = 0.2
TUNING = 0
BLOCK_SECONDS = 2.0  # the earlier protocol's
COUNTS = (1, 2, 3, 4, 5, 6, 7, 8)
EIGHT = (3, 14, 16, 17, 51, 52, 53, 54)
SIX = (3, 16, 51, 52, 53, 54)
TWENTY_SIX = tuple(range(3, 19)) + tuple(range(51, 61))  # the lips and jaw
METHODS = ("pca", "guided")


def folds(motion):
    """[(fold, train mask, test mask)]: 6 contiguous blocks, each held out in turn, the frames within
    0.2 s of it left out of the building."""
    n = len(motion)
    edges = np.linspace(0, n, FOLDS + 1).round().astype(int)
    guard = int(round(GUARD_SECONDS * motion.fps))
    out = []
    for fold in range(FOLDS):
        test = np.zeros(n, bool)
        test[edges[fold]:edges[fold + 1]] = True
        near = np.zeros(n, bool)
        near[max(0, edges[fold] - guard):min(n, edges[fold + 1] + guard)] = True
        out.append((fold, ~near & motion.valid, test & motion.valid))
    return out


def alternate_folds(motion):
    """The earlier protocol: alternate 2-second blocks (fold A: built on blocks 0, 2, ...)."""
    block = (np.arange(len(motion)) // int(round(BLOCK_SECONDS * motion.fps))) % 2
    return [("A", (block == 0) & motion.valid, (block == 1) & motion.valid),
            ("B", (block == 1) & motion.valid, (block == 0) & motion.valid)]


def only(stream, numbers):
    from faceanim.mpeg4.fapstream import FapStream

    keep = np.zeros(stream.mask.shape[1], bool)
    keep[np.array(numbers) - 1] = True
    return FapStream(stream.values, stream.mask & keep, stream.fps)


FAP_POINTS = tuple(f"2.{i}" for i in range(1, 11)) + tuple(f"8.{i}" for i in range(1, 9))  # a FAP measures them
JAW_CORNERS = ("2.13", "2.14")


def rigid_share(points: np.ndarray, shift: np.ndarray) -> float:
    """The share of ``shift (P, 3)`` (a constant miss) that a small rigid motion of ``points (P, 3)``
    explains (least squares over a rotation vector and a translation)."""
    centred = points - points.mean(axis=0)
    A = np.zeros((3 * len(points), 6))
    for i, (x, y, z) in enumerate(centred):
        A[3 * i:3 * i + 3, :3] = [[0, z, -y], [-z, 0, x], [y, -x, 0]]
        A[3 * i:3 * i + 3, 3:] = np.eye(3)
    fitted = A @ np.linalg.lstsq(A, shift.reshape(-1), rcond=None)[0]
    return 1 - ((shift.reshape(-1) - fitted) ** 2).sum() / (shift**2).sum()


def head_angles(motion) -> np.ndarray:
    """(T, 3) the tracker's head yaw, pitch and roll (degrees)."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(motion.pose[:, :3, :3]).as_euler("yxz", degrees=True)


def pose_share(motion, names) -> float:
    """R^2 of the points ``names``' head-frame motion on a linear fit of the head angles (valid frames)."""
    angles = head_angles(motion)[motion.valid]
    d = motion.displacements[motion.valid][:, motion.index(names)].reshape(int(motion.valid.sum()), -1)
    X = np.c_[angles, np.ones(len(angles))]
    fitted = X @ np.linalg.lstsq(X, d, rcond=None)[0]
    return 1 - ((d - fitted) ** 2).sum() / ((d - d.mean(axis=0)) ** 2).sum()


def rigid_refit(motion, train):
    """Each frame's points moved rigidly so that the steadier half of the static points (least spread
    over ``train``) best match their neutral positions."""
    from faceanim.motion import Motion
    from faceanim.speaker import mobile_names

    moving = set(mobile_names(motion))
    static = [n for n in motion.names if n not in moving]
    spread = motion.displacements[train][:, motion.index(static)].std(axis=0).sum(axis=-1)
    anchors = motion.index([static[i] for i in np.argsort(spread)[:len(static) // 2]])
    X = motion.neutral[None] + motion.displacements
    out = X.copy()
    target = motion.neutral[anchors]
    for t in np.flatnonzero(motion.valid):
        source = X[t, anchors]
        H = (source - source.mean(axis=0)).T @ (target - target.mean(axis=0))
        U, _, Vt = np.linalg.svd(H)
        R = Vt.T @ np.diag([1, 1, np.sign(np.linalg.det(Vt.T @ U.T))]) @ U.T
        out[t] = (X[t] - source.mean(axis=0)) @ R.T + target.mean(axis=0)
    d = out - motion.neutral[None]
    d[~motion.valid] = 0
    return Motion(motion.names, motion.neutral, d, motion.pose, motion.fps, motion.fapu, valid=motion.valid)


def angles_out(motion, train):
    """Every point's motion less its linear fit on the head angles over ``train``."""
    from faceanim.motion import Motion

    angles = head_angles(motion)
    centred = angles - angles[train].mean(axis=0)
    d = motion.displacements.reshape(len(motion), -1)
    X = np.c_[centred, np.ones(len(motion))]
    coefficients = np.linalg.lstsq(X[train], d[train], rcond=None)[0]
    out = (d - centred @ coefficients[:3]).reshape(motion.displacements.shape)
    out[~motion.valid] = 0
    return Motion(motion.names, motion.neutral, out, motion.pose, motion.fps, motion.fapu, valid=motion.valid)


def measure(motion, faps, model, test) -> dict:
    from faceanim.speaker import reconstruction_error

    missed = reconstruction_error(model, motion, test)
    seen = model.neutral + motion.displacements[test][:, motion.index(model.names)]
    own = (seen - seen.mean(axis=0)) ** 2
    about_rest = (seen - model.rest) ** 2
    lips = np.array([n.startswith(("2.", "8.")) for n in model.names])
    points = np.array([n in FAP_POINTS for n in model.names])
    corners = np.array([n in JAW_CORNERS for n in model.names])
    second = seen[1:-1] - 0.5 * (seen[:-2] + seen[2:])
    noise = (second[:, lips] ** 2).mean() / 1.5 * seen[:, lips].size
    constant = len(missed) * (missed[:, lips].mean(axis=0) ** 2).sum()
    j = model.fap_columns
    tracked = faps.values[test][:, j]
    fap_rms = {}
    for label, numbers in (("all", None), ("8", EIGHT)):
        sent = faps if numbers is None else only(faps, numbers)
        decoded = model.regularise(sent).values[test][:, j]
        fap_rms[label] = float(np.sqrt(((decoded - tracked) ** 2).mean()))
    squared = (missed[:, lips] ** 2).sum()
    shift = missed[:, lips].mean(axis=0)
    sums = {}
    for name, where in (("lips", lips), ("points", points)):
        sums[f"{name}:miss"] = float((missed[:, where] ** 2).sum())  # summed, for pooling (see pooled)
        sums[f"{name}:own"], sums[f"{name}:rest"] = float(own[:, where].sum()), float(about_rest[:, where].sum())
    return {**sums, "explained": 1 - (missed**2).sum() / own.sum(),
            "points": 1 - sums["points:miss"] / sums["points:own"],
            "points_rest": 1 - sums["points:miss"] / sums["points:rest"],
            "shift_mm": 10 * float(np.sqrt((shift**2).sum(axis=-1).mean())),
            "rigid": rigid_share(model.rest[lips], shift),
            "corners": float((missed[:, corners] ** 2).sum() / squared),
            "lips": 1 - squared / own[:, lips].sum(),
            "lips_rest": 1 - squared / about_rest[:, lips].sum(),
            "constant": constant / own[:, lips].sum(), "noise": noise / own[:, lips].sum(),
            "rms_mm": 10 * float(np.sqrt((missed**2).sum(axis=-1).mean())),
            "fap_all": fap_rms["all"], "fap_8": fap_rms["8"]}


def pooled(rows, name: str, part: str) -> float:
    """1 - the summed squared misses over the summed variances (``part``: own or rest) of ``rows``."""
    return 1 - sum(r[f"{name}:miss"] for r in rows) / sum(r[f"{name}:{part}"] for r in rows)


def summary(values, worst) -> str:
    return f"{np.median(values):.1f} ({worst(values):.1f})"


def speed(model, frames=100_000, runs=5) -> list[str]:
    from faceanim.mpeg4.fapstream import FapStream

    rng = np.random.default_rng(0)
    truth = model.to_faps(rng.normal(size=(frames, model.parameter_count)))
    mixed_mask = truth.mask.copy()
    subsets = [None, TWENTY_SIX, EIGHT, SIX]
    pick = rng.integers(len(subsets), size=frames)
    for k, numbers in enumerate(subsets):
        if numbers is not None:
            keep = np.zeros(truth.mask.shape[1], bool)
            keep[np.array(numbers) - 1] = True
            mixed_mask[pick == k] &= keep
    mixed = FapStream(truth.values, mixed_mask, truth.fps)
    lines = ["| stream | decoding | frames | median frames/s | worst frames/s |", "|---|---|---:|---:|---:|"]
    for label, stream in (("all 34 FAPs on every frame", truth), ("34, 26, 8 or 6 FAPs, mixed frame by frame", mixed)):
        for temporal in (False, True):
            rates = []
            for _ in range(runs):
                start = time.perf_counter()
                model.regularise(stream, temporal=temporal)
                rates.append(frames / (time.perf_counter() - start))
            how = "temporal prior" if temporal else "frame by frame"
            lines.append(f"| {label} | {how} | {frames:,} | {np.median(rates):,.0f} | {min(rates):,.0f} |")
    # fap-decompress's default: smoothed within each packet (25 frames), kept within the cells, on a coded stream
    from faceanim.mpeg4.fapcoder import decode_faps, encode_faps

    coded = decode_faps(encode_faps(FapStream(np.rint(truth.values), truth.mask, truth.fps), quant=16))
    rates = []
    for _ in range(3):
        start = time.perf_counter()
        model.regularise(coded, quant=16, temporal=True, window=25)
        rates.append(frames / (time.perf_counter() - start))
    lines.append(f"| all 34 FAPs coded at quant 16 | smoothed in 25-frame windows, within the cells (3 runs) | "
                 f"{frames:,} | {np.median(rates):,.0f} | {min(rates):,.0f} |")
    return lines


def main() -> None:
    from faceanim.inputs import capture_motion
    from faceanim.motion import motion_to_faps
    from faceanim.speaker import build_model

    results, earlier, corrections, leaks = {}, {}, {}, {}
    speed_model = None
    for clip in CLIPS:
        motion = capture_motion(VIDEOS / f"{clip}.mp4", progress=False, floor=False)  # as speaker build
        faps = motion_to_faps(motion)
        for fold, train, test in folds(motion):
            for method in METHODS:
                for count in COUNTS:
                    model = build_model(motion, parameters=count, frames=train, method=method)
                    results[clip, fold, method, count] = measure(motion, faps, model, test)
                    if speed_model is None and count == 6 and method == "guided":
                        speed_model = model
        for fold, train, test in folds(motion):
            for label, correct in (("rigid refit", rigid_refit), ("head angles out", angles_out)):
                corrected = correct(motion, train)
                model = build_model(corrected, parameters=6, frames=train, method="guided")
                corrections[clip, fold, label] = measure(corrected, motion_to_faps(corrected), model, test)
        leaks[clip] = {"9.15": pose_share(motion, ["9.15"]), "2.13/2.14": pose_share(motion, list(JAW_CORNERS))}
        for fold, train, test in alternate_folds(motion):
            for method in METHODS:
                model = build_model(motion, parameters=6, frames=train, method=method)
                earlier[clip, fold, method] = measure(motion, faps, model, test)
        print(f"{clip}: {len(motion)} frames, {FOLDS} folds", flush=True)
    reporting = [(c, f) for c in CLIPS for f in range(FOLDS) if f != TUNING]
    lines = ["# Speaker model: held-out fit on the shared speech clips", "",
             "`flock /tmp/faceanim-bench.lock python benchmarks/speaker_model.py` (tracker: the Face Landmarker). "
             f"Each clip in {FOLDS} contiguous blocks, each held out in turn, the model built on the frames more "
             f"than {GUARD_SECONDS:g} s away from it; fold {TUNING} of each clip is the tuning fold, folds 1-5 of both "
             "clips the 10 reporting draws (median, worst in brackets). Lips and jaw: feature points 2.x and 8.x (the "
             "goal's, >= 90% with 6 parameters). Own mean: variance about the held-out block's own mean (strict); "
             "rest: about the model's rest, the building frames' mean (Q^2: no parameters explain 0%). FAP error: "
             "the held-out frames' tracked FAPs (motion_to_faps) against the same decoded through the model from all "
             "34 of its FAPs or from the 8 of the ICP figure (FAPU, RMS over the 34).", "",
             "## Six parameters, reporting draws: median (worst)", "",
             "| method | lips and jaw, own mean | lips and jaw, rest | all mobile points, own mean | RMS error (mm) "
             "| miss constant over the block | tracker noise | FAP error from 34 | FAP error from 8 |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for method in METHODS:
        cells = []
        for key, scale, worst in (("lips", 100, min), ("lips_rest", 100, min), ("explained", 100, min),
                                  ("rms_mm", 1, max), ("constant", 100, max), ("noise", 100, max),
                                  ("fap_all", 1, max), ("fap_8", 1, max)):
            cells.append(summary([results[c, f, method, 6][key] * scale for c, f in reporting], worst))
        lines.append(f"| {method} | " + " | ".join(cells) + " |")
    lines += ["", "Miss constant over the block, tracker noise: shares of the block's own lip and jaw variance (so "
              "the strict figure's miss is their sum and the rest, ~100% minus it).", "",
              "## Six parameters, each clip's 5 reporting blocks pooled", "",
              "| clip | method | lips and jaw, own mean | lips and jaw, rest | FAP points, own mean "
              "| FAP points, rest |",
              "|---|---|---:|---:|---:|---:|"]
    for clip in CLIPS:
        for method in METHODS:
            rows = [results[clip, f, method, 6] for f in range(FOLDS) if f != TUNING]
            lines.append(f"| {clip} | {method} | " + " | ".join(
                f"{100 * pooled(rows, name, part):.1f}" for name in ("lips", "points") for part in ("own", "rest"))
                + " |")
    lines += ["", "FAP points: 2.1-2.10 and 8.1-8.8, the lip and jaw points a FAP measures.", "",
              "The goal's measure is the rest figure (Q^2, as PRESS): the miss against the variance the same frames "
              "have about what a model of no parameters predicts, its rest, so that both sides measure the same "
              "deviations. The strict figure divides the same miss by the variance about the block's own mean: a "
              "~1 s block's offset from the rest (a posture held, a run of open vowels) is counted in the miss but "
              "not in the variance, so a block with little motion scores low however well it is fitted "
              "(speech_man fold 2: 72.7% strict, 94.6% rest). With half of each clip held out (the earlier "
              "protocol, below) the two nearly agree. Both are reported.", "",
              "## What the miss constant over a block is (guided, six parameters)", "",
              "| clip | fold | constant miss RMS (mm) | of it, rigid | jaw corners' share of the miss | "
              "lips and jaw, own mean / rest |", "|---|---:|---:|---:|---:|---:|"]
    for clip in CLIPS:
        for f in range(FOLDS):
            r = results[clip, f, "guided", 6]
            lines.append(f"| {clip} | {f}{' (tuning)' if f == TUNING else ''} | {r['shift_mm']:.2f} | "
                         f"{100 * r['rigid']:.0f}% | {100 * r['corners']:.0f}% | "
                         f"{100 * r['lips']:.1f} / {100 * r['lips_rest']:.1f} |")
    lines += ["", "Head pose left in the head frame (all frames): R^2 of a linear fit on the tracker's yaw, pitch "
              "and roll of " + "; ".join(f"{clip}: 9.15 (static) {100 * leaks[clip]['9.15']:.0f}%, 2.13/2.14 "
                                         f"{100 * leaks[clip]['2.13/2.14']:.0f}%" for clip in CLIPS) + ".", "",
              "## Corrections of the head frame measured (guided, six parameters; not adopted)", "",
              "| clip | correction | fold 0 (tuning) | folds 1-5 | pooled, lips and jaw own / rest |",
              "|---|---|---:|---:|---:|"]
    for clip in CLIPS:
        for label, source in (("none", None), ("rigid refit", "rigid refit"), ("head angles out", "head angles out")):
            rows = [results[clip, f, "guided", 6] if source is None else corrections[clip, f, source]
                    for f in range(FOLDS)]
            reporting_rows = [r for f, r in enumerate(rows) if f != TUNING]
            tuning = rows[TUNING]
            lines.append(f"| {clip} | {label} | {100 * tuning['lips']:.1f} / {100 * tuning['lips_rest']:.1f} | "
                         + ", ".join(f"{100 * r['lips']:.1f} / {100 * r['lips_rest']:.1f}" for r in reporting_rows)
                         + f" | {100 * pooled(reporting_rows, 'lips', 'own'):.1f} / "
                         f"{100 * pooled(reporting_rows, 'lips', 'rest'):.1f} |")
    lines += ["", "## Six parameters, every fold (lips and jaw, own mean / rest)", "",
              "| clip | method | " + " | ".join(f"fold {f}{' (tuning)' if f == TUNING else ''}" for f in range(FOLDS))
              + " |", "|---|---|" + "---:|" * FOLDS]
    for clip in CLIPS:
        for method in METHODS:
            row = [results[clip, f, method, 6] for f in range(FOLDS)]
            lines.append(f"| {clip} | {method} | " + " | ".join(
                f"{100 * r['lips']:.1f} / {100 * r['lips_rest']:.1f}" for r in row) + " |")
    lines += ["", "## Against the number of parameters, reporting draws: median (worst)", "",
              "| K | PCA lips and jaw, own mean | guided | PCA lips and jaw, rest | guided | PCA FAP error from 8 "
              "| guided |", "|---:|---:|---:|---:|---:|---:|---:|"]
    for count in COUNTS:
        cells = []
        for key, scale, worst in (("lips", 100, min), ("lips_rest", 100, min), ("fap_8", 1, max)):
            for method in METHODS:
                cells.append(summary([results[c, f, method, count][key] * scale for c, f in reporting], worst))
        lines.append(f"| {count} | " + " | ".join(cells) + " |")
    tuning = {method: [results[c, TUNING, method, 6] for c in CLIPS] for method in METHODS}
    lines += ["", "## Tuning folds, six parameters (lips and jaw own mean / rest; FAP error from 8)", "",
              "| method | " + " | ".join(CLIPS) + " |", "|---|" + "---:|" * len(CLIPS)]
    for method in METHODS:
        lines.append(f"| {method} | " + " | ".join(
            f"{100 * r['lips']:.1f}% / {100 * r['lips_rest']:.1f}%; {r['fap_8']:.1f}" for r in tuning[method]) + " |")
    closer = {key: sum(results[c, f, "guided", 6][key] < results[c, f, "pca", 6][key] for c, f in reporting)
              for key in ("fap_all", "fap_8")}
    lines += ["", f"Six parameters: the guided model decodes the held-out tracked FAPs closer than PCA in "
              f"{closer['fap_all']} of {len(reporting)} reporting draws from all 34 FAPs and {closer['fap_8']} of "
              f"{len(reporting)} from 8. `faceanim speaker build` uses guided by default.", "",
              "## The earlier protocol (alternate 2-second blocks, 4 draws), six parameters: median (worst)", "",
              "| method | lips and jaw, own mean | lips and jaw, rest | all mobile points, own mean |",
              "|---|---:|---:|---:|"]
    draws = [(c, f) for c in CLIPS for f in ("A", "B")]
    for method in METHODS:
        lines.append(f"| {method} | " + " | ".join(
            summary([earlier[c, f, method][key] * 100 for c, f in draws], min)
            for key in ("lips", "lips_rest", "explained")) + " |")
    lines += ["", "## Interpretation speed (regularise), model of speech_man fold 0, 6 parameters", ""]
    lines += speed(speed_model)
    publish("speaker_model.md", lines)


if __name__ == "__main__":
    main()
