"""Peak memory of `encode`, `animate`, `aus`, `decode` and `speaker track` against the video's length: 10 s to
10 minutes.

    python3 benchmarks/memory_length.py [--lengths 10,60,300] [--baseline OTHER_CHECKOUT/src [--baseline-lengths 10,60]]

The videos are d6 (a 33.6 s, 480x480, 30 fps performance from ../shared/data/videos) played forwards
and backwards until the length is reached, written once into a cache folder (the system's temporary
folder; ``--work`` to choose). Each job is the README's command onto the ICT-FaceKit head, run as a
fresh process, its memory (with that of the processes it forks) sampled as it runs (see :func:`peak`):

- ``faceanim encode VIDEO -o x.fap``
- ``faceanim animate VIDEO --target ICT -o x.glb``
- ``faceanim aus VIDEO -o x.csv``
- ``faceanim decode x.fap --target ICT -o y.glb``
- ``faceanim speaker track VIDEO --model SPEAKER -o x.csv``: the clone's analysis by synthesis, with a
  speaker model and textures made once from d6 itself (``speaker build``, ``speaker textures``; not
  measured)
- ``batch task``: what one Ray task of ``faceanim batch --do encode,aus,blendshapes,animate --target ICT`` runs for
  a video (:func:`faceanim.dataset.process_video`), in a process of its own (a Ray worker's own
  footprint, about 0.1 GB, comes on top)

``--jobs`` picks some of them (the table then goes to ``memory_length_JOBS.md``).

The goal (issue 20): flat in length, and at most 1.5 GB for ``animate`` at any length.
``--baseline`` runs the same jobs with another checkout's ``src`` first on ``PYTHONPATH`` (the code
before a change), side by side in the same run. Writes ``benchmarks/results/memory_length.md``.
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from report import publish  # noqa: E402

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"
SOURCE = DATA / "videos" / "d6.mp4"
TARGET = DATA / "ict_facekit" / "obj" / "generic_neutral_mesh.obj"
GOAL_GB = 1.5
JOBS = ("encode", "animate", "aus", "decode", "speaker track", "batch task")


def looped_video(seconds: int, folder: Path) -> Path:
    """d6 forwards, backwards, forwards... to ``seconds`` (at its 30 fps), as H.264; made once."""
    import av
    import numpy as np

    path = folder / f"d6_loop_{seconds}s.mp4"
    if path.exists():
        return path
    with av.open(str(SOURCE)) as container:
        stream = container.streams.video[0]
        fps = float(stream.average_rate)
        frames = [frame.to_ndarray(format="rgb24") for frame in container.decode(stream)]
    order = np.r_[np.arange(len(frames)), np.arange(len(frames) - 2, 0, -1)]
    total = int(round(seconds * fps))
    partial = path.with_suffix(".partial.mp4")
    with av.open(str(partial), mode="w") as out:
        video = out.add_stream("libx264", rate=round(fps))
        video.width, video.height, video.pix_fmt = frames[0].shape[1], frames[0].shape[0], "yuv420p"
        for t in range(total):
            for packet in video.encode(av.VideoFrame.from_ndarray(frames[order[t % len(order)]], format="rgb24")):
                out.mux(packet)
        for packet in video.encode():
            out.mux(packet)
    partial.replace(path)
    return path


def speaker_model(folder: Path) -> Path:
    """A speaker model with its textures made from d6 (``speaker build`` then ``speaker textures``); made
    once."""
    path = folder / "d6_speaker.npz"
    if not path.exists():
        partial = folder / "d6_speaker.partial.npz"
        for command in (["speaker", "build", str(SOURCE), "-o", str(partial)],
                        ["speaker", "textures", str(SOURCE), "--model", str(partial), "-o", str(partial)]):
            subprocess.run([sys.executable, "-m", "faceanim.cli", *command], check=True, stdout=subprocess.DEVNULL)
        partial.replace(path)
    return path


BATCH_TASK = """
import sys
from pathlib import Path
from faceanim.dataset import process_video
from faceanim.inputs import load_target
from faceanim.manifest import Video
video, folder, target = sys.argv[1:4]
result = process_video(Video(Path(video), Path(video).stem), ("encode", "aus", "blendshapes", "animate"), Path(folder),
                       force=True, target=load_target(target))
if result.status != "done":
    raise SystemExit(result.error)
"""


def peak(command: list[str], src: str | None) -> tuple[float, float, float]:
    """(peak resident memory in GB of its largest process, peak of its processes' memory together in GB,
    wall seconds) of ``faceanim COMMAND`` (or, for a command that starts with ``-c``, that Python
    program) run under /usr/bin/time.

    /usr/bin/time gives the largest single process's peak; ``animate`` and ``decode`` deform their
    frames in forked processes too, so the tree is also sampled every 20 ms and the proportional set
    sizes (Pss: a page shared by the forked processes counted once in all) of all its processes summed.
    """
    env = dict(os.environ)
    if src is not None:
        env["PYTHONPATH"] = src + os.pathsep + env.get("PYTHONPATH", "")
    program = command if command[0] == "-c" else ["-m", "faceanim.cli", *command]
    with tempfile.NamedTemporaryFile("r", suffix=".time") as report, tempfile.TemporaryFile("w+") as said:
        started = subprocess.Popen(["/usr/bin/time", "-f", "%M %e", "-o", report.name, sys.executable, *program],
                                   env=env, stdout=subprocess.DEVNULL, stderr=said, text=True)
        together = 0
        while started.poll() is None:
            together = max(together, tree_pss(started.pid))
            time.sleep(0.02)
        if started.returncode != 0:
            said.seek(0)
            raise SystemExit(f"{' '.join(command)} failed:\n{said.read()}")
        kilobytes, seconds = report.read().split()[-2:]
    return int(kilobytes) / 1024**2, together / 1024**2, float(seconds)


def tree_pss(root: int) -> int:
    """Kilobytes: the Pss of process ``root`` and all its descendants now (0 for those gone)."""
    total, pending = 0, [root]
    while pending:
        pid = pending.pop()
        try:
            for line in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines():
                if line.startswith("Pss:"):
                    total += int(line.split()[1])
                    break
            for task in Path(f"/proc/{pid}/task").iterdir():
                pending += [int(child) for child in (task / "children").read_text().split()]
        except (FileNotFoundError, ProcessLookupError, PermissionError):
            continue
    return total


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lengths", default="10,60,300,600", help="video lengths in seconds (default 10,60,300,600)")
    parser.add_argument("--baseline", metavar="SRC", help="another checkout's src folder, run side by side")
    parser.add_argument("--baseline-lengths", help="the lengths the baseline runs at (default: --lengths)")
    parser.add_argument("--jobs", default=",".join(JOBS), help=f"which jobs (default all: {','.join(JOBS)})")
    parser.add_argument("--work", default=str(Path(tempfile.gettempdir()) / "faceanim-memory"),
                        help="where the looped videos and outputs go")
    args = parser.parse_args()
    if not SOURCE.exists() or not TARGET.exists():
        raise SystemExit(f"needs {SOURCE} and {TARGET} (../shared/data)")
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    lengths = [int(x) for x in args.lengths.split(",")]
    chosen = [j.strip() for j in args.jobs.split(",")]
    if unknown := [j for j in chosen if j not in JOBS]:
        raise SystemExit(f"--jobs: unknown {unknown[0]!r}; the jobs are {', '.join(JOBS)}")
    baseline_lengths = [int(x) for x in (args.baseline_lengths or args.lengths).split(",")]
    versions = [("this checkout", None)] + ([("baseline", args.baseline)] if args.baseline else [])
    rows = []
    for seconds in lengths:
        video = looped_video(seconds, work)
        for name, src in versions:
            if src is not None and seconds not in baseline_lengths:
                continue
            tag = f"{seconds}s_{'base' if src else 'this'}"
            fap, glb, decoded = (work / f"{tag}.fap", work / f"{tag}.glb", work / f"{tag}_decoded.glb")
            jobs = (("encode", ["encode", str(video), "-o", str(fap)]),
                    ("animate", ["animate", str(video), "--target", str(TARGET), "-o", str(glb)]),
                    ("aus", ["aus", str(video), "-o", str(work / f"{tag}_aus.csv")]),
                    ("decode", ["decode", str(fap), "--target", str(TARGET), "-o", str(decoded)]),
                    ("speaker track", ["speaker", "track", str(video), "--model", str(work / "d6_speaker.npz"), "-o",
                                       str(work / f"{tag}_speaker.csv")]),
                    ("batch task", ["-c", BATCH_TASK, str(video), str(work / f"{tag}_batch"), str(TARGET)]))
            for job, command in jobs:
                if job not in chosen:
                    continue
                if job == "batch task":
                    (work / f"{tag}_batch").mkdir(exist_ok=True)
                if job == "speaker track":
                    speaker_model(work)
                largest, gigabytes, wall = peak(command, src)
                rows.append((name, job, seconds, gigabytes, wall))
                print(f"{name:<14} {job:<8} {seconds:>5} s  {gigabytes:6.2f} GB together "
                      f"({largest:.2f} GB its largest process)  {wall:7.1f} s", flush=True)
    lines = ["# Peak memory against the video's length", "",
             f"`python3 benchmarks/memory_length.py --lengths {args.lengths}"
             + ("" if chosen == list(JOBS) else f" --jobs '{args.jobs}'")
             + (f" --baseline SRC --baseline-lengths {','.join(map(str, baseline_lengths))}`" if args.baseline
                else "`"), "",
             f"d6 looped forwards and backwards (30 fps, 480x480) onto the ICT-FaceKit head (26,719 vertices); "
             f"{platform.machine()}, {os.cpu_count()} cores; the peak of the job's processes' memory together "
             "(their Pss summed, sampled every 20 ms; the deformation runs in forked processes too). "
             f"Goal: flat in length, animate at most {GOAL_GB} GB.", "",
             "| code | job | " + " | ".join(f"{s} s ({s * 30} frames)" for s in lengths) + " | growth per minute |",
             "|---|---|" + "---|" * len(lengths) + "---|"]
    for name, _ in versions:
        for job in chosen:
            cells = {s: (g, w) for n, j, s, g, w in rows if n == name and j == job}
            ran = sorted(cells)
            growth = ((cells[ran[-1]][0] - cells[ran[0]][0]) / ((ran[-1] - ran[0]) / 60)
                      if len(ran) > 1 else float("nan"))
            lines.append(f"| {name} | {job} | " + " | ".join(f"{cells[s][0]:.2f} GB ({cells[s][1]:.0f} s)" if s in cells
                                                             else "not run" for s in lengths)
                         + (f" | {growth * 1024:+.0f} MB |" if len(ran) > 1 else " | - |"))
    everything = chosen == list(JOBS)
    publish("memory_length.md" if everything else f"memory_length_{'_'.join(chosen).replace(' ', '_')}.md", lines)


if __name__ == "__main__":
    main()
