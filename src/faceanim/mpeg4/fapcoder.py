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

The container (``.fba``, faceanim's own, **not** the MPEG-4 FBA bit syntax), little-endian, version 2::

    magic      4 bytes  b"faFB"
    version    u8       2
    flags      u8       bit 0: frame numbers are first, first + 1, ...
    fps        f64
    quant      f64
    frames     u32      T, from 1 to 2**22
    faps       9 bytes  the 68 sent-FAP flags, FAP 1 first, MSB first (numpy.packbits); FAPs 1-2 never set
    name       u8 length, then that many bytes of UTF-8 (one token)
    first      u32      the first frame's number (flag set only)
    packets, until they hold T frames, each:
      runs     varint R >= 1, then R runs of frames sharing a mask: varint (length << 1 | same), then,
               unless ``same`` (the previous run's pattern again, across packets), the pattern:
               ceil(J/8) bytes (J sent FAPs, packbits)
      numbers  flag clear: one u32 per frame of the packet (never decreasing, < 2**31)
      payload  varint N, then N u32 words: the packet's symbols, range coded and sealed
    check      u32 CRC-32 of every byte before it

A packet is decodable alone once it has arrived: its range coder is sealed at its end (the adaptive
models' state carries over, so a packet costs only its header and the sealing, about 5 bytes).
:class:`FbaDecoder` decodes a stream as its bytes arrive, a packet at a time, with memory bounded by a
packet; :func:`encode_faps`' ``packet`` sets the frames per packet, the decoder's delay (default
:data:`PACKET_SECONDS` of frames). Version 1 (read, no longer written) had the same header, then every
frame's mask ahead of a single payload for the whole stream, which cannot be decoded before it ends.

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

__all__ = ["encode_faps", "decode_faps", "FbaDecoder", "read_fba", "read_fba_pieces", "write_fba", "fba_quant",
           "fap_psnr", "FORMAT_VERSION", "PACKET_SECONDS"]

MAGIC = b"faFB"
FORMAT_VERSION = 2
_READS = (1, 2)
# Frames per packet by default, in seconds of the stream: the decoder's delay. A packet costs ~5 bytes
# (its header and the range coder's sealing), so at 25 fps one packet a second adds ~0.04 kbit/s, one a
# frame ~1 kbit/s (benchmarks/fap_coding.py measures it): a delay of a second keeps the rate of the
# 8-FAP speech streams (~0.4 kbit/s) within 10% of one packet for the whole stream.
PACKET_SECONDS = 1.0
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


def encode_faps(stream: FapStream, *, quant: float = 1.0, faps: Sequence[int] | None = None,
                packet: int | None = None) -> bytes:
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
    packet : int, optional
        Frames per packet, the decoder's delay (:class:`FbaDecoder` decodes a packet as soon as it has
        all of it); default :data:`PACKET_SECONDS` of frames at the stream's rate. Each packet costs about
        5 bytes (its header and the range coder's last word).

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
    if packet is None:
        packet = max(1, round(PACKET_SECONDS * stream.fps))
    if isinstance(packet, bool) or not isinstance(packet, (int, np.integer)) or packet < 1:
        raise ValueError(f"packet must be a whole number of frames from 1, got {packet!r}")
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
    frames = stream.frame_numbers
    consecutive = bool(np.array_equal(frames, frames[0] + np.arange(T))) and 0 <= frames[0] < 2**31
    if not consecutive and (frames.min() < 0 or frames.max() >= 2**31):
        raise ValueError("stream.frame_numbers must lie from 0 to 2**31 - 1")

    parts = [_header(stream, columns, quant, consecutive)]
    J = len(columns)
    state = np.full(J, _START, dtype=np.int64)
    last = np.zeros(J, dtype=np.int64)
    seen = np.zeros(J, dtype=bool)
    previous = None  # the pattern of the last run written
    law = _law()
    for begin in range(0, T, packet):
        stop = min(T, begin + packet)
        symbols, scales = [], []
        for t in range(begin, stop):
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
            encoder.encode(flat, law, np.zeros(len(flat)), np.concatenate(scales))
        words = encoder.get_compressed().astype("<u4")
        previous = _packet(parts, mask[begin:stop], None if consecutive else frames[begin:stop], words, previous)
    body = b"".join(parts)
    return body + struct.pack("<I", zlib.crc32(body))


def _varint(n: int) -> bytes:
    out = bytearray()
    while True:
        byte, n = n & 0x7F, n >> 7
        out.append(byte | (0x80 if n else 0))
        if not n:
            return bytes(out)


def _header(stream: FapStream, columns, quant, consecutive: bool) -> bytes:
    sent = np.zeros(72, dtype=bool)
    sent[columns] = True
    name = stream.name.encode("utf-8")[:255].decode("utf-8", "ignore").encode("utf-8")  # cut on a character
    head = _HEAD.pack(MAGIC, FORMAT_VERSION, _CONSECUTIVE if consecutive else 0, stream.fps, quant, len(stream),
                      np.packbits(sent).tobytes())
    first = struct.pack("<I", int(stream.frame_numbers[0])) if consecutive else b""
    return head + bytes([len(name)]) + name + first


def _packet(parts: list, mask: np.ndarray, frames, words: np.ndarray, previous):
    """Append one packet (its frames' ``mask``, their numbers unless consecutive, the range coder's
    ``words``) to ``parts``; returns the pattern of its last run."""
    starts = np.flatnonzero(np.r_[True, (mask[1:] != mask[:-1]).any(axis=1)])
    lengths = np.diff(np.r_[starts, len(mask)])
    parts.append(_varint(len(starts)))
    for s, n in zip(starts, lengths, strict=True):
        same = previous is not None and np.array_equal(mask[s], previous)
        parts.append(_varint(int(n) << 1 | int(same)))
        if not same:
            parts.append(np.packbits(mask[s]).tobytes())
        previous = mask[s]
    if frames is not None:
        parts.append(frames.astype("<u4").tobytes())
    parts.append(_varint(len(words)))
    parts.append(words.tobytes())
    return previous


class _Short(Exception):
    """The bytes so far end inside the field being read: wait for more."""


class _Reader:
    """Reads fields off ``body`` from ``at``. Running past the end raises ``_Short`` when more bytes may
    still come (``final`` False), else a FileFormatError naming ``source``."""

    def __init__(self, body, at: int, source: str, final: bool = True):
        self.body, self.at, self.source, self.final = body, at, source, final

    def take(self, n: int, what: str) -> bytes:
        if n < 0 or self.at + n > len(self.body):
            if not self.final and n >= 0:
                raise _Short
            raise FileFormatError(self.source, f"ends inside its {what}")
        chunk = bytes(self.body[self.at:self.at + n])
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


def _check_head(data, source: str) -> tuple:
    """The fixed header's fields, checked; ``data`` holds at least ``_HEAD.size`` bytes."""
    fail = FileFormatError
    _, version, flags, fps, quant, T, sent_bytes = _HEAD.unpack_from(bytes(data[:_HEAD.size]))
    if version not in _READS:
        raise fail(source, f"is version {version} of the .fba format; this faceanim reads versions "
                           f"{' and '.join(map(str, _READS))}")
    if flags & ~_CONSECUTIVE:
        raise fail(source, f"has unknown flags {flags:#x}")
    sane = np.isfinite(fps) and 0 < fps <= _FPS_MAX and np.isfinite(quant) and quant > 0
    if not sane or not 1 <= T <= _MAX_FRAMES:
        raise fail(source, f"has an impossible header (fps {fps:g}, quant {quant:g}, {T} frames)")
    sent = np.unpackbits(np.frombuffer(sent_bytes, dtype=np.uint8)).astype(bool)
    if sent[:2].any() or sent[FAP_COUNT:].any() or not sent.any():
        raise fail(source, "sends no FAPs, or FAPs that cannot be coded (1, 2, or beyond 68)")
    return version, flags, fps, quant, T, np.flatnonzero(sent)


def _read_name(read: _Reader) -> str:
    raw = read.take(read.take(1, "name")[0], "name")
    try:
        name = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise FileFormatError(read.source, "has a name that is not UTF-8") from None
    if not name or any(c.isspace() for c in name):
        raise FileFormatError(read.source, "has an empty name or one with whitespace")
    return name


class _Symbols:
    """The decoder's side of the adaptive models: the FAPs' scale states and last values."""

    def __init__(self, J: int, source: str):
        self.state = np.full(J, _START, dtype=np.int64)
        self.last = np.zeros(J, dtype=np.int64)
        self.seen = np.zeros(J, dtype=bool)
        self.residual = np.zeros(J, dtype=np.int64)
        self.source = source
        self.law = _law()

    def frames(self, decoder, mask_sent: np.ndarray, first: int) -> np.ndarray:
        """(n, J) the quantised values of the frames ``mask_sent (n, J)`` from ``decoder``; frame numbers
        in messages count from ``first``."""
        q = np.zeros(mask_sent.shape, dtype=np.int64)
        residual = self.residual
        for t, present in enumerate(mask_sent):
            n = int(present.sum())
            if not n:
                continue
            scale = np.where(self.seen, _scales(self.state), _INTRA_SCALE)[present]
            residual[:] = 0
            try:
                residual[present] = decoder.decode(self.law, np.zeros(n), scale)
            except (AssertionError, ValueError, RuntimeError):  # constriction asserts on words no encoder makes
                raise FileFormatError(self.source, f"is corrupt (frame {first + t} cannot be decoded)") from None
            value = self.last + residual
            if (np.abs(value[present]) >= _LIMIT).any():
                raise FileFormatError(self.source, f"is corrupt (frame {first + t} decodes out of range)")
            _update(self.state, present & self.seen, residual)
            self.last[present] = value[present]
            q[t, present] = value[present]
            self.seen |= present
        return q


class FbaDecoder:
    """Decodes a ``.fba`` as its bytes arrive: :meth:`feed` it bytes in pieces of any size and it returns
    the frames that have become decodable (each packet's as soon as the packet is whole), then
    :meth:`close` it, which checks the end. Memory holds one packet, not the stream.

    The frames come out before the end check has been read: a consumer that must not act on a damaged
    stream keeps what it makes provisional until :meth:`close` returns (``fap-decompress`` writes its
    ``.fap`` atomically). A file of version 1 (one range-coded payload for the whole stream) is read
    whole and its frames come out at :meth:`close`.

    >>> import numpy as np
    >>> values = np.zeros((50, 68)); values[:, 2] = np.arange(50) * 40.0
    >>> mask = np.zeros((50, 68), bool); mask[:, 2] = True
    >>> data = encode_faps(FapStream(values, mask, fps=25.0), packet=10)
    >>> decoder = FbaDecoder()
    >>> [len(decoder.feed(data[k:k + 16]) or ()) for k in range(0, len(data), 16)]
    [0, 0, 0, 10, 10, 10, 20]
    >>> decoder.close() is None and decoder.frames_done
    50
    """

    def __init__(self, source: str = "<bytes>"):
        self.source = str(source)
        self._buffer = bytearray()
        self._crc = 0
        self._head = None  # (version, flags, fps, quant, T, columns, name, first frame or None)
        self._symbols = None
        self._pattern = None
        self._last_frame = -1
        self.frames_done = 0
        self.packet_frames = None  # the frames of the first packet, once it is read: the stream's delay
        self._ended = False
        self._closed = False

    # ---- the header, once read

    @property
    def fps(self) -> float | None:
        return None if self._head is None else self._head[2]

    @property
    def quant(self) -> float | None:
        return None if self._head is None else self._head[3]

    @property
    def frame_count(self) -> int | None:
        """T, the frames the stream holds (from its header), or None before the header has arrived."""
        return None if self._head is None else self._head[4]

    @property
    def name(self) -> str | None:
        return None if self._head is None else self._head[6]

    # ---- decoding

    def feed(self, data) -> FapStream | None:
        """Take the next bytes of the stream; returns the frames they completed (a FapStream numbering
        them as the stream does), or None when they completed none.

        Raises
        ------
        FileFormatError
            Naming the source: what has arrived cannot be part of a valid ``.fba``.
        """
        if self._closed:
            raise ValueError("this FbaDecoder is closed")
        self._buffer += bytes(data)
        if not self._buffer:
            return None
        out = []
        try:
            if self._head is None:
                self._read_head()
            if self._head[0] == 1:  # version 1: one payload, read whole at close
                return None
            while not self._ended:
                decoded = self._read_packet()
                out.append(decoded)
            if len(self._buffer) > 4:
                raise FileFormatError(self.source, "has bytes after its end check")
        except _Short:
            pass
        return self._stream(out)

    def close(self) -> FapStream | None:
        """The stream is complete: check its end; returns the frames still held (a version 1 file's).

        Raises
        ------
        FileFormatError
            The stream is truncated (ends before its last frame or its end check) or its end check fails.
        """
        if self._closed:
            return None
        self._closed = True
        fail = FileFormatError
        if self._head is None:
            if not self._buffer:
                raise fail(self.source, "is empty")
            raise fail(self.source, f"is truncated ({len(self._buffer)} bytes; the header alone takes "
                                     f"{_HEAD.size + 4})")
        if self._head[0] == 1:
            return _decode_v1(bytes(self._buffer), self.source)
        if not self._ended:
            raise fail(self.source, f"is truncated or corrupt (it ends after frame {self.frames_done} of "
                                    f"{self._head[4]})")
        if len(self._buffer) != 4 or struct.unpack("<I", self._buffer)[0] != self._crc:
            raise fail(self.source, "is truncated or corrupt (its end check does not match)")
        return None

    def _consume(self, n: int) -> None:
        self._crc = zlib.crc32(self._buffer[:n], self._crc)
        del self._buffer[:n]

    def _read_head(self) -> None:
        buffer = self._buffer
        if not bytes(buffer[:4]) == MAGIC[:len(buffer[:4])]:
            raise FileFormatError(self.source, "is not a faceanim FAP stream (.fba): its first bytes are not b'faFB'")
        if len(buffer) < _HEAD.size:
            raise _Short
        version, flags, fps, quant, T, columns = _check_head(buffer, self.source)
        if version == 1:
            self._head = (version, flags, fps, quant, T, columns, None, None)
            return
        read = _Reader(buffer, _HEAD.size, self.source, final=False)
        name = _read_name(read)
        first = struct.unpack("<I", read.take(4, "frame numbers"))[0] if flags & _CONSECUTIVE else None
        if first is not None and first + T - 1 >= 2**31:
            raise FileFormatError(self.source, "has frame numbers that decrease or exceed 2**31 - 1")
        self._head = (version, flags, fps, quant, T, columns, name, first)
        self._symbols = _Symbols(len(columns), self.source)
        self._consume(read.at)

    def _read_packet(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(frame numbers, mask (n, J), quantised values (n, J)) of the next packet, once it is whole."""
        import constriction

        _, flags, _, _, T, columns, _, first = self._head
        J, left = len(columns), T - self.frames_done
        fail = FileFormatError
        read = _Reader(self._buffer, 0, self.source, final=False)
        runs = read.varint("mask runs")
        if not 1 <= runs <= left:
            raise fail(self.source, f"has a packet of {runs} mask runs where {left} frames are left")
        width = (J + 7) // 8
        patterns, lengths, pattern = [], [], self._pattern
        for _ in range(runs):
            code = read.varint("mask runs")
            n, same = code >> 1, code & 1
            if same:
                if pattern is None:
                    raise fail(self.source, "has a mask run that repeats a pattern before any")
            else:
                pattern = np.unpackbits(np.frombuffer(read.take(width, "mask patterns"), dtype=np.uint8))[:J]
                pattern = pattern.astype(bool)
            lengths.append(n)
            patterns.append(pattern)
        count = sum(lengths)
        if min(lengths) < 1 or count > left:
            raise fail(self.source, "has mask runs that do not cover its frames")
        if flags & _CONSECUTIVE:
            frames = first + self.frames_done + np.arange(count, dtype=np.int64)
        else:
            frames = np.frombuffer(read.take(4 * count, "frame numbers"), dtype="<u4").astype(np.int64)
            if frames[-1] >= 2**31 or (np.diff(frames) < 0).any() or frames[0] < self._last_frame:
                raise fail(self.source, "has frame numbers that decrease or exceed 2**31 - 1")
        n_words = read.varint("payload")
        if n_words > 2 * J * count + 2:  # two words a symbol is more than any symbol takes
            raise fail(self.source, f"has a packet payload of {n_words} words for {count} frames")
        words = np.frombuffer(read.take(4 * n_words, "payload"), dtype="<u4").astype(np.uint32)
        mask_sent = np.repeat(np.array(patterns), lengths, axis=0)
        decoder = constriction.stream.queue.RangeDecoder(words)
        q = self._symbols.frames(decoder, mask_sent, self.frames_done)
        if not decoder.maybe_exhausted():
            raise fail(self.source, f"is corrupt (a packet's payload holds more than its frames, at frame "
                                    f"{self.frames_done + count})")
        self._consume(read.at)
        self._pattern = pattern
        self._last_frame = int(frames[-1])
        if self.packet_frames is None:
            self.packet_frames = count
        self.frames_done += count
        self._ended = self.frames_done == T
        return frames, mask_sent, q

    def _stream(self, packets) -> FapStream | None:
        if not packets:
            return None
        _, _, fps, quant, _, columns, name, _ = self._head
        frames = np.concatenate([p[0] for p in packets])
        values = np.zeros((len(frames), FAP_COUNT))
        values[:, columns] = np.concatenate([p[2] for p in packets]) * _steps(columns, quant)
        mask = np.zeros((len(frames), FAP_COUNT), dtype=bool)
        mask[:, columns] = np.concatenate([p[1] for p in packets])
        return FapStream(values, mask, fps=fps, frame_numbers=frames, name=name)


def decode_faps(data: bytes, *, source: str = "<bytes>") -> FapStream:
    """Decode ``.fba`` bytes made by :func:`encode_faps` back into a :class:`FapStream`.

    Values are the quantised reconstruction in FAPU; the mask is the sent FAPs on the frames that
    carried them (no other FAP, and never FAPs 1 and 2). Reads versions 1 and 2 (see
    :class:`FbaDecoder` to decode as the bytes arrive).

    Raises
    ------
    FileFormatError
        Naming ``source``: a truncated or corrupt payload (the end check fails), another file, a
        version this faceanim does not read, or fields that contradict one another.
    """
    data = bytes(data)
    fail = FileFormatError
    if not data:
        raise fail(source, "is empty")
    if not data.startswith(MAGIC[:len(data)]):
        raise fail(source, "is not a faceanim FAP stream (.fba): its first bytes are not b'faFB'")
    if len(data) < _HEAD.size + 4:
        raise fail(source, f"is truncated ({len(data)} bytes; the header alone takes {_HEAD.size + 4})")
    _check_head(data, source)
    if zlib.crc32(data[:-4]) != struct.unpack("<I", data[-4:])[0]:
        raise fail(source, "is truncated or corrupt (its end check does not match)")
    decoder = FbaDecoder(source)
    first = decoder.feed(data)
    last = decoder.close()
    return first if last is None else last


def _decode_v1(data: bytes, source: str) -> FapStream:
    """A version 1 ``.fba`` (one payload for the whole stream, masks ahead of it), whole."""
    import constriction

    fail = FileFormatError
    if len(data) < _HEAD.size + 4:
        raise fail(source, f"is truncated ({len(data)} bytes; the header alone takes {_HEAD.size + 4})")
    _, flags, fps, quant, T, columns = _check_head(data, source)
    body, check = data[:-4], struct.unpack("<I", data[-4:])[0]
    if zlib.crc32(body) != check:
        raise fail(source, "is truncated or corrupt (its end check does not match)")
    J = len(columns)
    read = _Reader(body, _HEAD.size, source)
    name = _read_name(read)
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
    q = _Symbols(J, source).frames(decoder, mask_sent, 0)
    if not decoder.maybe_exhausted():
        raise fail(source, "is corrupt (its payload holds more than its frames)")
    values = np.zeros((T, FAP_COUNT))
    values[:, columns] = q * _steps(columns, quant)
    mask = np.zeros((T, FAP_COUNT), dtype=bool)
    mask[:, columns] = mask_sent
    return FapStream(values, mask, fps=fps, frame_numbers=frames, name=name)


def write_fba(path, stream: FapStream, *, quant: float = 1.0, faps: Sequence[int] | None = None,
              packet: int | None = None) -> bytes:
    """Code ``stream`` (see :func:`encode_faps`) into the file ``path``, complete or not at all; returns
    the bytes written."""
    data = encode_faps(stream, quant=quant, faps=faps, packet=packet)
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


def read_fba_pieces(path, *, chunk: int = 1 << 16):
    """Decode the ``.fba`` file ``path`` as it is read, ``chunk`` bytes at a time (:class:`FbaDecoder`):
    yields the :class:`FbaDecoder` first (its header read: fps, quant, frame count, name), then each
    FapStream of frames as they become decodable. Memory holds a chunk and a packet, not the stream.
    The last frames come before the end check is read; it raises after them if the file is damaged.

    Raises
    ------
    InputError
        The file does not exist or cannot be read.
    FileFormatError
        It is not a ``.fba``, is truncated or corrupt, or of another version.
    """
    from pathlib import Path

    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    decoder = FbaDecoder(str(path))
    try:
        with open(path, "rb") as handle:
            held = []
            while decoder.frame_count is None:
                data = handle.read(chunk)
                piece = decoder.feed(data) if data else decoder.close()
                if piece is not None:
                    held.append(piece)
            yield decoder
            yield from held
            while data := handle.read(chunk):
                piece = decoder.feed(data)
                if piece is not None:
                    yield piece
    except OSError as exc:
        raise InputError(f"{path}: cannot be read ({exc.strerror})") from None
    piece = decoder.close()
    if piece is not None:
        yield piece


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
    return float(20 * np.log10(spread / rms)) if spread > 0 else float("-inf")
