"""The FAP stream coder: MPEG-4's low-delay FAP coding scheme, in faceanim's own container (``.fba``).

The coding follows ISO/IEC 14496-2's low-delay (predictive) FAP coding:

* **Quantiser.** FAP ``j`` is quantised with step ``QP[j] * quant``, QP the ``quant_step_QP`` column of
  Table C-1 (``shared/mpeg4/faps.csv``; ``fapu.md`` section 5) and ``quant`` the scale (the standard's
  ``fap_quant``; here any positive number, so 0.5 is finer than the standard allows).
* **Intra, then predicted.** The first frame that carries a FAP sends its quantised value; every later
  frame that carries it sends the quantised difference from the decoder's own reconstruction of its
  last sent value. Both sides predict from the same reconstruction, so quantisation errors do not
  accumulate: every decoded value lies within half a step of the original, at any frame (the
  reconstruction is ``step * round(value / step)``, which is what the closed loop comes to).
* **Adaptive arithmetic coding** of the symbols with ``constriction``'s range coder. Each FAP has its
  own adaptive model: a discrete Laplace law (``QuantizedLaplace``, mean 0) whose scale follows the
  mean absolute size of that FAP's recent differences (an integer exponential average with weight
  1/4, floor 0.2 step, start 1 step), updated identically by encoder and decoder after each frame.
  Intra values use a fixed wide law (scale 64 steps). Measured against the alternative the brief
  suggested, an adaptive frequency table per FAP (31 difference symbols and an escape, Krichevsky-
  Trofimov-like counts), on four of Xface's ``.fap`` files (tuning set: anger, beg, disgust, fear):
  132 against 154 bits per frame at ``quant`` 1 and 84 against 102 at ``quant`` 4. One parameter per
  FAP learns in a few frames where a table of 32 counts needs hundreds, and these clips are ~100
  frames long. Integer state keeps encoder and decoder bit-identical.

FAPs 1 and 2 (visemes and expressions: selections, not curves) are not coded: ``faps=None`` leaves
them out, and asking for them is refused.

The container (``.fba``, faceanim's own, **not** the MPEG-4 FBA bit syntax), little-endian::

    magic      4 bytes  b"faFB"
    version    u8       1
    flags      u8       bit 0: frame numbers are first, first + 1, ...
    fps        f64
    quant      f64
    frames     u32      T, from 1 to 2**22
    faps       9 bytes  the 68 sent-FAP flags, FAP 1 first, MSB first (numpy.packbits); FAPs 1-2 never set
    name       u8 length, then that many bytes of UTF-8 (one token)
    frame numbers       flag set: u32 first frame; else T x u32 (never decreasing, < 2**31)
    masks      varint P, then P patterns of ceil(J/8) bytes (J sent FAPs, packbits); varint R, then R
               runs (varint length >= 1, varint pattern index); the lengths sum to T
    payload    u32 N, then N u32 words of the range coder
    check      u32 CRC-32 of every byte before it

A FAP absent from a frame is not sent; the next frame that carries it is predicted from its last sent
value. Quantised values must stay below 2**15 steps in magnitude (every legal FAP does at ``quant``
0.12 and above); :func:`encode_faps` refuses finer settings for larger values.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Sequence

import numpy as np

from ..atomic import atomic_output
from ..errors import FileFormatError, InputError
from .fapstream import FapStream, curve_columns
from .tables import FAP_COUNT, fap_table

__all__ = ["encode_faps", "decode_faps", "read_fba", "write_fba", "fba_quant", "fap_psnr", "FORMAT_VERSION"]

MAGIC = b"faFB"
FORMAT_VERSION = 1
_HEAD = struct.Struct("<4sBBddI9s")  # magic, version, flags, fps, quant, frames, sent FAPs
_CONSECUTIVE = 1
_LIMIT = 2**15  # |quantised value| < _LIMIT
_SHIFT = 2  # weight 1/4 of the scale's exponential average
_ONE = 256  # the scale state counts 1/256 of a step
_START = 1 * _ONE
_FLOOR = 0.2
_INTRA_SCALE = 64.0
_FPS_MAX = 1000.0
_MAX_FRAMES = 2**22  # 39 hours at 30 fps; a header saying more is refused before anything is allocated


def _law():
    import constriction

    return constriction.stream.model.QuantizedLaplace(-2 * _LIMIT, 2 * _LIMIT)


def _steps(columns: np.ndarray, quant: float) -> np.ndarray:
    return fap_table().quant_step[columns] * quant


def _columns(stream: FapStream, faps: Sequence[int] | None) -> np.ndarray:
    if faps is None:
        return curve_columns(stream)
    numbers = sorted({int(f) for f in faps})
    bad = [n for n in numbers if not 3 <= n <= FAP_COUNT]
    if bad:
        raise ValueError(f"faps must be FAP numbers from 3 to {FAP_COUNT} (1 and 2, visemes and expressions, are "
                         f"not coded), got {bad[0]}")
    return np.array(numbers, dtype=np.int64) - 1


def _scales(state: np.ndarray) -> np.ndarray:
    return np.maximum(state / _ONE, _FLOOR)


def _update(state: np.ndarray, predicted: np.ndarray, residual: np.ndarray) -> None:
    """The scale state of the FAPs ``predicted`` (bool) after their differences ``residual``."""
    size = np.abs(residual[predicted]) * _ONE
    state[predicted] += (size - state[predicted]) >> _SHIFT


def encode_faps(stream: FapStream, *, quant: float = 1.0, faps: Sequence[int] | None = None) -> bytes:
    """Code ``stream`` into the ``.fba`` bytes described in the module's docstring.

    Parameters
    ----------
    stream : FapStream
        Values in FAPU (angles in 1e-5 rad), with the per-frame mask; at least one frame.
    quant : float
        Scale of the quantiser steps ``QP x quant`` (``QP`` from Table C-1); positive.
    faps : sequence of int, optional
        1-based numbers (3-68) of the FAPs to send; default: every low-level FAP the mask carries.
        A FAP is sent on the frames whose mask carries it.

    Returns
    -------
    bytes

    >>> import numpy as np
    >>> values = np.zeros((3, 68)); values[:, 2] = [0, 411, 829]    # open_jaw, QP 4
    >>> mask = np.zeros((3, 68), bool); mask[:, 2] = True
    >>> back = decode_faps(encode_faps(FapStream(values, mask, fps=25.0)))
    >>> back.values[:, 2].tolist()   # within half a step (2) of the original
    [0.0, 412.0, 828.0]
    """
    import constriction

    if not isinstance(stream, FapStream):
        raise TypeError(f"stream must be a FapStream, got {type(stream).__name__}")
    quant = float(quant)
    if not np.isfinite(quant) or quant <= 0:
        raise ValueError(f"quant must be a positive number, got {quant}")
    T = len(stream)
    if not 1 <= T <= _MAX_FRAMES:
        raise ValueError(f"stream must have from 1 to {_MAX_FRAMES} frames, got {T}")
    if not 0 < stream.fps <= _FPS_MAX:
        raise ValueError(f"stream.fps must lie in (0, {_FPS_MAX:g}], got {stream.fps:g}")
    columns = _columns(stream, faps)
    if not len(columns):
        raise ValueError("stream carries none of the FAPs to send (3-68)")
    steps = _steps(columns, quant)
    mask = stream.mask[:, columns]
    q = np.rint(stream.values[:, columns] / steps).astype(np.int64)
    q[~mask] = 0
    over = np.abs(q) >= _LIMIT
    if over.any():
        t, j = np.argwhere(over)[0]
        raise ValueError(f"FAP {columns[j] + 1} at frame {t} is {stream.values[t, columns[j]]:g}, "
                         f"{abs(q[t, j])} quantiser steps at quant {quant:g}; the coder holds fewer than {_LIMIT}: "
                         "use a coarser quant")

    J = len(columns)
    state = np.full(J, _START, dtype=np.int64)
    last = np.zeros(J, dtype=np.int64)
    seen = np.zeros(J, dtype=bool)
    symbols, scales = [], []
    for t in range(T):
        present = mask[t]
        if not present.any():
            continue
        residual = q[t] - last
        scale = np.where(seen, _scales(state), _INTRA_SCALE)
        symbols.append(residual[present])
        scales.append(scale[present])
        _update(state, present & seen, residual)
        last[present] = q[t, present]
        seen |= present
    encoder = constriction.stream.queue.RangeEncoder()
    if symbols:
        flat = np.concatenate(symbols).astype(np.int32)
        encoder.encode(flat, _law(), np.zeros(len(flat)), np.concatenate(scales))
    words = encoder.get_compressed().astype("<u4")
    return _container(stream, columns, quant, mask, words)


def _varint(n: int) -> bytes:
    out = bytearray()
    while True:
        byte, n = n & 0x7F, n >> 7
        out.append(byte | (0x80 if n else 0))
        if not n:
            return bytes(out)


def _container(stream: FapStream, columns, quant, mask, words) -> bytes:
    T = len(stream)
    sent = np.zeros(72, dtype=bool)
    sent[columns] = True
    frames = stream.frame_numbers
    consecutive = bool(np.array_equal(frames, frames[0] + np.arange(T))) and 0 <= frames[0] < 2**31
    name = stream.name.encode("utf-8")[:255].decode("utf-8", "ignore").encode("utf-8")  # cut on a character
    parts = [_HEAD.pack(MAGIC, FORMAT_VERSION, _CONSECUTIVE if consecutive else 0, stream.fps, quant, T,
                        np.packbits(sent).tobytes()),
             bytes([len(name)]), name]
    if consecutive:
        parts.append(struct.pack("<I", int(frames[0])))
    else:
        if frames.min() < 0 or frames.max() >= 2**31:
            raise ValueError("stream.frame_numbers must lie from 0 to 2**31 - 1")
        parts.append(frames.astype("<u4").tobytes())
    # frame masks: distinct patterns, then runs of frames sharing one
    patterns, index = np.unique(mask, axis=0, return_inverse=True)
    index = np.asarray(index).reshape(-1)
    parts.append(_varint(len(patterns)))
    parts += [np.packbits(p).tobytes() for p in patterns]
    starts = np.flatnonzero(np.r_[True, index[1:] != index[:-1]])
    lengths = np.diff(np.r_[starts, T])
    parts.append(_varint(len(starts)))
    parts += [_varint(int(n)) + _varint(int(index[s])) for s, n in zip(starts, lengths, strict=True)]
    parts.append(struct.pack("<I", len(words)))
    parts.append(words.tobytes())
    body = b"".join(parts)
    return body + struct.pack("<I", zlib.crc32(body))


class _Reader:
    """Reads fields off a checked body; every overrun is a FileFormatError naming ``source``."""

    def __init__(self, body: bytes, at: int, source: str):
        self.body, self.at, self.source = body, at, source

    def take(self, n: int, what: str) -> bytes:
        if n < 0 or self.at + n > len(self.body):
            raise FileFormatError(self.source, f"ends inside its {what}")
        chunk = self.body[self.at:self.at + n]
        self.at += n
        return chunk

    def varint(self, what: str) -> int:
        value = 0
        for shift in range(0, 35, 7):
            byte = self.take(1, what)[0]
            value |= (byte & 0x7F) << shift
            if not byte & 0x80:
                return value
        raise FileFormatError(self.source, f"has a malformed {what}")


def decode_faps(data: bytes, *, source: str = "<bytes>") -> FapStream:
    """Decode ``.fba`` bytes made by :func:`encode_faps` back into a :class:`FapStream`.

    Values are the quantised reconstruction in FAPU; the mask is the sent FAPs on the frames that
    carried them (no other FAP, and never FAPs 1 and 2).

    Raises
    ------
    FileFormatError
        Naming ``source``: a truncated or corrupt payload (the end check fails), another file, a
        version this faceanim does not read, or fields that contradict one another.
    """
    import constriction

    data = bytes(data)
    fail = FileFormatError
    if not data:
        raise fail(source, "is empty")
    if not data.startswith(MAGIC[:len(data)]):
        raise fail(source, "is not a faceanim FAP stream (.fba): its first bytes are not b'faFB'")
    if len(data) < _HEAD.size + 4:
        raise fail(source, f"is truncated ({len(data)} bytes; the header alone takes {_HEAD.size + 4})")
    _, version, flags, fps, quant, T, sent_bytes = _HEAD.unpack_from(data)
    if version != FORMAT_VERSION:
        raise fail(source, f"is version {version} of the .fba format; this faceanim reads version {FORMAT_VERSION}")
    body, check = data[:-4], struct.unpack("<I", data[-4:])[0]
    if zlib.crc32(body) != check:
        raise fail(source, "is truncated or corrupt (its end check does not match)")
    if flags & ~_CONSECUTIVE:
        raise fail(source, f"has unknown flags {flags:#x}")
    sane = np.isfinite(fps) and 0 < fps <= _FPS_MAX and np.isfinite(quant) and quant > 0
    if not sane or not 1 <= T <= _MAX_FRAMES:
        raise fail(source, f"has an impossible header (fps {fps:g}, quant {quant:g}, {T} frames)")
    sent = np.unpackbits(np.frombuffer(sent_bytes, dtype=np.uint8)).astype(bool)
    if sent[:2].any() or sent[FAP_COUNT:].any() or not sent.any():
        raise fail(source, "sends no FAPs, or FAPs that cannot be coded (1, 2, or beyond 68)")
    columns = np.flatnonzero(sent)
    J = len(columns)
    read = _Reader(body, _HEAD.size, source)
    raw_name = read.take(read.take(1, "name")[0], "name")
    try:
        name = raw_name.decode("utf-8")
    except UnicodeDecodeError:
        raise fail(source, "has a name that is not UTF-8") from None
    if not name or any(c.isspace() for c in name):
        raise fail(source, "has an empty name or one with whitespace")
    if flags & _CONSECUTIVE:
        first = struct.unpack("<I", read.take(4, "frame numbers"))[0]
        frames = first + np.arange(T, dtype=np.int64)
    else:
        frames = np.frombuffer(read.take(4 * T, "frame numbers"), dtype="<u4").astype(np.int64)
    if frames[-1] >= 2**31 or (np.diff(frames) < 0).any():
        raise fail(source, "has frame numbers that decrease or exceed 2**31 - 1")

    count = read.varint("mask patterns")
    if not 1 <= count <= T:
        raise fail(source, f"has {count} mask patterns for {T} frames")
    width = (J + 7) // 8
    patterns = np.unpackbits(np.frombuffer(read.take(count * width, "mask patterns"), dtype=np.uint8)
                             .reshape(count, width), axis=1)[:, :J].astype(bool)
    runs = read.varint("mask runs")
    if not 1 <= runs <= T:
        raise fail(source, f"has {runs} mask runs for {T} frames")
    lengths, which = np.empty(runs, dtype=np.int64), np.empty(runs, dtype=np.int64)
    for r in range(runs):
        lengths[r], which[r] = read.varint("mask runs"), read.varint("mask runs")
    if (lengths < 1).any() or lengths.sum() != T or (which >= count).any():
        raise fail(source, "has mask runs that do not cover its frames")
    mask_sent = patterns[np.repeat(which, lengths)]
    n_words = struct.unpack("<I", read.take(4, "payload"))[0]
    if read.at + 4 * n_words != len(body):
        raise fail(source, f"has a payload of {len(body) - read.at - 4} bytes where its header says {4 * n_words}")
    words = np.frombuffer(read.take(4 * n_words, "payload"), dtype="<u4").astype(np.uint32)

    decoder = constriction.stream.queue.RangeDecoder(words)
    law = _law()
    state = np.full(J, _START, dtype=np.int64)
    last = np.zeros(J, dtype=np.int64)
    seen = np.zeros(J, dtype=bool)
    q = np.zeros((T, J), dtype=np.int64)
    residual = np.zeros(J, dtype=np.int64)
    for t in range(T):
        present = mask_sent[t]
        n = int(present.sum())
        if not n:
            continue
        scale = np.where(seen, _scales(state), _INTRA_SCALE)[present]
        residual[:] = 0
        try:
            residual[present] = decoder.decode(law, np.zeros(n), scale)
        except (AssertionError, ValueError, RuntimeError):  # constriction asserts on words no encoder makes
            raise fail(source, f"is corrupt (frame {t} cannot be decoded)") from None
        value = last + residual
        if (np.abs(value[present]) >= _LIMIT).any():
            raise fail(source, f"is corrupt (frame {t} decodes out of range)")
        _update(state, present & seen, residual)
        last[present] = value[present]
        q[t, present] = value[present]
        seen |= present
    if not decoder.maybe_exhausted():
        raise fail(source, "is corrupt (its payload holds more than its frames)")
    values = np.zeros((T, FAP_COUNT))
    values[:, columns] = q * _steps(columns, quant)
    mask = np.zeros((T, FAP_COUNT), dtype=bool)
    mask[:, columns] = mask_sent
    return FapStream(values, mask, fps=fps, frame_numbers=frames, name=name)


def write_fba(path, stream: FapStream, *, quant: float = 1.0, faps: Sequence[int] | None = None) -> bytes:
    """Code ``stream`` (see :func:`encode_faps`) into the file ``path``, complete or not at all; returns
    the bytes written."""
    data = encode_faps(stream, quant=quant, faps=faps)
    with atomic_output(path) as tmp:
        tmp.write_bytes(data)
    return data


def read_fba(path) -> FapStream:
    """Read a ``.fba`` file written by :func:`write_fba`.

    Raises
    ------
    InputError
        The file does not exist or cannot be read.
    FileFormatError
        It is not a ``.fba``, is truncated or corrupt, or of another version (see :func:`decode_faps`).
    """
    from pathlib import Path

    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"{path}: cannot be read ({exc.strerror})") from None
    return decode_faps(data, source=str(path))


def fba_quant(path) -> float:
    """The quantiser scale a ``.fba`` file was coded with (read :func:`read_fba` first: this reads only
    the header, and trusts it)."""
    with open(path, "rb") as handle:
        head = handle.read(_HEAD.size)
    if len(head) != _HEAD.size:
        raise FileFormatError(path, "is cut short in its header")
    return float(_HEAD.unpack(head)[4])


def fap_psnr(original: FapStream, decoded: FapStream, *, faps: Sequence[int] | None = None) -> float:
    """FAP PSNR in dB: ``20 log10(peak-to-peak range of the original FAPs / RMS error)``.

    Over the FAPs ``faps`` (1-based; default: the low-level FAPs ``original`` carries) on the frames
    whose original carries them, all pooled: the range is the largest minus the smallest original
    value among them, in each FAP's own units (FAPU counts, 1e-5 rad), the error is the decoded
    minus the original value (a FAP the decoded stream lacks counts as its held value, 0 before
    any). ``inf`` for an exact copy.

    >>> import numpy as np
    >>> values = np.zeros((2, 68)); values[:, 2] = [0, 100]
    >>> mask = np.zeros((2, 68), bool); mask[:, 2] = True
    >>> a = FapStream(values, mask, 25.0); b = FapStream(values + [[0] * 2 + [10] + [0] * 65], mask, 25.0)
    >>> round(fap_psnr(a, b), 2)   # range 100, RMS error 10
    20.0
    """
    from .fapstream import held

    if len(original) != len(decoded):
        raise ValueError(f"original and decoded must have as many frames, got {len(original)} and {len(decoded)}")
    columns = _columns(original, faps)
    where = original.mask[:, columns]
    truth = original.values[:, columns][where]
    if not truth.size:
        raise ValueError("original carries none of the FAPs to compare")
    error = held(decoded)[:, columns][where] - truth
    rms = float(np.sqrt(np.mean(error**2)))
    spread = float(truth.max() - truth.min())
    if rms == 0:
        return float("inf")
    return 20 * np.log10(spread / rms) if spread > 0 else float("-inf")
