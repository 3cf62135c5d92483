"""How long `faceanim animate` takes, step by step: d18 onto the ICT-FaceKit head.

    python3 benchmarks/animate_speed.py [--runs 3]

The command timed is the README's, without the preview:
``faceanim animate ../shared/data/videos/d18.mp4 --target ../shared/data/ict_facekit/obj/generic_neutral_mesh.obj
-o d18.glb``. Each run is a fresh process (interpreter start and imports count, as they do for a
person) calling what the command calls, ``pipeline.animate``, with a :class:`~faceanim.progress.Progress`
that notes the time at each step the command would show. The goal (issue 14) is 15 s or less on this
2-core machine. Writes ``benchmarks/results/animate_speed.md``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from report import publish  # noqa: E402

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"
VIDEO = DATA / "videos" / "d18.mp4"
TARGET = DATA / "ict_facekit" / "obj" / "generic_neutral_mesh.obj"
GOAL_SECONDS = 15.0
# The steps the command shows (how each line it prints begins; the first that fits), and what the table
# calls them.
STEPS = (
    ("start", "start-up: interpreter, imports, reading the target"),
    ("placing control points", "placement: control points on the target (render, track, cast back)"),
    ("tracking done", "motion: neutral, head frame, One Euro filter, FAPs"),
    ("tracking", "tracking: MediaPipe through the video"),
    ("following the tracked motion", "deformer set-up: parts, surface-aware interpolation, fold relaxer"),
    ("deforming", "deformation: the motion followed on the target, frame by frame, kept in a temporary file"),
    ("writing", "glTF writing: morph targets (two streaming passes), animation"),
)


def child(output: str, launched: float) -> None:
    """One run, in this process: print ``[(step, seconds), ...]`` as JSON."""
    from faceanim import pipeline
    from faceanim.progress import Progress

    class Marks(Progress):
        def __init__(self):
            super().__init__()
            self.marks = [("start", launched)]

        def status(self, what):
            self.marks.append((what, time.time()))

        def bar(self, iterable, *, total=None, desc, unit="frame"):
            self.marks.append((desc, time.time()))
            return self._done(iterable, desc)

        def _done(self, iterable, desc):
            yield from iterable
            self.marks.append((f"{desc} done", time.time()))

    marks = Marks()
    pipeline.animate(VIDEO, output, target_mesh=TARGET, progress=marks)
    marks.marks.append(("end", time.time()))
    steps = [(what, end - start) for (what, start), (_, end) in zip(marks.marks, marks.marks[1:], strict=False)]
    print(json.dumps(steps))


def step_name(what: str) -> str:
    return next((name for start, name in STEPS if what.startswith(start)), what)


def one_run(folder: Path) -> tuple[float, dict]:
    """Total wall-clock seconds of a fresh process, and its seconds per step."""
    launched = time.time()
    done = subprocess.run([sys.executable, __file__, "--child", str(folder / "d18.glb"), repr(launched)],
                          capture_output=True, text=True, check=True, env={**os.environ, "GLOG_minloglevel": "2"})
    total = time.time() - launched
    steps = {}
    for what, seconds in json.loads(done.stdout.strip().splitlines()[-1]):
        steps[step_name(what)] = steps.get(step_name(what), 0.0) + seconds
    return total, steps


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--child", nargs=2, metavar=("OUT", "LAUNCHED"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args.child[0], float(args.child[1]))
        return 0
    for path in (VIDEO, TARGET):
        if not path.exists():
            print(f"skipped: needs {path.resolve()} (the shared data folder beside the checkout)")
            return 0
    runs = []
    with tempfile.TemporaryDirectory() as folder:
        for i in range(args.runs):
            runs.append(one_run(Path(folder)))
            print(f"run {i + 1}: {runs[-1][0]:.1f} s", file=sys.stderr)
    names = list(dict.fromkeys(name for _, steps in runs for name in steps))
    total = statistics.median(t for t, _ in runs)
    verdict = "met" if total <= GOAL_SECONDS else f"not met, {total - GOAL_SECONDS:.1f} s over"
    lines = [f"# faceanim animate: d18 (216 frames) onto the ICT head (26,719 vertices); "
             f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, median of {args.runs} runs",
             "", f"Goal: {GOAL_SECONDS:.0f} s or less on 2 cores. Median total: {total:.1f} s ({verdict}).", "",
             "| step | median s | runs, s |", "|---|---:|---|"]
    for name in names:
        seconds = [steps.get(name, 0.0) for _, steps in runs]
        lines.append(f"| {name} | {statistics.median(seconds):.2f} | {', '.join(f'{s:.2f}' for s in seconds)} |")
    lines += [f"| **total (the whole process)** | **{total:.1f}** | {', '.join(f'{t:.1f}' for t, _ in runs)} |", "",
              "Steps are medians taken one by one, so they need not add up to the median total."]
    publish("animate_speed.md", lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
