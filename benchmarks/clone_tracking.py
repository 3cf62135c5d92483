"""Analysis by synthesis with the speaker's clone on the shared speech clips (issue 18: tracking).

    flock /tmp/faceanim-bench.lock python benchmarks/clone_tracking.py

For ``speech_man.mp4`` (125 frames) and ``speech_woman.mp4`` (199): the speaker model is built on the
first 70% of the frames (``faceanim speaker build --frames``) and given its textures from the same
frames (``faceanim speaker textures --frames``); the remaining 30% are held out and cut into 2
segments, so there are 4 reporting draws (2 clips x 2 segments), of which the median and the worst
are given. The prior's weight (``DEFAULT_PRIOR``) was chosen on the build frames only.

(a) **synthetic**: each held-out frame's landmark-based parameters (``fit_points`` of the capture) and
    the capture's head motion are drawn by the clone (``CloneRenderer``, the appearance half's GL
    renderer) over the real frame as background, with a lighting change (brightness falling linearly
    to 75% with a warm tint over the segment); the tracker, its colour model adapted on the segment's
    first 3 frames and started at the first frame's known parameters, tracks them back. RMS error of
    each parameter over the segment, in the model's units (the parameters have unit variance over the
    build frames) and divided by the parameter's spread on the segment (its standard deviation
    there, smaller: 0.25-1); the worst parameter per draw. Goal <= 0.1 of the spread.
(b) **real**: ``track_speaker`` on the whole clip (the job ``faceanim speaker track`` runs); on each
    held-out segment the tracked lip opening (the inner lips' middles 2.2-2.3, vertical) and width
    (corners 8.3-8.4, horizontal) of the model's points against MediaPipe's same points (the capture's
    head-frame points), correlation (goal >= 0.9); and each parameter against the landmark-based
    analysis (correlation, RMS over its spread).
(c) **speed**: the analysis's frames/s (``TrackedSpeech.seconds``: rendering, comparing, the simplex;
    decoding and the capture not counted) at the default cap of 150 evaluations, numpy rasteriser
    against GL (moderngl on Mesa's llvmpipe here), per clip. Goal >= 10 frames/s on 2 cores.

Writes ``benchmarks/results/clone_tracking.md``.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from report import publish  # noqa: E402

os.environ.setdefault("GLOG_minloglevel", "2")
VIDEOS = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "videos"
CLIPS = ("speech_man", "speech_woman")
BUILD_SHARE = 0.7
SEGMENTS = 2
ADAPT = 3


def held_out_segments(count: int) -> list[np.ndarray]:
    first = int(round(BUILD_SHARE * count))
    return np.array_split(np.arange(first, count), SEGMENTS)


def lip_measures(model, parameters) -> tuple[np.ndarray, np.ndarray]:
    """(opening, width) in cm of the model's points at ``parameters (T, K)``."""
    points = model.points(parameters)
    at = {n: i for i, n in enumerate(model.names)}
    return points[:, at["2.2"], 1] - points[:, at["2.3"], 1], points[:, at["8.3"], 0] - points[:, at["8.4"], 0]


def mediapipe_measures(motion) -> tuple[np.ndarray, np.ndarray]:
    x = motion.neutral[None] + motion.displacements
    at = {n: i for i, n in enumerate(motion.names)}
    return x[:, at["2.2"], 1] - x[:, at["2.3"], 1], x[:, at["8.3"], 0] - x[:, at["8.4"], 0]


def corr(a, b) -> float:
    return float(np.corrcoef(a, b)[0, 1])


def synthetic(model, appearance, video_frames, tracked, segment, width, height):
    """(a): each parameter's RMS error on one segment, in the model's units (one standard deviation
    over the build frames) and over its spread on the segment."""
    from faceanim.speaker.analysis import CloneAnalyser, pose_matrix
    from faceanim.speaker.clone import CloneRenderer

    truth = tracked.landmark_parameters[segment]
    rigid = tracked.rigid[segment]
    ramp = np.linspace(1.0, 0.75, len(segment))
    frames = []
    with CloneRenderer(model, appearance, width=width, height=height) as renderer:
        for a, r, background, level in zip(truth, rigid, video_frames[segment], ramp, strict=True):
            image = renderer.render(a, r, camera=tracked.camera, background=background).astype(np.float64)
            frames.append(np.clip(image * level * [1.0, 0.95, 0.88], 0, 255).astype(np.uint8))
    poses = pose_matrix(rigid)
    found = []
    with CloneAnalyser(model, appearance, width=width, height=height, mouth_width=tracked.mouth_width,
                       camera=tracked.camera) as analyser:
        analyser.adapt(frames[:ADAPT], truth[:ADAPT], poses[:ADAPT])
        previous = truth[0]
        for image, pose in zip(frames, poses, strict=True):
            previous = analyser.analyse(image, previous, pose).parameters
            found.append(previous)
    rms = np.sqrt(((np.array(found) - truth) ** 2).mean(axis=0))
    return rms, rms / truth.std(axis=0)


def main() -> None:
    from faceanim.capture.video import open_frames
    from faceanim.inputs import captured_source
    from faceanim.speaker import read_speaker
    from faceanim.speaker.appearance import read_appearance
    from faceanim.speakerclone import make_textures
    from faceanim.speakertrack import track_speaker
    from faceanim.speech import build_speaker

    for clip in CLIPS:
        if not (VIDEOS / f"{clip}.mp4").is_file():
            raise SystemExit(f"missing {VIDEOS / f'{clip}.mp4'}: the shared data is needed")
    rows_a, rows_b, rows_c, draws_a, draws_b = [], [], [], [], []
    with tempfile.TemporaryDirectory() as folder:
        for clip in CLIPS:
            video = VIDEOS / f"{clip}.mp4"
            capture = captured_source(video)
            motion = capture.motion
            T = len(motion)
            build = f"0:{int(round(BUILD_SHARE * T))}"
            path = Path(folder) / f"{clip}.npz"
            build_speaker(video, path, frames=build)
            make_textures(video, path, model=path, frames=build)
            model, appearance = read_speaker(path), read_appearance(path)
            frames = np.stack([image for _, image in open_frames(video)])
            runs = {}
            for raster in ("numpy", "gl"):
                runs[raster] = track_speaker(video, Path(folder) / f"{clip}_{raster}.csv", model=path, raster=raster)
                rows_c.append(f"| {clip} | {raster} | {T} | {int(np.median(runs[raster].evaluations))} | "
                              f"{int(runs[raster].evaluations.max())} | {T / runs[raster].seconds:.1f} |")
            tracked = runs["numpy"]
            opening, width = lip_measures(model, tracked.parameters)
            mp_opening, mp_width = mediapipe_measures(motion)
            for segment in held_out_segments(T):
                name = f"{clip} {segment[0]}-{segment[-1]}"
                a, b = tracked.parameters[segment], tracked.landmark_parameters[segment]
                c_open, c_width = corr(opening[segment], mp_opening[segment]), corr(width[segment], mp_width[segment])
                c_params = [corr(a[:, k], b[:, k]) for k in range(model.parameter_count)]
                r_params = np.sqrt(((a - b) ** 2).mean(axis=0)) / b.std(axis=0)
                draws_b.append((min(c_open, c_width), c_open, c_width, float(np.median(c_params)),
                                float(np.median(r_params))))
                rows_b.append(f"| {name} | {c_open:.2f} | {c_width:.2f} | "
                              + " ".join(f"{v:.2f}" for v in c_params) + " | "
                              + " ".join(f"{v:.2f}" for v in r_params) + " |")
                rms, error = synthetic(model, appearance, frames, tracked, segment, capture.width, capture.height)
                draws_a.append((float(rms.max()), float(error.max())))
                rows_a.append(f"| {name} | " + " ".join(f"{v:.2f}" for v in rms) + f" | {rms.max():.2f} | "
                              + " ".join(f"{v:.2f}" for v in error) + f" | {error.max():.2f} |")
            names = model.parameter_names

    def summary(values, worst) -> str:
        return f"{np.median(values):.2f} (worst {worst(values):.2f})"

    lines = [
        "# Analysis by synthesis with the speaker's clone (issue 18)", "",
        "`flock /tmp/faceanim-bench.lock python benchmarks/clone_tracking.py`: model and textures built on the first "
        "70% of each speech clip, scored on the held-out 30% cut into 2 segments (4 draws). Parameters: "
        + ", ".join(names) + ".", "",
        "## Summary (median over the 4 draws, worst in brackets)", "",
        "| measure | result | goal |", "|---|---|---|",
        "| (a) synthetic, worst parameter's RMS error, in the model's standard deviations | "
        f"{summary([d[0] for d in draws_a], max)} | <= 0.1 |",
        "| (a) synthetic, worst parameter's RMS error / its spread on the segment | "
        f"{summary([d[1] for d in draws_a], max)} | <= 0.1 |",
        f"| (b) real, lip opening correlation with MediaPipe | {summary([d[1] for d in draws_b], min)} | >= 0.9 |",
        f"| (b) real, lip width correlation with MediaPipe | {summary([d[2] for d in draws_b], min)} | >= 0.9 |",
        f"| (b) real, median parameter correlation with the landmark-based analysis | "
        f"{summary([d[3] for d in draws_b], min)} | |",
        "| (b) real, median parameter RMS difference / spread against it | "
        f"{summary([d[4] for d in draws_b], max)} | |",
        "", "## (a) Synthetic: frames drawn by the clone at known parameters, lighting falling to 75%", "",
        "| draw | RMS error per parameter (model's std) | worst | RMS error / segment's spread | worst |",
        "|---|---|---|---|---|", *rows_a,
        "", "## (b) Real held-out frames", "",
        "| draw | opening corr. | width corr. | parameter corr. with landmark analysis | RMS / spread |",
        "|---|---|---|---|---|", *rows_b,
        "", "## (c) Speed: the analysis alone, cap 150 evaluations a frame, 2 shared cores", "",
        "| clip | rasteriser | frames | median evaluations | most | frames/s |", "|---|---|---|---|---|---|", *rows_c,
    ]
    publish("clone_tracking.md", lines)


if __name__ == "__main__":
    main()
