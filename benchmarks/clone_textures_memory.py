"""Peak memory of ``faceanim speaker textures`` against the video's length (issue 18: the job streams).

    flock /tmp/faceanim-bench.lock python benchmarks/clone_textures_memory.py

The longest shared clip, ``d6.mp4`` (1008 frames, 480x480), against its first quarter (252 frames,
re-encoded): a speaker model is built on the quarter (``faceanim speaker build``), then ``faceanim
speaker textures`` runs on each clip in its own process under ``/usr/bin/time -v`` (the peak resident
set size, the kernel's ``Maximum resident set size``). For contrast, the same work with the capture held
whole in memory (every frame's head-frame points and landmarks as arrays, given to
``build_appearance``, as the job did before it streamed) in the same way. One run each (the figure is a
peak, not a timing; it varies by a few MB between runs).

Writes ``benchmarks/results/clone_textures_memory.md``.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from report import publish  # noqa: E402

os.environ.setdefault("GLOG_minloglevel", "2")
VIDEOS = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "videos"
CLIP = "d6"

HELD = """
import sys
import numpy as np
from faceanim.inputs import captured_source
from faceanim.speaker import read_speaker
from faceanim.speaker.texturing import build_appearance
from faceanim.speakerclone import _frames_of

video, model, folder = sys.argv[1:4]
capture = captured_source(video, folder=folder, floor=False)  # as speaker textures
motion = capture.motion
points = motion.neutral + motion.displacements  # every frame held
landmarks = capture.landmarks[:][..., :2]
build_appearance(read_speaker(model), names=motion.names, points=points, landmarks=landmarks, pose=motion.pose,
                 valid=motion.valid, width=capture.width, height=capture.height,
                 read_frames=lambda idx: _frames_of(video, idx))
"""


def peak_mib(command: list[str]) -> float:
    """The peak resident set size of ``command``, MiB (``/usr/bin/time -v``)."""
    done = subprocess.run(["/usr/bin/time", "-v", *command], capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed:\n{done.stderr[-2000:]}")
    return int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", done.stderr).group(1)) / 1024


def main() -> None:
    from faceanim.capture.video import open_frames
    from faceanim.render.video import video_writer

    video = VIDEOS / f"{CLIP}.mp4"
    if not video.is_file():
        raise SystemExit(f"missing {video}: the shared data is needed")
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        with open_frames(video) as source:
            T = sum(1 for _ in source)
        quarter = folder / f"{CLIP}_quarter.mp4"
        with open_frames(video) as source, video_writer(quarter, source.fps, source.width, source.height) as write:
            for _, (_, image) in zip(range(T // 4), source, strict=False):
                write(image)
        model = folder / "model.npz"
        subprocess.run(["faceanim", "speaker", "build", str(quarter), "-o", str(model)], check=True,
                       capture_output=True)
        clips = ((quarter, T // 4), (video, T))
        for how in ("streamed (the job)", "held whole (before)"):
            for clip, count in clips:
                out = folder / f"out_{count}.npz"
                if how.startswith("streamed"):
                    command = ["faceanim", "speaker", "textures", str(clip), "--model", str(model), "-o", str(out)]
                else:
                    command = [sys.executable, "-c", HELD, str(clip), str(model), str(folder)]
                mib = peak_mib(command)
                rows.append((how, clip.name, count, mib))
                print(how, clip.name, count, f"{mib:.0f} MiB", flush=True)
    lines = ["# Peak memory of `faceanim speaker textures` (issue 18)", "",
             "`flock /tmp/faceanim-bench.lock python benchmarks/clone_textures_memory.py`: the longest shared clip "
             f"({CLIP}.mp4, {T} frames) against its first quarter ({T // 4} frames), model built on the quarter; "
             "peak resident set size of each run in its own process (`/usr/bin/time -v`), one run each. "
             f"Load average at the end: {os.getloadavg()[0]:.1f}.", "",
             "| capture | clip | frames | peak RSS (MiB) |", "|---|---|---|---|",
             *(f"| {how} | {name} | {count} | {mib:.0f} |" for how, name, count, mib in rows), ""]
    by = {(how, count): mib for how, _, count, mib in rows}
    for how in ("streamed (the job)", "held whole (before)"):
        grow = by[(how, T)] - by[(how, T // 4)]
        lines.append(f"- {how}: {grow:+.0f} MiB from {T // 4} to {T} frames "
                     f"({1024 * grow / (T - T // 4):+.0f} KiB a frame).")
    publish("clone_textures_memory.md", lines)


if __name__ == "__main__":
    main()
