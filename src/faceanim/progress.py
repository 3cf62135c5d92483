"""Long work shown as it runs: the command line makes a :class:`Progress` when stderr is a terminal
(as git does) and hands it to the jobs, which show each long step through it; a job given none
stays quiet.

A per-frame loop gets a tqdm bar when the stream is a terminal, else one line saying what runs and
for how many frames (so a log gets one line, not a bar redrawn 200 times); a single long step gets
one line. Everything goes to stderr, so stdout keeps only what a command reports at its end.

>>> import io
>>> shown = io.StringIO()
>>> progress = Progress(shown)
>>> progress.status("placing control points on head.obj")
>>> sum(progress.bar(range(3), total=3, desc="rendering the preview"))
3
>>> print(shown.getvalue(), end="")
faceanim: placing control points on head.obj...
faceanim: rendering the preview (3 frames)...
>>> sum(as_progress(None).bar(range(3), total=3, desc="quiet"))
3
"""

from __future__ import annotations

import copy
import sys
from collections.abc import Iterable

__all__ = ["Progress", "Quiet", "QUIET", "Interrupted", "as_progress"]


class Progress:
    """Shows long steps on ``stream`` (default: the ``sys.stderr`` of the moment).

    Parameters
    ----------
    stream : text file, optional
        Where to write.
    bars : bool, optional
        Draw tqdm bars for per-frame loops; by default only when ``stream`` is a terminal.
    """

    def __init__(self, stream=None, *, bars: bool | None = None, interrupts: list | None = None):
        self._stream = stream
        self._bars = bars
        self._interrupts = interrupts

    @property
    def stream(self):
        return sys.stderr if self._stream is None else self._stream

    def status(self, what: str) -> None:
        """One line, ``faceanim: <what>...``, before a single step that takes a while. While bars are
        drawn it goes above them (a job's placement runs beside the video's tracking bar), not onto
        the end of the bar's line."""
        line = f"faceanim: {what}..."
        if self.shows_bars:
            from tqdm import tqdm

            tqdm.write(line, file=self.stream)
            self.stream.flush()
        else:
            print(line, file=self.stream, flush=True)

    @property
    def shows_bars(self) -> bool:
        """Whether :meth:`bar` draws tqdm bars (asked for, or on a terminal; tqdm installed): a job
        can then draw its own next to them (``faceanim batch``'s frames across its workers)."""
        bars = self._bars
        if bars is None:
            bars = bool(getattr(self.stream, "isatty", lambda: False)())
        if not bars:
            return False
        try:
            import tqdm  # noqa: F401 - tqdm comes with the capture extra; without it, a line will do
        except ImportError:
            return False
        return True

    def bar(self, iterable: Iterable, *, total: int | None = None, desc: str, unit: str = "frame") -> Iterable:
        """``iterable``, shown as it is consumed: a bar counting ``total`` of ``unit``, or one status line."""
        if self.shows_bars:
            from tqdm import tqdm

            return self._watched(tqdm(iterable, total=total, desc=desc, unit=unit, file=self.stream))
        self.status(f"{desc} ({total} {unit}s)" if total else desc)
        return self._watched(iterable)

    def stopped_by(self, stop: list) -> Progress:
        """This progress for work in another thread, which the command line's signals do not reach:
        its loops stop (:class:`Interrupted`) at the next item once ``stop`` holds a signal number, or
        the interrupts this one watches do."""
        clone = copy.copy(self)
        clone._interrupts = stop if self._interrupts is None else _EitherList(self._interrupts, stop)
        return clone

    def _watched(self, iterable: Iterable) -> Iterable:
        """``iterable``, stopped by :class:`Interrupted` at the next item once ``interrupts`` (the list
        the command line adds each SIGINT or SIGTERM to) holds one. The command line raises the
        interrupt where it lands, but a library that catches ``BaseException`` can swallow it (trimesh's
        optional imports do); the frame loops then end the job at the next frame instead of at its end."""
        if self._interrupts is None:
            return iterable
        return self._checked(iterable)

    def _checked(self, iterable: Iterable):
        for item in iterable:
            if self._interrupts:
                raise Interrupted(self._interrupts[0])
            yield item


class _EitherList:
    """Two lists of received signals read as one (true once either holds one; the first's first)."""

    def __init__(self, *lists: list):
        self._lists = lists

    def __bool__(self) -> bool:
        return any(self._lists)

    def __getitem__(self, index: int):
        return next(signals for signals in self._lists if signals)[index]


class Interrupted(KeyboardInterrupt):
    """SIGINT or SIGTERM received by the command line, raised where the work is, so every ``finally`` on
    the way out runs (``signum``: the signal)."""

    def __init__(self, signum: int):
        import signal

        super().__init__(signal.Signals(signum).name)
        self.signum = int(signum)


class Quiet(Progress):
    """Shows nothing: what a job uses when it is given no :class:`Progress` (``interrupts``: see
    :meth:`Progress._watched`)."""

    shows_bars = False

    def status(self, what: str) -> None:
        pass

    def bar(self, iterable: Iterable, *, total: int | None = None, desc: str, unit: str = "frame") -> Iterable:
        return self._watched(iterable)


QUIET = Quiet()


def as_progress(progress) -> Progress:
    """The :class:`Progress` a job was given: itself, or ``True`` for one on stderr; ``None`` or
    ``False``: :data:`QUIET`."""
    if isinstance(progress, Progress):
        return progress
    if progress is None or progress is False:
        return QUIET
    if progress is True:
        return Progress()
    raise TypeError(f"progress must be a Progress, True, False or None, got {type(progress).__name__}")
