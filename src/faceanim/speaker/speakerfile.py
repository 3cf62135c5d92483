"""The speaker model file (``.npz``, versioned): written complete or not at all, read with one-line errors.

Arrays (no pickled objects): ``version`` (2), ``names (P,)``, ``neutral (P, 3)``, ``rest (P, 3)``,
``basis (K, P, 3)``, ``parameter_names (K,)``, ``static_names (S,)``, ``static_points (S, 3)``,
``triangles (F, 3)`` (into the mobile then the static points), ``fapu (5,)`` (IRISD0, ES0, ENS0,
MNS0, MW0), ``ranges (K, 2)``, ``fps``, ``method``, ``ridge``, ``persistence (K,)`` (the temporal
prior's; new in version 2). Lengths in centimetres, head frame, MPEG-4 axes (+X the face's
left, +Y up, +Z out of the face).

Version 1 files (without ``persistence``) are still read: the model interprets streams frame by frame as
before, and asking it for the temporal prior is refused in one line. Other versions are refused.
"""

from __future__ import annotations

import contextlib
import zipfile
from pathlib import Path

import numpy as np

from ..atomic import atomic_output
from ..errors import FileFormatError, InputError
from ..mpeg4 import Fapu
from .model import SpeakerModel

__all__ = ["read_speaker", "write_speaker", "refusals_named", "SPEAKER_VERSION"]

SPEAKER_VERSION = 2
_READABLE = (1, 2)
_FAPU = ("irisd0", "es0", "ens0", "mns0", "mw0")
_ARRAYS = ("names", "neutral", "rest", "basis", "parameter_names", "static_names", "static_points", "triangles",
           "fapu", "ranges", "fps", "method", "ridge")


def write_speaker(path, model: SpeakerModel) -> Path:
    """Write ``model`` to ``path`` (``.npz``), complete or not at all."""
    path = Path(path)
    arrays = {
        "version": np.array(SPEAKER_VERSION), "names": np.array(model.names, dtype=str),
        "neutral": model.neutral, "rest": model.rest, "basis": model.basis,
        "parameter_names": np.array(model.parameter_names, dtype=str),
        "static_names": np.array(model.static_names, dtype=str).reshape(-1), "static_points": model.static_points,
        "triangles": model.triangles, "fapu": np.array([getattr(model.fapu, k) for k in _FAPU]),
        "ranges": model.ranges, "fps": np.array(model.fps), "method": np.array(model.method),
        "ridge": np.array(model.ridge)}
    if model.persistence is not None:
        arrays["persistence"] = model.persistence
    else:  # a model without a temporal prior is what version 1 held
        arrays["version"] = np.array(1)
    with atomic_output(path) as tmp, open(tmp, "wb") as handle:
        np.savez_compressed(handle, **arrays)
    return path


def _strings(value, key: str, path) -> tuple[str, ...]:
    if value.dtype.kind != "U" or value.ndim != 1:
        raise FileFormatError(path, f"{key} must be a list of strings, got {value.dtype} {value.shape}")
    return tuple(str(v) for v in value)


def _scalar(value, key: str, path, kind: str):
    if value.ndim != 0 or value.dtype.kind not in kind:
        raise FileFormatError(path, f"{key} must be a single value, got {value.dtype} {value.shape}")
    return value.item()


def read_speaker(path) -> SpeakerModel:
    """Read a speaker model written by :func:`write_speaker` (``faceanim speaker build``).

    Raises
    ------
    InputError
        The file is missing or cannot be read.
    FileFormatError
        Not an ``.npz`` archive, another version, a missing entry, or entries of the wrong shape or
        kind (the message names the entry).
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    if not zipfile.is_zipfile(path):
        raise FileFormatError(path, "is not a speaker model (not an .npz archive)")
    try:
        with np.load(path, allow_pickle=False) as archive:
            data = {key: archive[key] for key in archive.files}
    except (zipfile.BadZipFile, ValueError, EOFError) as exc:
        raise FileFormatError(path, f"is not a speaker model (an .npz archive): {exc}") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    if "version" not in data:
        raise FileFormatError(path, "is not a speaker model (no version entry)")
    try:
        version = int(_scalar(data["version"], "version", path, "iu"))
    except (TypeError, ValueError):
        raise FileFormatError(path, "is not a speaker model (its version is no whole number)") from None
    if version not in _READABLE:
        raise FileFormatError(path, f"is a speaker model of version {version}; this faceanim reads versions "
                                    f"{_READABLE[0]} to {SPEAKER_VERSION} (build it again with faceanim speaker "
                                    "build)")
    missing = [key for key in _ARRAYS + (("persistence",) if version >= 2 else ()) if key not in data]
    if missing:
        raise FileFormatError(path, f"lacks the speaker model's {', '.join(missing)}")
    try:
        fapu = data["fapu"]
        if fapu.shape != (5,) or fapu.dtype.kind != "f":
            raise FileFormatError(path, f"fapu must hold 5 distances, got {fapu.dtype} {fapu.shape}")
        for key in ("neutral", "rest", "basis", "static_points", "ranges", "triangles") + (
                ("persistence",) if version >= 2 else ()):
            if data[key].dtype.kind not in ("iu" if key == "triangles" else "f"):
                raise FileFormatError(path, f"{key} must be numbers, got {data[key].dtype}")
        return SpeakerModel(
            _strings(data["names"], "names", path), data["neutral"], data["rest"], data["basis"],
            _strings(data["parameter_names"], "parameter_names", path),
            _strings(data["static_names"], "static_names", path), data["static_points"], data["triangles"],
            Fapu(*(float(v) for v in fapu)), data["ranges"], float(_scalar(data["fps"], "fps", path, "fiu")),
            method=str(_scalar(data["method"], "method", path, "U")),
            ridge=float(_scalar(data["ridge"], "ridge", path, "fiu")), persistence=data.get("persistence"))
    except (ValueError, TypeError) as exc:
        if isinstance(exc, FileFormatError):
            raise
        raise FileFormatError(path, f"is no valid speaker model: {exc}") from None


@contextlib.contextmanager
def refusals_named(stream_file, speaker_file):
    """The model's refusal of a stream inside the block (too few of its FAPs on a frame) named by the
    files the user gave, ``STREAM with --speaker MODEL: ...``, not by the stream's own name inside;
    errors that already name ``stream_file`` (a corrupt file) pass as they are."""
    try:
        yield
    except InputError as error:
        if speaker_file is None or str(error).startswith(str(stream_file)):
            raise
        raise InputError(f"{stream_file} with --speaker {speaker_file}: {error}") from None
