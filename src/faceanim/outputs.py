"""Where a job may write, checked before it does any work.

Every output a job names (``-o`` and the extras: ``--fap``, ``--preview``, ``--overlay``, ``--csv``,
``--obj-sequence``, the demo's folder) must have its kind's suffix, lie in an existing folder that
can be written to, and be none of the job's inputs and no other of its outputs. Paths are compared
resolved, and as the same file where both exist, so a symlink, a hard link or ``./x`` for ``x`` is
caught. The error names the argument: ``--fap in.mp4: is also the input VIDEO; ...``.

Side files: an ``.obj`` with a texture is written with its material and image beside it, named
after it (``me.obj``: ``me.mtl`` and ``me_texture.png``). faceanim marks the side files it writes (the
MTL's first line is ``# written by faceanim``, the PNG carries the text ``Software: faceanim``) and
refuses to replace a file of either name that it did not write, unless ``force`` is given
(``--force`` on the command line).
"""

from __future__ import annotations

import os
import secrets
from collections.abc import Mapping
from pathlib import Path

from .errors import InputError

__all__ = ["check_outputs", "check_output_folder", "check_side_files", "side_files", "is_ours", "SEQUENCE_FOLDER",
           "MARK", "MTL_HEADER"]

SEQUENCE_FOLDER = "folder"  # the kind of an output that is a new (or empty) folder of files, not a file
MARK = "faceanim"  # the PNG text "Software" of a texture faceanim wrote
MTL_HEADER = "# written by faceanim"  # the first line of an MTL faceanim wrote
_SIDE_KINDS = ("material", "texture")


def side_files(path) -> tuple[Path, Path]:
    """The material and the texture written beside the ``.obj`` at ``path``: ``me.obj`` gives
    ``(me.mtl, me_texture.png)``.

    >>> [p.name for p in side_files("out/me.obj")]
    ['me.mtl', 'me_texture.png']
    """
    path = Path(path)
    return path.with_suffix(".mtl"), path.with_name(f"{path.stem}_texture.png")


def is_ours(path) -> bool:
    """True if the MTL or PNG at ``path`` carries faceanim's mark (see the module's docstring)."""
    path = Path(path)
    try:
        with open(path, "rb") as handle:
            head = handle.read(4096)
    except OSError:
        return False
    if path.suffix.lower() == ".mtl":
        return head.startswith(MTL_HEADER.encode())
    return head.startswith(b"\x89PNG") and b"tEXtSoftware\x00" + MARK.encode() in head


def check_side_files(path, *, force: bool = False, argument: str | None = None) -> None:
    """Refuse to write the ``.obj`` at ``path`` where its material or texture (:func:`side_files`) would
    replace a file that faceanim did not write (or a folder); ``force`` replaces such files.
    ``argument`` (``"-o"``) is named in the error."""
    path = Path(path)
    said = f"{argument} {path}" if argument else str(path)
    for what, side in zip(_SIDE_KINDS, side_files(path), strict=True):
        if side.is_dir():
            raise InputError(f"{said}: its {what} {side} is a folder")
        if side.exists() and not force and not is_ours(side):
            raise InputError(f"{said}: its {what} would replace {side}, which faceanim did not write; move it away, "
                             "or pass --force")


def _same(a: Path, b: Path) -> bool:
    if a.resolve() == b.resolve():
        return True
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def _inside(path: Path, folder: Path) -> bool:
    return folder.resolve() in path.resolve().parents


def _choices(suffixes: tuple[str, ...]) -> str:
    return ", ".join(suffixes)


def _check_folder(argument: str, path: Path) -> None:
    """``path``'s folder exists, is a folder and can be written in."""
    parent = path.parent
    if not parent.exists():
        raise InputError(f"{argument} {path}: the folder {parent} does not exist")
    if not parent.is_dir():
        raise InputError(f"{argument} {path}: {parent} is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"{argument} {path}: the folder {parent} is not writable")
    _check_creatable(argument, path, parent)


def _check_creatable(argument: str, path: Path, folder: Path) -> None:
    """A file can be made in ``folder`` (and is removed at once): permissions alone do not say so for
    /proc, /sys, a read-only mount or a full disk, which would fail only when the output is written."""
    probe = probe_path(folder)  # named before it is made: removed whatever interrupts
    ours = True
    try:
        os.close(os.open(probe, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o600))
    except FileExistsError:
        ours = False  # another's probe: files can be made here
    except OSError as exc:
        raise InputError(f"{argument} {path}: no file can be made in {folder} ({exc.strerror or exc})") from None
    finally:
        if ours:
            probe.unlink(missing_ok=True)


def probe_path(folder: Path) -> Path:
    """A new name for a probe file in ``folder``: ``.faceanim-probe-XXXXXXXX``, 8 random hex characters (the
    pattern :func:`faceanim.dataset.remove_leftovers` knows)."""
    return folder / f".faceanim-probe-{secrets.token_hex(4)}"


def check_output_folder(argument: str, folder) -> Path:
    """``folder`` as a Path, if outputs can be written into it: an existing folder that can be
    written in, or one that can be made (its nearest existing parent is a folder that can be written in)."""
    folder = Path(folder)
    existing = folder if folder.exists() else next(p for p in folder.absolute().parents if p.exists())
    if not existing.is_dir():
        where = "exists and is not a folder" if existing is folder else f"{existing} is not a folder"
        raise InputError(f"{argument} {folder}: {where}")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise InputError(f"{argument} {folder}: the folder {existing} is not writable")
    _check_creatable(argument, folder, existing)
    return folder


def check_outputs(outputs: Mapping, *, inputs: Mapping | None = None, force: bool = False) -> None:
    """Refuse, before any work, outputs that cannot or must not be written.

    Parameters
    ----------
    outputs : mapping
        ``{argument: (path or None, kind)}``: the argument's name as the user gave it (``"-o"``,
        ``"--preview"``), its path (None: not asked for, skipped) and its kind, a suffix (``".glb"``),
        a tuple of suffixes, or :data:`SEQUENCE_FOLDER` (a new or empty folder). Suffixes are compared
        without case.
    inputs : mapping, optional
        ``{argument: path}``: the files the job reads (values that are no path, like None, are skipped).
    force : bool
        Replace side files (an ``.obj``'s material and texture) that faceanim did not write.

    Raises
    ------
    InputError
        Naming the argument: a wrong suffix, a missing or read-only folder, a path that is a folder,
        a sequence folder that is not empty, a path that is one of ``inputs`` or another output, an
        output inside the sequence folder, a side file that faceanim did not write.

    >>> check_outputs({"-o": ("x.glb", ".glb"), "--preview": ("x.glb", ".mp4")})
    Traceback (most recent call last):
    ...
    faceanim.errors.InputError: --preview x.glb: this output is written as .mp4
    """
    named = [(argument, Path(path), kind) for argument, (path, kind) in outputs.items() if path is not None]
    sources = [(argument, Path(path)) for argument, path in (inputs or {}).items()
               if isinstance(path, (str, os.PathLike))]  # not None, nor a frame number given as --neutral
    written: list[tuple[str, Path, str | None]] = []  # (argument, path, side file kind or None)
    for argument, path, kind in named:
        if kind == SEQUENCE_FOLDER:
            if path.is_symlink():  # the finished folder is renamed onto the path, which a link would refuse at the end
                raise InputError(f"{argument} {path}: is a symbolic link; the OBJ sequence needs a new or empty folder")
            if path.exists() and (not path.is_dir() or any(path.iterdir())):
                raise InputError(f"{argument} {path}: exists and is not an empty folder; the OBJ sequence needs "
                                 "a new one")
            _check_folder(argument, path)
            written.append((argument, path, None))
            continue
        suffixes = (kind,) if isinstance(kind, str) else tuple(kind)
        if path.suffix.lower() not in suffixes:
            raise InputError(f"{argument} {path}: this output is written as {_choices(suffixes)}")
        _check_folder(argument, path)
        if path.is_dir():
            raise InputError(f"{argument} {path}: is a folder")
        written.append((argument, path, None))
        if path.suffix.lower() == ".obj":
            check_side_files(path, force=force, argument=argument)
            written += [(argument, side, what) for what, side in zip(_SIDE_KINDS, side_files(path), strict=True)]
    paths = {argument: path for argument, path, _ in named}
    for k, (argument, path, what) in enumerate(written):
        said = f"{argument} {paths[argument]}: " + ("" if what is None else f"its {what} {path} ")
        for source, read in sources:
            if _same(path, read):
                raise InputError(f"{said}is also the input {source}; faceanim does not write over its inputs")
        for other, earlier, other_what in written[:k]:
            if _same(path, earlier):
                theirs = other if other_what is None else f"the {other_what} of {other}"
                raise InputError(f"{said}is also where {theirs} goes; give each output its own path")
    for argument, folder, kind in named:
        if kind != SEQUENCE_FOLDER:
            continue
        for other, path, _ in written:
            if other != argument and _inside(path, folder):
                raise InputError(f"{other} {paths[other]}: lies in {argument}'s folder {folder}, which holds only "
                                 "the OBJ sequence")
