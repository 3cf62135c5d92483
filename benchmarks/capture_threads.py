"""Where one batch task's CPU goes: the streamed capture of a video (what every ``faceanim batch`` step
starts from), its CPU time by thread, to tell whether one task spreads over more than its one CPU.

    python3 benchmarks/capture_threads.py [VIDEO ...]

Per video (default: the shared d10 and speech_woman): the capture is made once to warm up (imports,
the model), then again while a sampler reads ``/proc/self/task/*/stat`` every 50 ms (threads that
end between two reads lose their last 50 ms); CPU seconds by thread name (MediaPipe's graph threads are
``drishti``, FFmpeg's decoder threads ``av:h264:df*``), the process's user+sys time over the wall time
(cores kept busy), and CPU ms per frame. Writes ``benchmarks/results/capture_threads.md``. A timing:
run it under the bench lock on a quiet machine (the load is reported).
"""

from __future__ import annotations

import argparse
import collections
import os
import sys
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from report import publish  # noqa: E402

VIDEOS = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "videos"
DEFAULT = ("d10.mp4", "speech_woman.mp4")


def threads() -> dict[str, tuple[str, float]]:
    """{thread id: (name, CPU seconds)} of this process's threads now."""
    found = {}
    for tid in os.listdir("/proc/self/task"):
        try:
            stat = open(f"/proc/self/task/{tid}/stat").read()
        except OSError:  # ended meanwhile
            continue
        fields = stat[stat.rindex(")") + 2:].split()
        found[tid] = (stat[stat.index("(") + 1:stat.rindex(")")],
                      (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK"))
    return found


def profile(video: Path):
    from faceanim.inputs import captured_source

    with_folder = Path(os.environ.get("TMPDIR", "/tmp"))
    captured_source(video, folder=with_folder)  # warm up
    seen, stop = {}, threading.Event()

    def sample():
        while not stop.is_set():
            for tid, (name, cpu) in threads().items():
                seen[tid] = (name, max(cpu, seen.get(tid, (name, 0.0))[1]))
            time.sleep(0.05)

    before = threads()
    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    start, times = time.perf_counter(), os.times()
    capture = captured_source(video, folder=with_folder)
    wall, after = time.perf_counter() - start, os.times()
    stop.set()
    sampler.join()
    by_name = collections.Counter()
    for tid, (name, cpu) in seen.items():
        by_name[name] += cpu - before.get(tid, (name, 0.0))[1]
    cpu = after.user - times.user + after.system - times.system
    return len(capture), wall, cpu, by_name


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("videos", nargs="*")
    args = parser.parse_args()
    videos = [Path(v) for v in args.videos] or [VIDEOS / name for name in DEFAULT]
    lines = ["# One capture's CPU by thread", "",
             f"`python3 benchmarks/capture_threads.py` on {os.cpu_count()} cores, load "
             f"{os.getloadavg()[0]:.2f} before. Cores: the process's user+sys time over the wall time.", "",
             "| video | frames | wall s | CPU s | cores | CPU ms per frame | by thread (CPU s, share) |",
             "|---|---|---|---|---|---|---|"]
    for video in videos:
        frames, wall, cpu, by_name = profile(video)
        shares = ", ".join(f"{name} {s:.2f} ({100 * s / cpu:.0f}%)" for name, s in by_name.most_common(6))
        lines.append(f"| {video.name} | {frames} | {wall:.2f} | {cpu:.2f} | {cpu / wall:.2f} | "
                     f"{1000 * cpu / frames:.1f} | {shares} |")
    publish("capture_threads.md", lines)


if __name__ == "__main__":
    main()
