"""Whole datasets: ``faceanim batch`` runs the single commands' work on many videos, one Ray task per
video, locally (``ray.init(num_cpus=workers)``) or on a cluster (``address``).

Each task tracks its video once and writes the outputs asked for (``encode``: ``NAME.fap``, ``aus``:
``NAME_aus.csv``, ``blendshapes``: ``NAME_take.csv``, the Live Link take, ``animate``: ``NAME.glb``,
``plot``: ``NAME_curves.png``, the FAPs as ``faceanim plot`` draws them), the same files the single
commands write, all together or none (:func:`faceanim.atomic.output_group`). A video that cannot be
read or shows no face fails alone, with its one-line reason, and the others go on. An output already
in the folder is not made again (``force`` redoes it), so a re-run after a failure or an interrupt
does only what is missing.
The summary (``batch_summary.csv`` in the folder, and a table) gives per video: frames, the share with
a face tracked, seconds, outputs, error.
"""

from __future__ import annotations

import os
import re
import socket
import time
from dataclasses import dataclass, field
from pathlib import Path

from .cpus import usable_cpus
from .errors import InputError
from .manifest import STEPS, Video, collect_videos, outputs_of
from .progress import Quiet

__all__ = ["run_batch", "BatchResult", "VideoResult", "process_video", "remove_leftovers", "SUMMARY_NAME",
           "SUMMARY_COLUMNS"]

SUMMARY_NAME = "batch_summary.csv"
SUMMARY_COLUMNS = ("video", "name", "success", "status", "frames", "tracked", "seconds", "outputs", "error")


@dataclass(frozen=True)
class VideoResult:
    """What became of one video: ``status`` done, skipped (its outputs were there) or failed."""

    video: str
    name: str
    status: str
    frames: int | None = None
    tracked: float | None = None  # share of frames with a face found, 0-1
    seconds: float = 0.0
    outputs: tuple[str, ...] = ()
    error: str = ""


@dataclass
class BatchResult:
    """The summary of a batch: one :class:`VideoResult` per video, in the inputs' order."""

    folder: Path
    videos: list[VideoResult] = field(default_factory=list)
    seconds: float = 0.0  # the whole batch, Ray's start and stop included
    startup: float = 0.0  # of which starting Ray (locally) or joining the cluster

    @property
    def failed(self) -> list[VideoResult]:
        return [v for v in self.videos if v.status == "failed"]

    def table(self) -> str:
        """The summary as a printed table."""
        rows = [("video", "status", "frames", "tracked", "seconds", "outputs / error")]
        for v in self.videos:
            rows.append((v.name, v.status, "" if v.frames is None else str(v.frames),
                         "" if v.tracked is None else f"{100 * v.tracked:.0f}%", f"{v.seconds:.1f}",
                         v.error or " ".join(v.outputs)))
        widths = [max(len(r[k]) for r in rows) for k in range(5)]
        lines = ["  ".join(c.ljust(w) if k in (0, 1) else c.rjust(w) for k, (c, w) in enumerate(zip(r, widths,
                 strict=False))) + "  " + r[5] for r in rows]
        done = sum(v.status == "done" for v in self.videos)
        skipped = sum(v.status == "skipped" for v in self.videos)
        lines.append(f"{len(self.videos)} videos: {done} done, {skipped} skipped (outputs there), {len(self.failed)} "
                     f"failed, in {self.seconds:.1f} s; summary in {self.folder / SUMMARY_NAME}")
        return "\n".join(lines)


def _one_line(exc: BaseException) -> str:
    from .errors import InputError as Declared

    text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    if isinstance(exc, (Declared, OSError, ValueError)):
        return text or type(exc).__name__
    return f"{type(exc).__name__}: {text}"  # a fault in faceanim: still one line, named as such


def process_video(video: Video, steps: tuple[str, ...], folder, *, force: bool = False, target=None,
                  report=None) -> VideoResult:
    """Do ``steps`` for one video into ``folder``: track it once, then write each output not already
    there (all of them with ``force``), together or none. Never raises for the video's own faults
    (unreadable, no face, a bad option): they come back as a failed :class:`VideoResult`. ``report``:
    a :class:`FrameCount` actor the tracked frames are told to (every :data:`REPORT_EVERY`), or None."""
    from . import pipeline
    from .arkit import blendshapes
    from .atomic import output_group
    from .expressions import aus
    from .inputs import captured_source
    from .mpeg4.fapfile import read_fap

    start = time.perf_counter()
    wanted = outputs_of(video, steps, folder)
    todo = {s: p for s, p in wanted.items() if force or not p.exists()}
    if not todo:
        return VideoResult(str(video.path), video.name, "skipped", outputs=tuple(p.name for p in wanted.values()))
    frames = tracked = None
    try:
        if not video.path.is_file():
            raise InputError(f"{video.path}: no such file")
        capture = None
        if todo.keys() - {"plot"}:  # tracked once, streamed through disk, for every step
            capture = captured_source(video.path, neutral=video.neutral, smoothing=video.smoothing,
                                      folder=Path(folder), progress=None if report is None else _Reporter(report))
            frames, tracked = len(capture), float(capture.valid.mean())
        with output_group():  # this video's outputs appear together, or none of them
            stream = None
            if "encode" in todo:
                stream, _ = pipeline.encode(video.path, todo["encode"], capture=capture)
            if "plot" in todo:
                _plot_faps(stream if stream is not None else read_fap(wanted["encode"]), todo["plot"], video)
            if "aus" in todo:
                aus(video.path, todo["aus"], smoothing=video.smoothing, capture=capture)
            if "blendshapes" in todo:
                blendshapes(video.path, todo["blendshapes"], neutral=video.neutral, smoothing=video.smoothing,
                            capture=capture)
            if "animate" in todo:
                own = None if video.target is None else pipeline.load_target(video.target)
                # A task holds one of the cluster's CPUs: it deforms in its own process only.
                pipeline.animate(video.path, todo["animate"], target=own or target, capture=capture, workers=1)
    except Exception as exc:  # noqa: BLE001 - one video's fault is its own, reported in its row
        return VideoResult(str(video.path), video.name, "failed", frames, tracked, time.perf_counter() - start,
                           error=_one_line(exc))
    return VideoResult(str(video.path), video.name, "done", frames, tracked, time.perf_counter() - start,
                       tuple(p.name for p in wanted.values()))


REPORT_EVERY = 25  # frames a task tracks between two reports to the driver's progress bar


class FrameCount:
    """The frames tracked across a batch, as its tasks report them (made a Ray actor by
    :func:`run_batch` only when progress bars are shown): :meth:`add` from the tasks, :meth:`take` from
    the driver, which redraws its frames bar with what came in since it last asked."""

    def __init__(self):
        self._new = 0

    def add(self, frames: int) -> None:
        self._new += frames

    def take(self) -> int:
        new, self._new = self._new, 0
        return new


class _Reporter(Quiet):
    """A task's frame loop, told to the driver's :class:`FrameCount` actor every :data:`REPORT_EVERY`
    frames (a call that does not wait for an answer) and at its end; shows nothing itself."""

    def __init__(self, count):
        super().__init__()
        self._count = count

    def bar(self, iterable, *, total=None, desc: str, unit: str = "frame"):
        return self._reported(iterable) if unit == "frame" else iterable

    def _reported(self, iterable):
        done = 0
        try:
            for item in iterable:
                yield item
                done += 1
                if done == REPORT_EVERY:
                    self._count.add.remote(done)
                    done = 0
        finally:
            if done:
                self._count.add.remote(done)


def _temporary_names(names) -> re.Pattern:
    """The hidden temporaries :mod:`faceanim.atomic` writes outputs ``names`` through
    (``.NAME.XXXXXXXX.SUFFIX``, 8 random characters: hex now, ``tempfile``'s before), and faceanim's own folder probes
    and frame stores (``.faceanim-probe-XXXXXXXX``, ``.faceanim-frames-XXXXXXXX``)."""
    random = r"[a-z0-9_]{8}"
    ours = [re.escape(f".{name}.") + random + re.escape(Path(name).suffix) for name in names]
    ours += [rf"\.faceanim-(?:probe|frames)-{random}"]
    return re.compile("|".join(f"(?:{p})" for p in ours))


def remove_leftovers(folder, videos, steps) -> list[Path]:
    """Remove from ``folder`` the hidden temporary files that a batch's workers, stopped mid-write
    (Ctrl-C, a killed worker, a lost cluster node), left behind: only those named after an output of
    ``videos`` and ``steps`` (or the summary) by :mod:`faceanim.atomic`'s pattern, and faceanim's own
    hidden probes and frame stores, never a user's file. A probe or frame store of another faceanim job
    writing into the same folder at that moment is removed too: give each running batch its own folder.
    Returns what was removed. :func:`run_batch` calls it on start and after an interrupt."""
    folder = Path(folder)
    if not folder.is_dir():
        return []
    names = [p.name for v in videos for p in outputs_of(v, steps, folder).values()] + [SUMMARY_NAME]
    pattern = _temporary_names(names)
    removed = []
    for path in folder.iterdir():
        if path.name.startswith(".") and pattern.fullmatch(path.name) and path.is_file() and not path.is_symlink():
            path.unlink(missing_ok=True)
            removed.append(path)
    return removed


def _plot_faps(stream, path: Path, video: Video) -> None:
    """``video``'s FAP curves as ``faceanim plot`` draws them, into ``path``."""
    from .atomic import atomic_output
    from .export.plots import fap_png

    png = fap_png(stream, title=f"{video.path.name}: FAPs")
    with atomic_output(path, suffix=".png") as tmp:
        tmp.write_bytes(png)


def _parse_steps(do) -> tuple[str, ...]:
    steps = tuple(s.strip() for s in (do.split(",") if isinstance(do, str) else do) if s.strip())
    unknown = [s for s in steps if s not in STEPS]
    if not steps or unknown:
        raise InputError(f"--do takes {', '.join(STEPS)} (comma-separated), got {','.join(unknown) or 'nothing'}")
    if "plot" in steps and "encode" not in steps:
        raise InputError("--do plot draws each video's FAPs: ask for encode too (--do encode,plot)")
    return tuple(dict.fromkeys(steps))


def _check_address(address: str) -> None:
    """A ``ray://HOST:PORT`` or ``HOST:PORT`` address answers on TCP (said in one line if not), so a
    wrong address fails at once, not after Ray's own long wait."""
    if address == "auto":
        return
    where = address.split("://", 1)[-1]
    host, _, port = where.rpartition(":")
    if not host or not port.isdigit():
        raise InputError(f"--address {address}: give ray://HOST:PORT, HOST:PORT or auto")
    try:
        socket.create_connection((host, int(port)), timeout=5).close()
    except OSError as exc:
        raise InputError(f"--address {address}: no Ray cluster answers there ({exc.strerror or exc})") from None


def _start_ray(workers: int | None, address: str | None):
    try:
        import ray
    except ImportError:
        raise ImportError("faceanim batch needs Ray: pip install 'faceanim[batch]'") from None
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")  # nothing leaves the machine
    if address is not None:
        _check_address(address)
        try:
            ray.init(address=address, log_to_driver=False, logging_level="error")
        except (ConnectionError, RuntimeError, ValueError) as exc:
            raise InputError(f"--address {address}: {_one_line(exc)}") from None
    else:
        ray.init(num_cpus=workers or usable_cpus(), include_dashboard=False, log_to_driver=False,
                 logging_level="error")
    return ray


def _write_summary(folder: Path, result: BatchResult) -> None:
    from .atomic import atomic_output

    lines = [",".join(SUMMARY_COLUMNS)]
    for v in result.videos:
        cells = [v.video, v.name, "0" if v.status == "failed" else "1", v.status,
                 "" if v.frames is None else str(v.frames), "" if v.tracked is None else f"{v.tracked:.4f}",
                 f"{v.seconds:.2f}", " ".join(v.outputs), v.error]
        lines.append(",".join('"' + c.replace('"', '""') + '"' if any(x in c for x in ',"\n') else c for c in cells))
    with atomic_output(folder / SUMMARY_NAME) as tmp:
        tmp.write_text("\n".join(lines) + "\n")


def longest_first(videos) -> list[int]:
    """The order to hand ``videos`` to the workers: the largest files first (size stands in for length
    without opening them; a bad file fails in its own task, not here). Scheduled in input order, a
    long video that comes last runs alone on one worker while the others wait: on a batch of 6 shared
    videos that tail alone held 2 workers to 1.47x of 1."""
    def size(k: int) -> int:
        try:
            return videos[k].path.stat().st_size
        except OSError:
            return 0
    return sorted(range(len(videos)), key=lambda k: (-size(k), k))


def run_batch(inputs, output, *, do=("encode",), target_mesh=None, workers: int | None = None,
              address: str | None = None, force: bool = False, progress=None) -> BatchResult:
    """``faceanim batch``: ``do`` (``encode``, ``aus``, ``blendshapes``, ``animate``, ``plot``, or a
    comma-separated string) for every video named by ``inputs`` (files, folders, globs, manifests: see
    :func:`~faceanim.manifest.collect_videos`), one Ray task per video, outputs into the folder
    ``output`` (made if missing). ``target_mesh``: the face ``animate`` moves (default: the avatar),
    loaded once; ``workers``: tasks at once on this machine (default: the CPUs this process may use,
    :func:`~faceanim.cpus.usable_cpus`); ``address``: a Ray cluster (``ray://HOST:PORT``, ``HOST:PORT``
    or ``auto``) instead; ``force``: redo outputs already there. Returns the :class:`BatchResult`;
    writes ``batch_summary.csv`` beside the outputs.

    Raises
    ------
    InputError
        Before any work and with nothing written: a bad input or manifest, an output folder that is a
        file, a bad ``do`` or ``workers``, an unreachable ``address``, a target that cannot be loaded.
    """
    from .outputs import check_output_folder
    from .progress import as_progress

    start = time.perf_counter()
    steps = _parse_steps(do)
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise InputError(f"--workers must be a whole number from 1, got {workers!r}")
    if workers is not None and address is not None:
        raise InputError("--workers sets up a local Ray; a cluster given by --address has its own workers")
    folder = check_output_folder("-o", output)
    videos = collect_videos(inputs)
    shown = as_progress(progress)
    target = None
    if "animate" in steps and any(v.target is None for v in videos):
        from .inputs import load_target

        if target_mesh is not None and not Path(target_mesh).is_file():
            raise InputError(f"--target {target_mesh}: no such file")
        target = load_target(target_mesh, progress=shown)  # once, shared by every task through Ray's store
    remove_leftovers(folder, videos, steps)  # a run stopped mid-write before this one left them
    joining = time.perf_counter()
    ray = _start_ray(workers, address)
    startup = time.perf_counter() - joining
    frames_bar = None
    try:
        folder.mkdir(parents=True, exist_ok=True)
        task = ray.remote(num_cpus=1, max_retries=0)(process_video)
        shared = ray.put(target)
        count = ray.remote(num_cpus=0)(FrameCount).remote() if shown.shows_bars else None
        pending = {task.remote(videos[k], steps, folder.absolute(), force=force, target=shared, report=count): k
                   for k in longest_first(videos)}
        results: list[VideoResult | None] = [None] * len(videos)

        def finished():
            waiting = list(pending)
            while waiting:
                done, waiting = ray.wait(waiting, num_returns=1, timeout=None if count is None else 0.5)
                if count is not None:
                    frames_bar.update(ray.get(count.take.remote()))
                if done:
                    results[pending[done[0]]] = ray.get(done[0])
                    yield results[pending[done[0]]]

        videos_bar = shown.bar(finished(), total=len(videos), desc=f"{'+'.join(steps)} on {len(videos)} videos",
                               unit="video")
        if count is not None:
            from tqdm import tqdm

            frames_bar = tqdm(desc="frames tracked", unit="frame", file=shown.stream,
                              bar_format="{desc}: {n_fmt} frames [{elapsed}, {rate_fmt}]")
        for _ in videos_bar:
            pass
        if count is not None:
            frames_bar.update(ray.get(count.take.remote()))  # what came in with the last video
    except BaseException:
        for ref in list(locals().get("pending", {})):
            ray.cancel(ref, force=True)
        raise
    finally:
        if frames_bar is not None:
            frames_bar.close()
        ray.shutdown()
        remove_leftovers(folder, videos, steps)  # what workers stopped mid-write (an interrupt) left
    result = BatchResult(folder, results, time.perf_counter() - start, startup)
    _write_summary(folder, result)
    return result
