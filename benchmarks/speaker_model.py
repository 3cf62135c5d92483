"""The speaker's articulatory model on the shared speech clips: held-out fit, PCA against guided, and
the interpretation's speed (issue 17, parts 1 and 5).

    flock /tmp/faceanim-bench.lock python benchmarks/speaker_model.py

For ``speech_man.mp4`` and ``speech_woman.mp4``: the video is tracked as ``faceanim speaker build``
tracks it, cut into 2-second blocks, and the model is built on alternate blocks and measured on the
others (fold A: built on blocks 0, 2, ...; fold B: on blocks 1, 3, ...), so neighbouring frames do
not leak into the measure. Measures on the held-out frames:

* variance explained: 1 - (sum of squared residuals) / (sum of squared deviations from the held-out
  frames' own mean), the residual being what the model's nearest shape (least squares over its K
  parameters) misses; over all mobile points, and over the lip and jaw feature points (2.x, 8.x);
* RMS point error (mm) over the mobile points;
* FAP error (FAPU, RMS) of the held-out frames' tracked FAPs (``motion_to_faps`` of the capture) decoded
  through the model from all 30 of its FAPs and from the 8 of the ICP figure (3, 14, 16, 17, 51-54).

Speed: ``SpeakerModel.regularise`` on 100,000 frames made by the model (all 30 FAPs; 4 subsets mixed
frame by frame: 30, 26, 8, 6 FAPs), median and worst of 5 runs. Writes
``benchmarks/results/speaker_model.md``.
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
BLOCK_SECONDS = 2.0
COUNTS = (1, 2, 3, 4, 5, 6, 7, 8)
EIGHT = (3, 14, 16, 17, 51, 52, 53, 54)
SIX = (3, 16, 51, 52, 53, 54)
TWENTY_SIX = tuple(range(3, 19)) + tuple(range(51, 61))  # the lips and jaw: the 30 without the cheeks


def folds(motion):
    """(name, train mask, test mask) for alternate 2-second blocks."""
    block = (np.arange(len(motion)) // int(round(BLOCK_SECONDS * motion.fps))) % 2
    return [("A", block == 0, block == 1), ("B", block == 1, block == 0)]


def only(stream, numbers):
    from faceanim.mpeg4.fapstream import FapStream

    keep = np.zeros(stream.mask.shape[1], bool)
    keep[np.array(numbers) - 1] = True
    return FapStream(stream.values, stream.mask & keep, stream.fps)


def measure(motion, faps, model, test) -> dict:
    from faceanim.speaker import reconstruction_error

    missed = reconstruction_error(model, motion, test)
    seen = motion.displacements[test][:, motion.index(model.names)]
    spread = (seen - seen.mean(axis=0)) ** 2
    lips = np.array([n.startswith(("2.", "8.")) for n in model.names])
    j = model.fap_columns
    tracked = faps.values[test][:, j]
    fap_rms = {}
    for label, numbers in (("all", None), ("8", EIGHT)):
        sent = faps if numbers is None else only(faps, numbers)
        decoded = model.regularise(sent).values[test][:, j]
        fap_rms[label] = float(np.sqrt(((decoded - tracked) ** 2).mean()))
    return {"explained": 1 - (missed**2).sum() / spread.sum(),
            "lips": 1 - (missed[:, lips] ** 2).sum() / spread[:, lips].sum(),
            "rms_mm": 10 * float(np.sqrt((missed**2).sum(axis=-1).mean())),
            "fap_all": fap_rms["all"], "fap_8": fap_rms["8"]}


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
    lines = ["| stream | frames | median frames/s | worst frames/s |", "|---|---:|---:|---:|"]
    for label, stream in (("all 30 FAPs on every frame", truth), ("30, 26, 8 or 6 FAPs, mixed frame by frame", mixed)):
        rates = []
        for _ in range(runs):
            start = time.perf_counter()
            model.regularise(stream)
            rates.append(frames / (time.perf_counter() - start))
        lines.append(f"| {label} | {frames:,} | {np.median(rates):,.0f} | {min(rates):,.0f} |")
    return lines


def main() -> None:
    from faceanim.inputs import capture_motion
    from faceanim.motion import motion_to_faps
    from faceanim.speaker import build_model

    results = {}
    speed_model = None
    for clip in CLIPS:
        motion = capture_motion(VIDEOS / f"{clip}.mp4", progress=False)
        faps = motion_to_faps(motion)
        for fold, train, test in folds(motion):
            for method in ("pca", "guided"):
                for count in COUNTS:
                    model = build_model(motion, parameters=count, frames=train, method=method)
                    results[clip, fold, method, count] = measure(motion, faps, model, test)
                    if speed_model is None and count == 6 and method == "guided":
                        speed_model = model
            print(f"{clip} fold {fold}: {int(train.sum())} frames to build, {int(test.sum())} held out", flush=True)
    lines = ["# Speaker model: held-out fit on the shared speech clips", "",
             "`flock /tmp/faceanim-bench.lock python benchmarks/speaker_model.py`. Built on alternate 2-second "
             "blocks, measured on the others (folds A and B, see the script). Variance explained about the held-out "
             "frames' own mean. FAP error: the held-out frames' tracked FAPs (motion_to_faps) against the same "
             "decoded through the model from all 30 of its FAPs or from the 8 of the ICP figure (FAPU, RMS over the "
             "30).", "", "## Six parameters, per clip and fold", "",
             "| clip | fold | method | variance explained, mobile points | lips and jaw (2.x, 8.x) | RMS error (mm) "
             "| FAP error from 30 | FAP error from 8 |", "|---|---|---|---:|---:|---:|---:|---:|"]
    for clip in CLIPS:
        for fold in ("A", "B"):
            for method in ("pca", "guided"):
                r = results[clip, fold, method, 6]
                lines.append(f"| {clip} | {fold} | {method} | {100 * r['explained']:.1f}% | {100 * r['lips']:.1f}% | "
                             f"{r['rms_mm']:.2f} | {r['fap_all']:.1f} | {r['fap_8']:.1f} |")
    lines += ["", "## Over the 4 draws (2 clips x 2 folds): median (worst)", "",
              "| K | PCA variance explained | guided | PCA lips and jaw | guided | PCA FAP error from 8 | guided |",
              "|---:|---:|---:|---:|---:|---:|---:|"]
    for count in COUNTS:
        cells = []
        for key, scale, worst in (("explained", 100, min), ("lips", 100, min), ("fap_8", 1, max)):
            for method in ("pca", "guided"):
                values = [results[c, f, method, count][key] * scale for c in CLIPS for f in ("A", "B")]
                cells.append(f"{np.median(values):.1f} ({worst(values):.1f})")
        lines.append(f"| {count} | " + " | ".join(cells) + " |")
    draws = [(c, f) for c in CLIPS for f in ("A", "B")]
    closer = {key: sum(results[c, f, "guided", 6][key] < results[c, f, "pca", 6][key] for c, f in draws)
              for key in ("fap_all", "fap_8")}
    lines += ["", f"Six parameters: the guided model decodes the held-out tracked FAPs closer than PCA in "
              f"{closer['fap_all']} of 4 draws from all 30 FAPs and {closer['fap_8']} of 4 from 8; PCA explains "
              "more of the points' variance (table above). `faceanim speaker build` uses guided by default."]
    lines += ["", "## Interpretation speed (regularise), model of speech_man fold A, 6 parameters", ""]
    lines += speed(speed_model)
    publish("speaker_model.md", lines)


if __name__ == "__main__":
    main()
