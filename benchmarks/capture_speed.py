"""Capture on the shared videos: speed against MediaPipe alone, tracking, ranges, jitter.

    flock /tmp/faceanim-bench.lock python benchmarks/capture_speed.py [--runs 3] [VIDEO.mp4 ...]

For every video in ``../shared/data/videos`` (or those named): frames per second of MediaPipe's Face
Landmarker alone (decode + ``detect_for_video``, one face, blendshapes and the transformation matrix
on, as faceanim runs it, from faceanim's own bundle), and of faceanim's whole ``encode`` (decode,
tracking, head pose, filtering, neutral, FAPs, writing the ``.fap``), each the median and worst of
``--runs`` runs; the share of frames with a face; how many written FAP values had to be clipped to
their MPEG-4 range; and the jitter (mean landmark acceleration in cm/s^2 of the 468 mesh points, head
frame, on the stillest quarter of frames) without and with the One Euro filter.

Where the installed MediaPipe still has the legacy FaceMesh (``mediapipe.solutions``, up to 0.10.21),
the same for FaceMesh alone (one face, iris refinement): its speed, the share of frames it finds and
its raw jitter on the same frames, so the two trackers are compared on one machine in one run.
Writes ``benchmarks/results/capture_speed.md``.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from report import publish  # noqa: E402

os.environ.setdefault("GLOG_minloglevel", "2")
VIDEOS = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "videos"


def landmarker_alone(path) -> float:
    """Frames per second of decode + the Face Landmarker in video mode, one face."""
    import mediapipe as mp
    from mediapipe.tasks.python import BaseOptions, vision

    from faceanim.capture.tracker import DEFAULT_MODEL
    from faceanim.capture.video import open_frames

    settings = vision.FaceLandmarkerOptions(
        base_options=BaseOptions(model_asset_path=str(DEFAULT_MODEL)), running_mode=vision.RunningMode.VIDEO,
        num_faces=1, output_face_blendshapes=True, output_facial_transformation_matrixes=True)
    start = time.perf_counter()
    count = 0
    with open_frames(path) as source, vision.FaceLandmarker.create_from_options(settings) as landmarker:
        for index, (t, rgb) in enumerate(source):
            ms = int(round(1000 * (t if t is not None else index / source.fps)))
            landmarker.detect_for_video(mp.Image(image_format=mp.ImageFormat.SRGB, data=np.ascontiguousarray(rgb)),
                                        max(ms, index))
            count += 1
    return count / (time.perf_counter() - start)


def facemesh_alone(path):
    """Frames per second of decode + the legacy FaceMesh (one face, iris refinement) and the Track it
    makes, or None where the installed MediaPipe no longer has it."""
    try:
        from mediapipe.python.solutions import face_mesh
    except ImportError:
        return None
    from faceanim.capture.track import Track
    from faceanim.capture.video import open_frames

    landmarks, valid, times = [], [], []
    start = time.perf_counter()
    with open_frames(path) as source, face_mesh.FaceMesh(max_num_faces=1, refine_landmarks=True) as mesh:
        for index, (t, rgb) in enumerate(source):
            found = mesh.process(rgb).multi_face_landmarks
            landmarks.append(np.array([(p.x, p.y, p.z) for p in found[0].landmark]) if found else None)
            valid.append(bool(found))
            times.append(t if t is not None else index / source.fps)
        fps, width, height = source.fps, source.width, source.height
    speed = len(valid) / (time.perf_counter() - start)
    points = np.array([np.full((478, 3), np.nan) if p is None else p for p in landmarks])
    return speed, Track(points, np.array(valid), np.zeros(len(valid), bool), np.array(times), fps, width, height)


def jitters(track, still) -> tuple[float, float]:
    """Raw and One Euro-filtered jitter of the 468 mesh points on the ``still`` frames."""
    from faceanim.capture.headframe import head_frame
    from faceanim.capture.smoothing import jitter, one_euro

    points = head_frame(track)[0][:, :468]
    return jitter(points, track.fps, still), jitter(one_euro(points, track.times), track.fps, still)


def stillest_quarter(track) -> np.ndarray:
    from faceanim.capture.headframe import head_frame
    from faceanim.capture.smoothing import OneEuro, one_euro

    points = head_frame(track)[0][:, :468]
    smooth = one_euro(points, track.times, OneEuro(min_cutoff=0.5, beta=0.0))
    speed = np.r_[np.inf, np.sqrt(((smooth[1:] - smooth[:-1]) ** 2).sum(-1).mean(-1))]
    speed[~np.isfinite(speed)] = np.inf
    return speed <= np.quantile(speed[np.isfinite(speed)], 0.25)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("videos", nargs="*", help="names in the shared videos folder (default: all .mp4)")
    parser.add_argument("--runs", type=int, default=3, help="timed runs of each (median and worst reported)")
    args = parser.parse_args()
    if not VIDEOS.exists():
        print(f"skipped: needs {VIDEOS} (the shared data folder beside the checkout)")
        return 0
    import mediapipe

    from faceanim import pipeline
    from faceanim.capture.track import Track

    videos = [VIDEOS / name for name in args.videos] or sorted(VIDEOS.glob("*.mp4"))
    rows = []
    for video in videos:
        alone, ours, legacy = [], [], []
        for _ in range(args.runs):
            alone.append(landmarker_alone(video))
            with tempfile.TemporaryDirectory() as tmp:
                start = time.perf_counter()
                stream, clipped = pipeline.encode(video, Path(tmp) / "out.fap", progress=False)
                ours.append(len(stream) / (time.perf_counter() - start))
            made = facemesh_alone(video)
            if made is not None:
                legacy.append(made[0])
        with tempfile.TemporaryDirectory() as tmp:
            pipeline.track(video, Path(tmp) / "t.npz", progress=False)
            track = Track.load(Path(tmp) / "t.npz")
        still = stillest_quarter(track)
        raw, filtered = jitters(track, still)
        mesh = None if made is None else (100 * made[1].valid.mean(), jitters(made[1], still)[0])
        rows.append((video.name, f"{track.width}x{track.height}", len(track), 100 * track.valid.mean(), alone, ours,
                     clipped, int(stream.mask.sum()), raw, filtered, legacy, mesh))
        print(rows[-1][:4], f"alone {np.median(alone):.1f} encode {np.median(ours):.1f}", flush=True)

    def fps(values) -> str:
        return f"{np.median(values):.1f} ({min(values):.1f})"

    with_mesh = any(row[-1] is not None for row in rows)
    lines = ["# Capture on the shared videos", "",
             f"`flock /tmp/faceanim-bench.lock python benchmarks/capture_speed.py --runs {args.runs}` on "
             f"{os.cpu_count()} cores, mediapipe {mediapipe.__version__}, 1-minute load before the run "
             f"{os.getloadavg()[0]:.2f}. Frames per second as median (worst) of {args.runs} runs. Face Landmarker "
             "alone: decode + `detect_for_video` (one face, blendshapes and matrix on, faceanim's bundle). "
             "faceanim: the whole `encode` (decode, Face Landmarker tracking, head pose, One Euro filter, neutral, "
             "FAPs, .fap written); ratio: encode over the Face Landmarker alone, medians. Jitter: mean landmark "
             "acceleration (cm/s^2, head frame, 468 mesh points) on each video's stillest quarter of frames.", ""]
    header = ("| video | size | frames | face found % | Face Landmarker alone fps | faceanim encode fps | ratio | "
              "values clipped / written | jitter raw | jitter filtered |")
    rule = "|---|---|---|---|---|---|---|---|---|---|"
    if with_mesh:
        header += " FaceMesh alone fps | FaceMesh found % | FaceMesh jitter raw |"
        rule += "---|---|---|"
    lines += [header, rule]
    for name, size, frames, found, alone, ours, clipped, written, raw, filtered, legacy, mesh in rows:
        line = (f"| {name} | {size} | {frames} | {found:.1f} | {fps(alone)} | {fps(ours)} | "
                f"{np.median(ours) / np.median(alone):.2f} | {clipped} / {written} | {raw:.1f} | {filtered:.1f} |")
        if with_mesh:
            line += f" {fps(legacy)} | {mesh[0]:.1f} | {mesh[1]:.1f} |" if mesh else " - | - | - |"
        lines.append(line)
    publish("capture_speed.md", lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
