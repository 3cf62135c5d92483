"""JSON input files (control points, correspondence pairs, vertex masks, parts): parsed, or refused
with an error that names the file and, where known, the line.

JSON text is UTF-8 (RFC 8259). Python's parser also fails in ways that are not
:class:`json.JSONDecodeError` (a number of more than 4,300 digits, nesting deeper than the
interpreter's recursion limit); these are the file's fault too and are reported the same way.

>>> parse_json(b'[0, 1,\\n 2', "ids.json")
Traceback (most recent call last):
...
faceanim.errors.FileFormatError: ids.json:2: is not valid JSON (Expecting ',' delimiter)
>>> parse_json(b'{"8.3": \\xff}', "points.json")
Traceback (most recent call last):
...
faceanim.errors.FileFormatError: points.json:1: is not UTF-8 text (byte 0xff)
"""

from __future__ import annotations

import json
from pathlib import Path

from .errors import FileFormatError, InputError

__all__ = ["read_json", "parse_json"]


def read_json(path):
    """The JSON value in the file at ``path``.

    Raises
    ------
    InputError
        The file cannot be read (missing, a folder, no permission).
    FileFormatError
        The file is not UTF-8 or not JSON; the message names the file and, where known, the line.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    return parse_json(data, path)


def parse_json(data: bytes, path):
    """The JSON value in ``data``, read from the file ``path`` (named in errors, as in :func:`read_json`)."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        raise FileFormatError(path, f"is not UTF-8 text (byte {data[exc.start]:#04x})", line) from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise FileFormatError(path, f"is not valid JSON ({exc.msg})", exc.lineno) from None
    except ValueError as exc:  # a number too long for int(): "Exceeds the limit (4300 digits) ..."
        raise FileFormatError(path, f"is not valid JSON ({str(exc).split(';')[0]})") from None
    except RecursionError:
        raise FileFormatError(path, "is not valid JSON (nested too deeply)") from None
