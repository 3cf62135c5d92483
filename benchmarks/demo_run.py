"""`faceanim demo`, timed step by step, with how well the capture reads back the scripted FAPs.

    python3 benchmarks/demo_run.py [--runs N]

The demo's performance is scripted, so its true FAPs are known: the table gives, per expression, the
correlation over the clip between scripted and recovered FAP curves and the gain (recovered / scripted,
least squares; 1 is exact). Timings are wall-clock on this machine, the best of N runs.
"""

from __future__ import annotations

import argparse
import os
import platform
import tempfile

from report import publish

from faceanim.demo import run_demo


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    results = []
    for _ in range(args.runs):
        with tempfile.TemporaryDirectory() as folder:
            results.append(run_demo(folder))
    best = min(results, key=lambda r: sum(s for _, s in r.steps))
    lines = [f"# faceanim demo ({platform.processor() or platform.machine()}, {os.cpu_count()} cores; "
             f"best of {args.runs} runs)", "", "| step | seconds |", "|---|---:|"]
    lines += [f"| {what} | {seconds:.1f} |" for what, seconds in best.steps]
    lines += [f"| **total** | **{sum(s for _, s in best.steps):.1f}** |", "",
              "All runs, total seconds: " + ", ".join(f"{sum(s for _, s in r.steps):.1f}" for r in results), "",
              "| expression | FAPs | correlation | gain |", "|---|---|---:|---:|"]
    lines += [f"| {name} | {faps} | {corr:.2f} | {gain:.2f} |" for name, faps, corr, gain in best.recovery]
    publish("demo_run.md", lines)


if __name__ == "__main__":
    main()
