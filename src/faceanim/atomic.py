"""Write a file (or a folder) completely or not at all, and the outputs of one job all together or none.

Each output is written to a hidden temporary beside it (``.NAME.XXXXXXXX.SUFFIX``) and moved onto
its path when it is complete. Inside an :func:`output_group` (the command line runs every job in
one) the move waits for the group to end: a job interrupted or failing late leaves none of its
outputs, not some of them, and the files that were at those paths before stay as they were.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
from contextvars import ContextVar
from pathlib import Path

__all__ = ["atomic_output", "atomic_folder", "output_group"]

# The open group's list of (temporary, final path), or None outside any group.
_GROUP: ContextVar[list[tuple[Path, Path]] | None] = ContextVar("faceanim_output_group", default=None)


@contextlib.contextmanager
def output_group():
    """Outputs finished inside the block (by :func:`atomic_output` or :func:`atomic_folder`) appear
    together when it ends without error; on an error or an interrupt (``KeyboardInterrupt``) none of
    them appears and their temporary files are removed.

    Groups nest; an inner group moves its own outputs into place when it ends (a step whose output a
    later step reads, as the demo's performance video is read by its capture step).

    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> try:
    ...     with output_group():
    ...         with atomic_output(folder / "a.txt") as tmp:
    ...             _ = tmp.write_text("finished")
    ...         raise KeyboardInterrupt  # interrupted before the second output
    ... except KeyboardInterrupt:
    ...     pass
    >>> sorted(p.name for p in folder.iterdir())  # neither a.txt nor its temporary file
    []
    """
    pending: list[tuple[Path, Path]] = []
    token = _GROUP.set(pending)
    try:
        yield
        _GROUP.reset(token)
        token = None
        while pending:
            tmp, path = pending[0]
            _move_into_place(tmp, path)
            pending.pop(0)
    finally:
        if token is not None:
            _GROUP.reset(token)
        for tmp, _ in pending:
            _remove(tmp)


def _hand_over(tmp: Path, path: Path) -> None:
    """Move ``tmp`` onto ``path`` now, or when the open group ends."""
    group = _GROUP.get()
    if group is None:
        _move_into_place(tmp, path)
    else:
        group.append((tmp, path))


def _move_into_place(tmp: Path, path: Path) -> None:
    if tmp.is_dir() and path.is_dir():
        path.rmdir()  # an empty folder waiting for it (a non-empty one is refused by rmdir)
    os.replace(tmp, path)


def _remove(tmp: Path) -> None:
    if tmp.is_dir():
        shutil.rmtree(tmp, ignore_errors=True)
    else:
        tmp.unlink(missing_ok=True)


def _make_temporary(made: list[Path], path: Path, suffix: str, *, folder: bool) -> Path:
    """A new hidden temporary beside ``path`` (``.NAME.XXXXXXXX.SUFFIX``; a folder if ``folder``), with the
    usual permissions (those the umask leaves, as for any file the user makes).

    Its name goes into ``made`` before it is created: a signal arriving the moment it appears (``faceanim
    track`` interrupted as it starts writing its track left its hidden temporary file behind when the name
    was only known once the file was made) still finds it in the caller's clean-up; a name whose file was
    never made costs that clean-up nothing."""
    for _ in range(_NAME_TRIES):
        tmp = path.parent / f".{path.name}.{secrets.token_hex(4)}{suffix}"
        made.append(tmp)
        try:
            _create(tmp, folder=folder)
            return tmp
        except FileExistsError:
            made.pop()  # someone else's: not ours to remove
    raise FileExistsError(f"{path.parent}: no free name for a temporary file beside {path.name}")


def _create(tmp: Path, *, folder: bool) -> None:
    if folder:
        os.mkdir(tmp, 0o777)
    else:
        os.close(os.open(tmp, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o666))


_NAME_TRIES = 100


@contextlib.contextmanager
def atomic_output(path, suffix: str | None = None):
    """Yield a temporary path beside ``path``; move it onto ``path`` only if the block succeeds.

    A failure inside the block (a bad argument found late, an interrupted write) leaves any earlier
    file at ``path`` untouched and no partial file behind. Inside an :func:`output_group` the move
    waits for the group's end.

    >>> import tempfile, pathlib
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "x.txt"
    >>> with atomic_output(out) as tmp:
    ...     _ = tmp.write_text("done")
    >>> out.read_text()
    'done'
    """
    path = Path(path)
    if not path.parent.exists():
        raise FileNotFoundError(f"{path}: the folder {path.parent} does not exist")
    made: list[Path] = []
    handed = False
    try:
        tmp = _make_temporary(made, path, suffix or path.suffix, folder=False)
        yield tmp
        _hand_over(tmp, path)
        handed = True
    finally:
        if not handed:
            for tmp in made:
                _remove(tmp)


@contextlib.contextmanager
def atomic_folder(path):
    """Yield a temporary folder beside ``path``; it becomes ``path`` (which must be absent or an empty
    folder) only if the block succeeds. Inside an :func:`output_group` the move waits for the group's end;
    the files written into the temporary folder are the folder's business and are not held back.

    >>> import tempfile, pathlib
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "frames"
    >>> with atomic_folder(out) as work:
    ...     _ = (work / "0.txt").write_text("frame")
    >>> [p.name for p in out.iterdir()]
    ['0.txt']
    """
    path = Path(path)
    if not path.parent.exists():
        raise FileNotFoundError(f"{path}: the folder {path.parent} does not exist")
    made: list[Path] = []
    handed = False
    try:
        work = _make_temporary(made, path, "", folder=True)
        inside = _GROUP.set(None)  # files inside go straight into the temporary folder
        try:
            yield work
        finally:
            _GROUP.reset(inside)
        _hand_over(work, path)
        handed = True
    finally:
        if not handed:
            for work in made:
                _remove(work)
