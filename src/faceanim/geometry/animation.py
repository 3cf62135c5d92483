"""`Animation`: a mesh and its vertex positions per frame, held or made on demand.

A long performance on a dense head is gigabytes of positions (26,000 vertices take 0.6 MB a frame),
so an animation that comes out of a deformer is not held: it is a function that makes any run of
frames, and every consumer (the morph compression, a preview, an OBJ sequence) reads it in chunks.
What that costs in memory is one chunk, whatever the length. Where several consumers read the same
frames, :func:`spilled` makes them once into a temporary file and lets each read them back from
there: the frames cost disk (0.3 MB a frame on that head), not memory, and are deformed once.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import multiprocessing.connection
import os
import pickle
import signal
import traceback
from collections.abc import Callable, Iterator

import numpy as np

from ..cpus import usable_cpus
from ..framestore import FrameStore
from ..validation import as_array
from .mesh import Mesh

__all__ = ["Animation", "FrameSource", "spilled", "worker_count"]

FrameSource = Callable[[int, int], np.ndarray]
"""``frames(start, stop)`` -> positions ``(stop - start, V, 3)`` float64 of frames ``start .. stop - 1``."""

CHUNK = 32  # frames made at once when streaming: a few tens of MB on a dense head
PARALLEL_RUN = 8  # frames a process making them in parallel makes at a time (runs differ in cost)
MOST_WORKERS = 4  # each holds a run of frames' working arrays besides what it shares with the job


class Animation:
    """``mesh`` (its own vertices are the rest pose), positions ``(T, V, 3)`` float64 (model units) and ``fps``.

    ``Animation(mesh, positions, fps)`` holds the positions given (copied, read-only);
    :meth:`streamed` makes them on demand from a :data:`FrameSource`, so that memory does not grow with
    the number of frames. Read them with :meth:`chunks` or :meth:`frames`; :attr:`positions` makes
    them all at once (for short animations: it costs ``T x V x 24`` bytes).

    >>> mesh = Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    >>> rise = Animation.streamed(mesh, lambda a, b: mesh.vertices + np.arange(a, b)[:, None, None], 5, 25.0)
    >>> len(rise), [len(c) for c in rise.chunks(2)], float(rise.positions[4, 0, 0])
    (5, [2, 2, 1], 4.0)
    """

    __slots__ = ("mesh", "fps", "_length", "_held", "_source")

    def __init__(self, mesh: Mesh, positions, fps: float):
        held = as_array(positions, "positions", shape=("T", len(mesh.vertices), 3), min_length=1).copy()
        held.flags.writeable = False
        self._init(mesh, len(held), fps, held, None)

    @classmethod
    def streamed(cls, mesh: Mesh, frames: FrameSource, length: int, fps: float) -> Animation:
        """An animation of ``length`` frames whose positions ``frames(start, stop)`` makes when read."""
        if int(length) != length or length < 1:
            raise ValueError(f"length must be a whole number of at least 1, got {length}")
        if not callable(frames):
            raise TypeError(f"frames must be a function (start, stop) -> positions, got {type(frames).__name__}")
        animation = cls.__new__(cls)
        animation._init(mesh, int(length), fps, None, frames)
        return animation

    def _init(self, mesh, length, fps, held, source) -> None:
        if not isinstance(mesh, Mesh):
            raise TypeError(f"mesh must be a Mesh, got {type(mesh).__name__}")
        if not np.isfinite(fps) or fps <= 0:
            raise ValueError(f"fps must be positive, got {fps}")
        for name, value in (("mesh", mesh), ("fps", float(fps)), ("_length", length), ("_held", held),
                            ("_source", source)):
            object.__setattr__(self, name, value)

    def __setattr__(self, name, value):
        raise AttributeError(f"an Animation is immutable; {name} cannot be set")

    def __len__(self) -> int:
        return self._length

    @property
    def is_streamed(self) -> bool:
        """True when the positions are made on demand rather than held."""
        return self._held is None

    def chunk(self, start: int, stop: int) -> np.ndarray:
        """Positions ``(stop - start, V, 3)`` of frames ``start .. stop - 1``."""
        if not 0 <= start < stop <= self._length:
            raise IndexError(f"frames {start}:{stop} are outside the animation's 0:{self._length}")
        if self._held is not None:
            return self._held[start:stop]
        made = np.asarray(self._source(start, stop), dtype=np.float64)
        if made.shape != (stop - start, len(self.mesh.vertices), 3):
            raise ValueError(f"the frame source made shape {made.shape} for frames {start}:{stop}, expected "
                             f"{(stop - start, len(self.mesh.vertices), 3)}")
        return made

    def chunks(self, size: int = CHUNK) -> Iterator[np.ndarray]:
        """Positions in runs of ``size`` frames (the last may be shorter), first to last."""
        if int(size) != size or size < 1:
            raise ValueError(f"size must be a whole number of at least 1, got {size}")
        for start in range(0, self._length, int(size)):
            yield self.chunk(start, min(start + int(size), self._length))

    def frames(self) -> Iterator[np.ndarray]:
        """Positions ``(V, 3)`` frame by frame."""
        for chunk in self.chunks():
            yield from chunk

    @property
    def positions(self) -> np.ndarray:
        """All positions ``(T, V, 3)``, read-only; a streamed animation makes them all, every time asked."""
        if self._held is not None:
            return self._held
        whole = np.concatenate(list(self.chunks()))
        whole.flags.writeable = False
        return whole

    def map(self, change: Callable[[int, int, np.ndarray], np.ndarray]) -> Animation:
        """A streamed animation whose frames are ``change(start, stop, positions)`` of these."""
        return Animation.streamed(self.mesh, lambda a, b: change(a, b, self.chunk(a, b)), self._length, self.fps)


@contextlib.contextmanager
def spilled(animation: Animation, *, folder=None, progress=None, desc: str = "deforming", workers=1):
    """Yield ``animation`` with its frames made once and kept in a temporary file, read back in chunks.

    The file holds each frame's displacement from the rest as float32 (what a glTF file keeps, to
    about 1e-7 of the motion's size); it has no name in any folder (it is unlinked as it is made), so
    nothing is left behind however the process ends. It goes in ``folder`` (the jobs pass their
    output's folder: the disk the results go to), else the system's temporary folder (``TMPDIR``;
    where that is a tmpfs, the frames cost memory after all). A held animation is yielded as it is.
    ``progress`` (a :class:`~faceanim.progress.Progress`) shows the frames being made, as ``desc``.
    ``workers``: processes making the frames (None: :func:`worker_count`'s default), each a run of
    :data:`PARALLEL_RUN` frames at a time (see :func:`_made_in_parallel`); the frames are the same
    whatever their number, to float32's rounding (a deformer's float64 sums over runs of other
    lengths can round differently in the last place).

    >>> mesh = Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    >>> made = []
    >>> def rise(a, b):
    ...     made.append((a, b))
    ...     return mesh.vertices + np.arange(a, b)[:, None, None] / 4
    >>> with spilled(Animation.streamed(mesh, rise, 5, 25.0)) as kept:
    ...     twice = [float(kept.chunk(4, 5)[0, 0, 0]) for _ in range(2)]
    >>> twice, made
    ([1.0, 1.0], [(0, 5)])
    """
    from ..progress import as_progress

    workers = worker_count(workers)
    if not animation.is_streamed:
        yield animation
        return
    rest = animation.mesh.vertices
    with FrameStore(rest.shape, folder=folder) as store:
        if workers > 1 and len(animation) > PARALLEL_RUN and "fork" in multiprocessing.get_all_start_methods():
            store.reserve(len(animation))
            with contextlib.closing(_made_in_parallel(animation, store, workers)) as making:
                for _ in as_progress(progress).bar(making, total=len(animation), desc=desc):
                    pass
        else:
            for frame in as_progress(progress).bar(animation.frames(), total=len(animation), desc=desc):
                store.append(frame - rest)
        yield Animation.streamed(animation.mesh, lambda start, stop: rest + store[start:stop], len(animation),
                                 animation.fps)


def worker_count(workers=None) -> int:
    """The processes :func:`spilled` makes frames in: ``workers``, a whole number of at least 1
    (``ValueError`` otherwise); by default the CPUs this process may use (:func:`~faceanim.cpus.usable_cpus`), at
    most :data:`MOST_WORKERS`."""
    if workers is None:
        return max(1, min(MOST_WORKERS, usable_cpus()))
    if isinstance(workers, bool) or not isinstance(workers, (int, float)) or int(workers) != workers or workers < 1:
        raise ValueError(f"workers must be a whole number of at least 1, got {workers!r}")
    return int(workers)


def _made_in_parallel(animation: Animation, store: FrameStore, workers: int) -> Iterator[None]:
    """Makes ``animation``'s frames into ``store`` (reserved to its length) as displacements from the
    rest, in this process and ``workers - 1`` forked ones, each taking the next run of
    :data:`PARALLEL_RUN` frames as it finishes one (runs differ in cost: a frame that folds is
    relaxed); yields once per frame made, by any of them, as they are made.

    Forked, not spawned: a worker starts with the frame source as it stands (a deformer whose set-up
    took seconds) instead of building it again, and writes its runs straight into the store's file.
    A worker's error (with its traceback as a note) is raised here and stops the others at once; so
    does an interruption here, or this process's end (a worker whose parent is gone stops at its
    next run). A worker killed from outside (the kernel's out-of-memory killer) is an ``OSError``.
    """
    context = multiprocessing.get_context("fork")
    claimed = context.Value("q", 0)  # runs handed out
    made = context.Value("q", 0)  # frames written
    failures = context.SimpleQueue()
    rest = animation.mesh.vertices
    runs = -(-len(animation) // PARALLEL_RUN)
    parent = os.getpid()

    def stop_claiming() -> None:
        with claimed.get_lock():
            claimed.value = runs

    def one_run() -> bool:
        with claimed.get_lock():
            run = claimed.value
            claimed.value += 1
        orphaned = os.getpid() != parent and os.getppid() != parent  # a worker whose job was killed outright
        if run >= runs or orphaned:
            return False
        start, stop = run * PARALLEL_RUN, min((run + 1) * PARALLEL_RUN, len(animation))
        store[start:stop] = animation.chunk(start, stop) - rest
        with made.get_lock():
            made.value += stop - start
        return True

    def work() -> None:
        # The parent decides when to stop: a Ctrl-C reaches it too, and it ends the workers; SIGTERM
        # (its way of ending them) ends a worker where it stands, not through the command's handler.
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        signal.pthread_sigmask(signal.SIG_UNBLOCK, _STOPPING)
        try:
            while one_run():
                pass
        except BaseException as error:  # noqa: BLE001 - carried to the parent, which raises it
            stop_claiming()
            failures.put(_carried(error, traceback.format_exc()))
            raise SystemExit(1) from None

    helpers = [context.Process(target=work, daemon=True) for _ in range(workers - 1)]
    # No signal between the fork and the worker's own handlers: the command's would run in the worker.
    before = signal.pthread_sigmask(signal.SIG_BLOCK, _STOPPING)
    try:
        for helper in helpers:
            helper.start()
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, before)
    told = 0
    try:
        failed = None
        while failed is None:
            more = one_run()
            if not failures.empty():  # read at once: a large error would fill the pipe and hold its worker
                failed = failures.get()
            now = made.value
            for _ in range(now - told):
                yield
            told = now
            alive = [helper.sentinel for helper in helpers if helper.is_alive()]
            if not more and not alive:
                break
            if not more:  # the workers' last runs
                multiprocessing.connection.wait(alive, 0.05)
        if failed is None and not failures.empty():
            failed = failures.get()
        if failed is not None:
            raise failed
        killed = next((-h.exitcode for h in helpers if h.exitcode is not None and h.exitcode < 0), None)
        if killed is not None or made.value != len(animation):
            cause = f"was killed by {signal.Signals(killed).name}" if killed else "ended"
            raise OSError(f"a process making the frames {cause} after {made.value} of {len(animation)} frames "
                          "(out of memory? workers=1 deforms in one process)")
    finally:
        stop_claiming()
        for helper in helpers:
            if helper.is_alive():
                helper.terminate()
            helper.join()


_STOPPING = {signal.SIGINT, signal.SIGTERM}


def _carried(error: BaseException, where: str) -> BaseException:
    """``error`` as it can be sent to another process and raised there, with the worker's traceback
    ``where`` as a note: itself if it pickles and unpickles, else the nearest of its classes that
    does, with its words (an :class:`~faceanim.errors.InputError` stays one, so the command still
    says it in one line)."""
    for kind in type(error).__mro__:
        candidate = error if kind is type(error) else None
        try:
            candidate = candidate if candidate is not None else kind(str(error))
            pickle.loads(pickle.dumps(candidate))
        except Exception:  # noqa: BLE001 - any class that cannot make the trip is passed over
            continue
        candidate.add_note(f"in a process making the frames:\n{where}")
        return candidate
    return RuntimeError(str(error))
