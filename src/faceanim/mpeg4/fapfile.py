"""The ASCII ``.fap`` file format (ISO/IEC 14496-2 FBA, Annex A of the visage overview), read and
written as ``shared/mpeg4/fap_file_format.md`` recommends: tolerant reading (comment lines anywhere,
integer or decimal values), strict writing (version 2.1, one-token name, integer fps, 68-digit masks,
integer values, 4 fields for FAP 1 and 6 for FAP 2). Every reading error names the file and line.

Numbers that are counts or codes must be whole, though they may be written as decimals (``3.0``):
frame numbers (0 to 2**31 - 1, never decreasing) and the fields of FAPs 1 and 2 (within 32 bits); a
fractional one (``2.5``) is refused, not truncated. A file must hold at least one frame.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..atomic import atomic_output
from ..errors import FileFormatError, InputError
from .fapstream import FapStream
from .tables import FAP_COUNT

__all__ = ["read_fap", "write_fap", "fap_header_line", "fap_frame_lines"]


def _lines(path: Path):
    """(line number, tokens) of the lines that are not blank or comments."""
    try:
        text = path.read_text(encoding="latin-1")
    except OSError as exc:
        raise InputError(f"{path}: cannot be read ({exc.strerror})") from None
    for number, line in enumerate(text.splitlines(), 1):
        stripped = line.strip()
        if stripped and not stripped.startswith("#"):
            yield number, stripped.split()


def _number(token: str, path, line: int, what: str) -> float:
    try:
        value = float(token)
    except ValueError:
        raise FileFormatError(path, f"{what} {token!r} is not a number", line) from None
    if not np.isfinite(value):
        raise FileFormatError(path, f"{what} {token!r} is not finite", line)
    return value


# Frame rates a .fap may say: from one frame in 1,000 s (a slide show) to 1,000 a second; outside,
# the times of the frames (and a glTF's keyframes) lose their meaning (1e300 fps gives times of 0).
_FPS_RANGE = (1e-3, 1000.0)
_WHOLE = 2**31  # frame numbers and the fields of FAPs 1 and 2 lie below this in magnitude (32 bits)


def _whole(value: float, token: str, path, line: int, what: str, *, low: int) -> int:
    """``value`` (parsed from ``token``) as an int, if it is whole and in ``[low, 2**31)``."""
    if value != int(value) or not low <= value < _WHOLE:
        raise FileFormatError(path, f"{what} {token} is not a whole number from {low} to {_WHOLE - 1}", line)
    return int(value)


def read_fap(path) -> FapStream:
    """Read a ``.fap`` file.

    Raises
    ------
    InputError
        The file does not exist or cannot be read.
    FileFormatError
        A bad header, a mask that is not 68 zeros and ones, a missing or short value line, a
        non-numeric or non-finite token, a frame number or FAP 1/2 field that is not whole (or out of
        32 bits), a value out of 32 bits, decreasing frame numbers, no frames, or a frame count that disagrees with the
        header; the message names the file and line. Values outside their MPEG-4 range are kept (see
        :meth:`FapStream.out_of_range`), never clipped.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    lines = _lines(path)
    header = next(lines, None)
    if header is None:
        raise FileFormatError(path, "is empty (no header line)")
    header_line, tokens = header
    if len(tokens) < 4:
        raise FileFormatError(path, "header must be '<version> <name> <fps> <frame count>'", header_line)
    _number(tokens[0], path, header_line, "version")
    name = tokens[1]
    fps = _number(tokens[-2], path, header_line, "frame rate")
    count = _number(tokens[-1], path, header_line, "frame count")
    if fps <= 0 or count < 0 or count != int(count):
        raise FileFormatError(path, f"header frame rate {tokens[-2]} and frame count {tokens[-1]} must be "
                                    "positive and whole", header_line)
    if not _FPS_RANGE[0] <= fps <= _FPS_RANGE[1]:
        raise FileFormatError(path, f"header frame rate {tokens[-2]} must lie from {_FPS_RANGE[0]:g} to "
                                    f"{_FPS_RANGE[1]:g} frames a second", header_line)

    values, masks, frames, visemes, expressions = [], [], [], [], []
    for mask_line, mask_tokens in lines:
        if len(mask_tokens) != FAP_COUNT or any(t not in ("0", "1") for t in mask_tokens):
            raise FileFormatError(path, f"FAP mask must be {FAP_COUNT} zeros and ones, got {len(mask_tokens)} "
                                        f"tokens", mask_line)
        mask = np.array([t == "1" for t in mask_tokens])
        value_entry = next(lines, None)
        if value_entry is None:
            raise FileFormatError(path, "FAP mask has no value line after it", mask_line)
        value_line, value_tokens = value_entry
        expected = 1 + 4 * mask[0] + 6 * mask[1] + int(mask[2:].sum())
        if len(value_tokens) != expected:
            raise FileFormatError(path, f"value line must hold the frame number and {expected - 1} values for "
                                        f"the mask on line {mask_line}, got {len(value_tokens)} tokens", value_line)
        numbers = [_number(t, path, value_line, "value") for t in value_tokens]
        frame = _whole(numbers.pop(0), value_tokens[0], path, value_line, "frame number", low=0)
        if frames and frame < frames[-1]:
            raise FileFormatError(path, f"frame number {frame} comes after frame {frames[-1]}", value_line)
        row = np.zeros(FAP_COUNT)
        viseme = np.zeros(4, dtype=np.int64)
        expression = np.zeros(6, dtype=np.int64)
        at = 1  # the token of numbers[0]
        for fap, fields, width in ((1, viseme, 4), (2, expression, 6)):
            if mask[fap - 1]:
                fields[:] = [_whole(v, t, path, value_line, f"FAP {fap} field", low=-_WHOLE)
                             for v, t in zip(numbers[:width], value_tokens[at:at + width], strict=True)]
                numbers, at = numbers[width:], at + width
        big = next((t for v, t in zip(numbers, value_tokens[at:], strict=True) if not -_WHOLE < v < _WHOLE), None)
        if big is not None:  # FAP values are counts of FAPU; beyond 32 bits, they overflow what they move
            raise FileFormatError(path, f"value {big} is beyond 32 bits (FAP values lie within +-{_WHOLE - 1})",
                                  value_line)
        row[2:][mask[2:]] = numbers
        frames.append(frame)
        values.append(row)
        masks.append(mask)
        visemes.append(viseme)
        expressions.append(expression)
    if len(frames) != count:
        raise FileFormatError(path, f"header says {int(count)} frames but the file holds {len(frames)}", header_line)
    if not frames:
        raise FileFormatError(path, "holds no frames", header_line)
    masks_array = np.array(masks)
    try:
        return FapStream(
            values=np.array(values), mask=masks_array, fps=fps, frame_numbers=np.array(frames, dtype=np.int64),
            visemes=np.array(visemes) if masks_array[:, 0].any() else None,
            expressions=np.array(expressions) if masks_array[:, 1].any() else None, name=name)
    except ValueError as exc:  # FapStream's own checks, should the reader's above miss one
        raise FileFormatError(path, str(exc)) from None


def write_fap(path, stream: FapStream) -> None:
    """Write ``stream`` as a version 2.1 ``.fap`` file, complete or not at all.

    Values are rounded to integers (the format's unit is one FAPU count) and fps to a whole number;
    a rate that rounds to none (below 0.5 fps) or beyond what :func:`read_fap` reads is refused before
    anything is written, with an :class:`~faceanim.errors.InputError` naming ``path``: the rate is the
    video's or the user's (``--fps``), not a fault of the caller.
    """
    lines = [fap_header_line(path, stream.name, stream.fps, len(stream)), *fap_frame_lines(stream)]
    with atomic_output(path) as tmp:
        tmp.write_text("\n".join(lines) + "\n")


def fap_header_line(path, name: str, fps: float, frames: int) -> str:
    """The header line of a ``.fap`` of ``frames`` frames (see :func:`write_fap`; ``path`` names the
    file in the refusal of a frame rate it cannot hold). A writer that gets its frames in pieces writes
    it, then :func:`fap_frame_lines` of each piece."""
    if not 1 <= round(fps) <= _FPS_RANGE[1]:
        raise InputError(f"{path}: a .fap holds a whole frame rate from 1 to {_FPS_RANGE[1]:g}; {fps:g} fps "
                         f"rounds to {round(fps)}")
    return f"2.1 {name} {round(fps)} {frames}"


def fap_frame_lines(stream: FapStream) -> list[str]:
    """The mask and value lines of every frame of ``stream`` (two a frame), as :func:`write_fap` writes them."""
    lines = []
    rounded = np.rint(stream.values).astype(np.int64)
    for t in range(len(stream)):
        mask = stream.mask[t]
        fields = [str(int(stream.frame_numbers[t]))]
        if mask[0]:
            fields += [str(int(v)) for v in stream.visemes[t]]
        if mask[1]:
            fields += [str(int(v)) for v in stream.expressions[t]]
        fields += [str(v) for v in rounded[t, 2:][mask[2:]]]
        lines.append(" ".join("1" if m else "0" for m in mask))
        lines.append(" ".join(fields))
    return lines
