"""How long `faceanim animate` takes, step by step: d18 onto the ICT-FaceKit head.

    python3 benchmarks/animate_speed.py [--runs 3] [--baseline SRC]

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
# The steps' intervals: from the first event whose text begins with the first words to the first
# later event whose text begins with the second (events from both threads, in time order).
STEPS = (
    ("start-up: interpreter, imports, reading the video's header", "start", ("placing control points", "tracking")),
    ("placement: control points on the target (render, track, cast back) and its parts", "placing control points",
     ("target ready",)),
    ("tracking: MediaPipe through the video", "tracking", ("tracking done",)),
    ("motion: neutral, head frame, One Euro filter, FAPs", "tracking done", ("capture ready",)),
    ("placement beside tracking and motion (wall time of the two threads)", ("placing control points", "tracking"),
     ("both ready",)),
    ("deformer set-up: parts, surface-aware interpolation, fold relaxer", "following the tracked motion",
     ("deforming",)),
    ("deformation: the motion followed on the target, frame by frame, kept in a temporary file", "deforming",
     ("deforming done",)),
    ("glTF writing: morph targets (two streaming passes), animation", "writing", ("end",)),
)


def child(output: str, launched: float) -> None:
    """One run, in this process: print ``[(event, time), ...]`` as JSON. The placement runs beside
    the tracking (``pipeline._beside``); the ends of the two are marked by wrapping what each calls."""
    import threading

    from faceanim import pipeline
    from faceanim.progress import Progress

    marks = [("start", launched)]
    lock = threading.Lock()

    def mark(what):
        with lock:
            marks.append((what, time.time()))

    class Marks(Progress):
        def status(self, what):
            mark(what)

        def bar(self, iterable, *, total=None, desc, unit="frame"):
            mark(desc)
            return self._done(iterable, desc)

        def _done(self, iterable, desc):
            yield from iterable
            mark(f"{desc} done")

    def marked(function, what):
        def run(*args, **kwargs):
            done = function(*args, **kwargs)
            mark(what)
            return done
        return run

    pipeline._ready_target = marked(pipeline._ready_target, "target ready")
    pipeline.captured_source = marked(pipeline.captured_source, "capture ready")
    if hasattr(pipeline, "_beside"):  # a baseline from before the two ran side by side has none
        pipeline._beside = marked(pipeline._beside, "both ready")
    pipeline.animate(VIDEO, output, target_mesh=TARGET, progress=Marks())
    mark("end")
    print(json.dumps(sorted(marks, key=lambda m: m[1])))


def step_seconds(marks) -> dict[str, float]:
    """Each step's seconds from a run's events (see :data:`STEPS`)."""
    out = {}
    for name, first, last in STEPS:
        firsts = (first,) if isinstance(first, str) else first
        begun = next((t for what, t in marks if what.startswith(firsts)), None)
        ended = next((t for what, t in marks if begun is not None and t >= begun and what.startswith(last)), None)
        if begun is not None and ended is not None:
            out[name] = ended - begun
    return out


def one_run(folder: Path, src: str | None) -> tuple[float, dict]:
    """Total wall-clock seconds of a fresh process (its ``faceanim`` from ``src`` when given), and its
    seconds per step."""
    env = {**os.environ, "GLOG_minloglevel": "2"}
    if src is not None:
        env["PYTHONPATH"] = src
    launched = time.time()
    done = subprocess.run([sys.executable, __file__, "--child", str(folder / "d18.glb"), repr(launched)],
                          capture_output=True, text=True, check=True, env=env)
    total = time.time() - launched
    return total, step_seconds(json.loads(done.stdout.strip().splitlines()[-1]))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--baseline", metavar="SRC",
                        help="also time the faceanim package under SRC (a src folder, e.g. of an earlier commit: "
                             "git archive REV src | tar -x -C DIR), run for run alternating with this one")
    parser.add_argument("--child", nargs=2, metavar=("OUT", "LAUNCHED"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args.child[0], float(args.child[1]))
        return 0
    for path in (VIDEO, TARGET):
        if not path.exists():
            print(f"skipped: needs {path.resolve()} (the shared data folder beside the checkout)")
            return 0
    versions = {"this checkout": None} | ({} if args.baseline is None else {"baseline": str(Path(args.baseline))})
    runs = {name: [] for name in versions}
    with tempfile.TemporaryDirectory() as folder:
        for i in range(args.runs):
            for name, src in versions.items():
                runs[name].append(one_run(Path(folder), src))
                print(f"run {i + 1}, {name}: {runs[name][-1][0]:.1f} s", file=sys.stderr)
    total = statistics.median(t for t, _ in runs["this checkout"])
    verdict = "met" if total <= GOAL_SECONDS else f"not met, {total - GOAL_SECONDS:.1f} s over"
    lines = [f"# faceanim animate: d18 (216 frames) onto the ICT head (26,719 vertices); "
             f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, median of {args.runs} runs",
             "", f"Goal: {GOAL_SECONDS:.0f} s or less on 2 cores. Median total: {total:.1f} s ({verdict})."]
    if args.baseline:
        before = statistics.median(t for t, _ in runs["baseline"])
        lines += ["", f"Baseline ({args.baseline}), timed in the same session, runs alternating: {before:.1f} s."]
    for name, measured in runs.items():
        lines += ["", f"## {name}", "", "| step | median s | runs, s |", "|---|---:|---|"]
        for step, *_ in STEPS:
            seconds = [steps.get(step) for _, steps in measured]
            if any(s is None for s in seconds):
                continue
            lines.append(f"| {step} | {statistics.median(seconds):.2f} | {', '.join(f'{s:.2f}' for s in seconds)} |")
        lines.append(f"| **total (the whole process)** | **{statistics.median(t for t, _ in measured):.1f}** | "
                     f"{', '.join(f'{t:.1f}' for t, _ in measured)} |")
    lines += ["", "Steps are medians taken one by one, so they need not add up to the median total. Placement runs "
              "in a thread beside the tracking and the motion (the row 'beside' is the wall time of the two), and the "
              "deformation in two processes (the frames in runs of 8, taken in turn)."]
    publish("animate_speed.md", lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
