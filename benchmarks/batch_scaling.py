"""faceanim batch on Ray against the single command run video by video: throughput with 1 and 2 workers.

    python benchmarks/batch_scaling.py [--max-load 1.0] [--wait 600] [--repeat N] [VIDEO ...]

The same videos (default: the shared d0, d10, d12, d18, d20, speech_woman; 1,299 frames; ``--repeat N``
lists each N times under its own names, a longer batch) three ways: ``faceanim encode VIDEO -o OUT.fap``
one after another, each its own process (what a shell loop does); ``faceanim batch --do encode
--workers 1``; and ``--workers 2``, with the same task settings. Throughput is the videos' frames over
the wall time, with Ray's start counted and, apart, without it; per video, frames per second of its own
task (median and worst over the videos). CPU seconds per frame are the whole machine's busy time over
the run (``/proc/stat``: every process, Ray's own included, and anything else running, hence the load
column). The goal on this 2-core machine: 2 workers >= 1.7x 1 worker.

The machine is shared: the script waits (up to ``--wait`` seconds) for the 1-minute load average to
fall below ``--max-load`` before each run, and reports the load it ran at. Writes
``benchmarks/results/batch_scaling.md`` (``batch_scaling_repeatN.md`` with ``--repeat``).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from report import publish  # noqa: E402

VIDEOS = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "videos"
DEFAULT = ("d0.mp4", "d10.mp4", "d12.mp4", "d18.mp4", "d20.mp4", "speech_woman.mp4")


def quiet(max_load: float, wait: float) -> tuple[float, bool]:
    """Wait until the 1-minute load average is below ``max_load`` (at most ``wait`` s); (load, quiet?)."""
    deadline = time.monotonic() + wait
    while True:
        load = os.getloadavg()[0]
        if load < max_load or time.monotonic() >= deadline:
            return load, load < max_load
        time.sleep(15)


def busy_seconds() -> float:
    """CPU seconds the whole machine has spent busy since it started (``/proc/stat``'s first line,
    less idle and iowait)."""
    ticks = [int(x) for x in open("/proc/stat").readline().split()[1:]]
    return (sum(ticks) - ticks[3] - ticks[4]) / os.sysconf("SC_CLK_TCK")


def single(videos, folder) -> list[float]:
    """Seconds of ``faceanim encode`` per video, each in its own process, one after another."""
    seconds = []
    for k, video in enumerate(videos):
        start = time.perf_counter()
        subprocess.run([sys.executable, "-m", "faceanim", "encode", str(video.path), "-o",
                        str(Path(folder) / f"{video.name}_{k}.fap")], check=True, capture_output=True)
        seconds.append(time.perf_counter() - start)
    return seconds


def batch(videos, folder, workers):
    from faceanim.dataset import run_batch

    return run_batch(videos, folder, do="encode", workers=workers, force=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("videos", nargs="*")
    parser.add_argument("--max-load", type=float, default=1.0)
    parser.add_argument("--wait", type=float, default=600.0)
    parser.add_argument("--repeat", type=int, default=1, help="list each video N times (a longer batch)")
    args = parser.parse_args()
    paths = [Path(v) for v in args.videos] or [VIDEOS / name for name in DEFAULT]
    missing = [str(v) for v in paths if not v.exists()]
    if missing:
        sys.exit(f"needs {', '.join(missing)} (the shared data folder beside the checkout)")
    from faceanim.manifest import Video

    videos = [Video(p, f"{p.stem}_{k}" if args.repeat > 1 else p.stem) for k in range(args.repeat) for p in paths]
    runs, loads, cpu = {}, {}, {}
    with tempfile.TemporaryDirectory() as work:
        loads["single"] = quiet(args.max_load, args.wait)
        before = busy_seconds()
        runs["single"] = single(videos, work)
        cpu["single"] = busy_seconds() - before
        for workers in (1, 2):
            loads[workers] = quiet(args.max_load, args.wait)
            manifest = Path(work) / f"w{workers}.jsonl"
            manifest.write_text("".join(json.dumps({"path": str(v.path), "name": v.name}) + "\n" for v in videos))
            before = busy_seconds()
            runs[workers] = batch([manifest], Path(work) / f"w{workers}", workers)
            cpu[workers] = busy_seconds() - before
    first = runs[1].videos
    frames = [v.frames for v in first]
    total = sum(frames)
    command = "python3 benchmarks/batch_scaling.py" + (f" --repeat {args.repeat}" if args.repeat > 1 else "")
    lines = ["# faceanim batch on Ray: throughput against the single command", "",
             f"`{command}` on {os.cpu_count()} cores, {len(videos)} videos "
             f"({', '.join(p.name for p in paths)}{f', each {args.repeat} times' if args.repeat > 1 else ''}), "
             f"{total:,} frames, `--do encode`. Frames per second; per video, its own task's (or command's) frames "
             "over its seconds. CPU ms per frame: the whole machine's busy time over the run (Ray's own processes, "
             "each command's start, and anything else running included).", "",
             "| run | load before | wall s | frames/s | frames/s without Ray's start | per video: median | worst |"
             " vs one by one | CPU ms per frame |", "|---|---|---|---|---|---|---|---|---|"]
    base_wall = sum(runs["single"])
    base = total / base_wall
    per = [f / s for f, s in zip(frames, runs["single"], strict=True)]
    load, ok = loads["single"]
    lines.append(f"| `faceanim encode`, one by one | {load:.2f}{'' if ok else ' (not quiet)'} | {base_wall:.1f} | "
                 f"{base:.1f} | - | {statistics.median(per):.1f} | {min(per):.1f} | 1.00x | "
                 f"{1000 * cpu['single'] / total:.1f} |")
    through, steady = {}, {}
    for workers in (1, 2):
        result = runs[workers]
        failed = [v.name for v in result.videos if v.status != "done"]
        if failed:
            sys.exit(f"batch with {workers} workers failed on {', '.join(failed)}")
        per = [v.frames / v.seconds for v in result.videos]
        through[workers] = total / result.seconds
        steady[workers] = total / (result.seconds - result.startup)
        load, ok = loads[workers]
        lines.append(f"| `faceanim batch --workers {workers}` | {load:.2f}{'' if ok else ' (not quiet)'} | "
                     f"{result.seconds:.1f} | {through[workers]:.1f} | {steady[workers]:.1f}"
                     f" | {statistics.median(per):.1f} | {min(per):.1f} | {through[workers] / base:.2f}x | "
                     f"{1000 * cpu[workers] / total:.1f} |")
    lines += ["", f"2 workers against 1: {through[2] / through[1]:.2f}x with Ray's start, "
              f"{steady[2] / steady[1]:.2f}x without (goal >= 1.7x); Ray's start: "
              f"{runs[1].startup:.1f} s and {runs[2].startup:.1f} s.",
              "A load above the cores' count means other work shared the 2 cores: the figures are then a floor."]
    publish("batch_scaling.md" if args.repeat == 1 else f"batch_scaling_repeat{args.repeat}.md", lines)


if __name__ == "__main__":
    main()
