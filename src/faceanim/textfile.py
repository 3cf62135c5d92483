"""Text input files (Live Link takes, AU curves): read whole, or refused with one line naming the file.

>>> import tempfile, pathlib
>>> bad = pathlib.Path(tempfile.mkdtemp()) / "take.csv"
>>> _ = bad.write_bytes(b"Timecode\\n\\xff")
>>> read_text(bad)
Traceback (most recent call last):
...
faceanim.errors.FileFormatError: ...take.csv: is not UTF-8 text (invalid start byte at byte 9)
"""

from __future__ import annotations

from pathlib import Path

from .errors import FileFormatError, InputError

__all__ = ["read_text"]


def read_text(path) -> str:
    """The UTF-8 text of ``path`` (a byte-order mark, as spreadsheet programs write one, dropped).

    Raises
    ------
    InputError
        The file is missing or cannot be read.
    FileFormatError
        It is not UTF-8 text (the byte is named).
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    try:
        return path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise FileFormatError(path, f"is not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot be read ({exc.strerror or exc})") from None
