"""Errors that mean "the input cannot be used", as opposed to bugs.

The command line prints these as one line and exits non-zero; library callers can catch
:class:`InputError` to tell a bad file or argument from a fault in faceanim itself.
"""

from __future__ import annotations

__all__ = ["InputError", "FileFormatError"]


class InputError(ValueError):
    """An argument or file that faceanim cannot use; the message says which and why."""


class FileFormatError(InputError):
    """A file that does not follow its format; the message names the file and, where known, the line."""

    def __init__(self, path, message: str, line: int | None = None):
        self.path = str(path)
        self.line = line
        where = f"{self.path}:{line}" if line is not None else self.path
        super().__init__(f"{where}: {message}")
