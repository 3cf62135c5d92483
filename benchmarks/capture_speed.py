"""Capture on the shared videos: speed against MediaPipe alone, tracking, ranges, jitter.

    python benchmarks/capture_speed.py

For every video in ``../shared/data/videos``, in one run: frames per second of MediaPipe's face mesh
alone (decode + ``FaceMesh.process``, one face, as a user would call it) and of faceanim's whole
``encode`` (decode, tracking, head pose, filtering, neutral, FAPs, writing the ``.fap``); the share of
frames with a face; how many written FAP values had to be clipped to their MPEG-4 range; and the
jitter (mean landmark acceleration in cm/s^2 on the stillest quarter of frames) without and with the
One Euro filter. Writes ``benchmarks/results/capture_speed.md``.
"""

from __future__ import annotations

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


def mediapipe_alone(path) -> tuple[float, int]:
    from mediapipe.python.solutions import face_mesh

    from faceanim.capture.video import open_frames

    start = time.perf_counter()
    count = 0
    with open_frames(path) as source, face_mesh.FaceMesh(max_num_faces=1, refine_landmarks=True) as mesh:
        for _, rgb in source:
            mesh.process(rgb)
            count += 1
    return count / (time.perf_counter() - start), count


def main() -> int:
    if not VIDEOS.exists():
        print(f"skipped: needs {VIDEOS} (the shared data folder beside the checkout)")
        return 0
    from faceanim import pipeline
    from faceanim.capture.headframe import head_frame
    from faceanim.capture.smoothing import OneEuro, jitter, one_euro
    from faceanim.capture.track import Track

    rows = []
    for video in sorted(VIDEOS.glob("*.mp4")):
        alone, frames = mediapipe_alone(video)
        with tempfile.TemporaryDirectory() as tmp:
            start = time.perf_counter()
            stream, clipped = pipeline.encode(video, Path(tmp) / "out.fap", progress=False)
            ours = frames / (time.perf_counter() - start)
            pipeline.track(video, Path(tmp) / "t.npz", progress=False)
            track = Track.load(Path(tmp) / "t.npz")
        points, _ = head_frame(track)
        smooth = one_euro(points, track.times, OneEuro(min_cutoff=0.5, beta=0.0))
        speed = np.r_[np.inf, np.sqrt(((smooth[1:] - smooth[:-1]) ** 2).sum(-1).mean(-1))]
        speed[~np.isfinite(speed)] = np.inf
        still = speed <= np.quantile(speed[np.isfinite(speed)], 0.25)
        raw = jitter(points, track.fps, still)
        filtered = jitter(one_euro(points, track.times), track.fps, still)
        rows.append((video.name, f"{track.width}x{track.height}", frames, 100 * track.valid.mean(), alone, ours,
                     ours / alone, clipped, int(stream.mask.sum()), raw, filtered))
        print(rows[-1], flush=True)

    lines = ["# Capture on the shared videos", "",
             f"`python benchmarks/capture_speed.py` on {os.cpu_count()} cores. MediaPipe alone: decode + "
             "`FaceMesh.process` (one face, iris refinement). faceanim: the whole `encode` (decode, tracking, "
             "head pose, One Euro filter, neutral, FAPs, .fap written). Jitter: mean landmark acceleration "
             "(cm/s^2, head frame) on each video's stillest quarter of frames.", "",
             "| video | size | frames | face found % | MediaPipe alone fps | faceanim encode fps | ratio | "
             "values clipped / written | jitter raw | jitter filtered |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for name, size, frames, found, alone, ours, ratio, clipped, written, raw, filtered in rows:
        lines.append(f"| {name} | {size} | {frames} | {found:.1f} | {alone:.1f} | {ours:.1f} | {ratio:.2f} | "
                     f"{clipped} / {written} | {raw:.1f} | {filtered:.1f} |")
    publish("capture_speed.md", lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
