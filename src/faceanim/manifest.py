"""What ``faceanim batch`` is asked to process: the videos named by files, folders, globs and
manifests, each with its own options, and the names of its outputs.

A manifest is a ``.csv`` (a header row) or ``.jsonl`` (one JSON object a line) with a ``path``
column; relative paths are read from the manifest's folder. Optional columns, per row: ``name`` (the
outputs' stem, default the video's), ``neutral`` (``FRAME`` or ``START:END``), ``no_filter``
(true/false, 1/0, yes/no) and ``target`` (a mesh for ``animate``). Any other column is refused, so a
misspelt option is not silently ignored.
"""

from __future__ import annotations

import csv
import glob
import json
from dataclasses import dataclass
from pathlib import Path

from .errors import FileFormatError, InputError

__all__ = ["Video", "collect_videos", "read_manifest", "STEPS", "VIDEO_SUFFIXES", "MANIFEST_COLUMNS", "outputs_of"]

VIDEO_SUFFIXES = (".mp4", ".mov", ".avi", ".mkv", ".webm", ".m4v", ".mpg", ".mpeg")
MANIFEST_SUFFIXES = (".csv", ".jsonl")
MANIFEST_COLUMNS = ("path", "name", "neutral", "no_filter", "target")
# step -> the output it writes, named as the README's single commands name theirs (d18.fap, d18_aus.csv,
# d18_take.csv, d18.glb)
STEPS = {"encode": "{name}.fap", "aus": "{name}_aus.csv", "blendshapes": "{name}_take.csv", "animate": "{name}.glb",
         "plot": "{name}_curves.png"}
_TRUE, _FALSE = ("1", "true", "yes", "on"), ("", "0", "false", "no", "off")


@dataclass(frozen=True)
class Video:
    """One video to process: its path, the stem of its outputs, and its own options."""

    path: Path
    name: str
    neutral: str | None = None
    smoothing: bool = True
    target: Path | None = None
    origin: str = ""  # where it was named (an argument, or manifest:line), for errors


def outputs_of(video: Video, steps, folder) -> dict[str, Path]:
    """``{step: output path}`` of ``video`` in ``folder``."""
    return {step: Path(folder) / STEPS[step].format(name=video.name) for step in steps}


def _flag(value, where: str) -> bool:
    if isinstance(value, bool):
        return not value
    text = str(value).strip().lower()
    if text in _TRUE:
        return False
    if text in _FALSE:
        return True
    raise InputError(f"{where}: no_filter must be true or false, got {value!r}")


def _row_video(row: dict, base: Path, where: str) -> Video:
    unknown = [k for k in row if k not in MANIFEST_COLUMNS]
    if unknown:
        raise InputError(f"{where}: unknown option {unknown[0]!r}; a manifest's columns are "
                         f"{', '.join(MANIFEST_COLUMNS)}")
    path = row.get("path")
    if not isinstance(path, str) or not path.strip():
        raise InputError(f"{where}: no path")
    path = base / path.strip()
    name = str(row.get("name") or "").strip() or path.stem
    if "/" in name or name.startswith("."):
        raise InputError(f"{where}: name {name!r} must be a plain file stem")
    neutral = row.get("neutral")
    neutral = None if neutral in (None, "") else str(neutral).strip()
    target = row.get("target")
    target = None if target in (None, "") else base / str(target).strip()
    return Video(path, name, neutral, _flag(row.get("no_filter", ""), where), target, where)


def read_manifest(path) -> list[Video]:
    """The videos of a ``.csv`` or ``.jsonl`` manifest (see the module's docstring).

    Raises
    ------
    InputError
        No ``path`` column, an unknown column, a row without a path, a bad value (named by line).
    FileFormatError
        Not UTF-8, or a JSONL line that is not a JSON object.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise FileFormatError(path, "is not a UTF-8 text manifest") from None
    base = path.parent
    videos = []
    if path.suffix.lower() == ".csv":
        rows = list(csv.reader(text.splitlines()))
        if not rows:
            raise InputError(f"{path}: is empty; a manifest needs a header with a path column")
        header = [h.strip() for h in rows[0]]
        if "path" not in header:
            raise InputError(f"{path}: has no path column (its header is {', '.join(header) or 'empty'})")
        for number, row in enumerate(rows[1:], start=2):
            if not any(cell.strip() for cell in row):
                continue
            if len(row) != len(header):
                raise FileFormatError(path, f"has {len(row)} cells where the header names {len(header)}", number)
            videos.append(_row_video(dict(zip(header, row, strict=True)), base, f"{path}:{number}"))
        return videos
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        try:
            row = json.loads(line)
        except ValueError as exc:
            raise FileFormatError(path, f"is not JSON ({exc})", number) from None
        if not isinstance(row, dict):
            raise FileFormatError(path, "each line must be a JSON object with a path", number)
        if "path" not in row:
            raise InputError(f"{path}:{number}: has no path (each line needs one)")
        videos.append(_row_video(row, base, f"{path}:{number}"))
    return videos


def collect_videos(inputs) -> list[Video]:
    """The videos named by ``inputs``: files (any video FFmpeg reads), folders (their videos, by
    :data:`VIDEO_SUFFIXES`, sorted), globs (``data/**/*.mp4``, sorted) and manifests (``.csv``,
    ``.jsonl``). A video named twice is kept once.

    Raises
    ------
    InputError
        A path that does not exist, a glob or a folder that matches no video, a bad manifest, or two
        videos whose outputs would share a name.
    """
    videos: list[Video] = []
    for given in inputs:
        given = str(given)
        path = Path(given)
        if path.is_file() and path.suffix.lower() in MANIFEST_SUFFIXES:
            videos += read_manifest(path)
        elif path.is_file():
            videos.append(Video(path, path.stem, origin=given))
        elif path.is_dir():
            found = sorted(p for p in path.iterdir() if p.is_file() and p.suffix.lower() in VIDEO_SUFFIXES)
            if not found:
                raise InputError(f"{given}: holds no video ({', '.join(VIDEO_SUFFIXES)})")
            videos += [Video(p, p.stem, origin=given) for p in found]
        elif glob.has_magic(given):
            found = sorted(Path(p) for p in glob.glob(given, recursive=True) if Path(p).is_file())
            if not found:
                raise InputError(f"{given}: matches no file")
            videos += [Video(p, p.stem, origin=given) for p in found]
        else:
            raise InputError(f"{given}: no such file or folder")
    kept, seen, names = [], set(), {}
    for video in videos:
        key = (video.path.resolve(), video.name)
        if key in seen:
            continue
        seen.add(key)
        if video.name in names:
            raise InputError(f"{video.origin}: {video.path} and {names[video.name]} would both write outputs named "
                             f"{video.name!r}; give one a name in a manifest")
        names[video.name] = video.path
        kept.append(video)
    if not kept:
        raise InputError("no video to process")
    return kept
