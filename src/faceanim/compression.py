"""The FAP coding jobs: ``faceanim fap-compress`` (a ``.fap`` into faceanim's coded ``.fba``) and
``faceanim fap-decompress`` (back to a ``.fap``, optionally interpreted through a speaker model).

The coder itself is :mod:`faceanim.mpeg4.fapcoder` (its docstring describes the scheme and the
container). These functions name their inputs, check their outputs before any work and write them
complete or not at all.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import InputError
from .mpeg4 import FAP_COUNT
from .outputs import check_outputs

__all__ = ["CompressionResult", "DecompressionResult", "fap_compress", "fap_decompress", "parse_fap_list"]


@dataclass(frozen=True)
class CompressionResult:
    """What ``fap_compress`` wrote: ``size`` bytes for ``frames`` frames at ``fps``, sending ``faps``
    (1-based numbers) at quantiser scale ``quant``; ``psnr`` is the FAP PSNR of the decoded stream against
    the input in dB (:func:`faceanim.mpeg4.fapcoder.fap_psnr`)."""

    size: int
    frames: int
    fps: float
    faps: tuple[int, ...]
    quant: float
    psnr: float

    @property
    def kbits_per_second(self) -> float:
        """The rate at the stream's frame rate, in kbit/s (1000 bits), the whole file counted."""
        return self.size * 8 / (self.frames / self.fps) / 1000

    def summary(self) -> str:
        return (f"{self.size} bytes, {self.frames} frames, {self.kbits_per_second:.2f} kbit/s at {self.fps:g} fps, "
                f"FAP PSNR {self.psnr:.1f} dB over {len(self.faps)} FAPs (quant {self.quant:g})")


def parse_fap_list(text: str) -> tuple[int, ...]:
    """``"3,14,16,17,51-54"`` as sorted FAP numbers; InputError (naming ``--faps``) for anything else.

    >>> parse_fap_list("3, 51-54,14")
    (3, 14, 51, 52, 53, 54)
    >>> parse_fap_list("5-3")
    Traceback (most recent call last):
    ...
    faceanim.errors.InputError: --faps 5-3: '5-3' is a range that ends before it starts
    """
    numbers: set[int] = set()
    items = [item.strip() for item in str(text).split(",")]
    for item in items:
        ends = item.split("-")
        if not item or len(ends) > 2 or not all(e.strip().isdigit() for e in ends):
            raise InputError(f"--faps {text}: {item!r} is not a FAP number or a range like 51-54")
        low, high = int(ends[0]), int(ends[-1])
        if low > high:
            raise InputError(f"--faps {text}: {item!r} is a range that ends before it starts")
        for number in (low, high):
            if not 3 <= number <= FAP_COUNT:
                why = " (1 and 2, visemes and expressions, are not coded)" if number in (1, 2) else ""
                raise InputError(f"--faps {text}: FAP {number} is not one from 3 to {FAP_COUNT}{why}")
        numbers.update(range(low, high + 1))
    return tuple(sorted(numbers))


def _quant(quant) -> float:
    try:
        value = float(quant)
    except (TypeError, ValueError):
        raise InputError(f"--quant {quant}: is not a number") from None
    if not np.isfinite(value) or value <= 0:
        raise InputError(f"--quant {quant}: must be a positive number (the scale of the steps QP x quant)")
    return value


def fap_compress(source, output, *, quant: float = 1.0, faps=None, packet: int | None = None) -> CompressionResult:
    """``faceanim fap-compress``: code the ``.fap`` at ``source`` into the ``.fba`` at ``output``.

    Parameters
    ----------
    quant : float
        Scale of the quantiser steps ``QP x quant``; positive.
    faps : str or sequence of int, optional
        The FAPs to send (``"3,14,16,17,51-54"`` or numbers 3-68); default every low-level FAP the file carries.
    packet : int, optional
        Frames per packet: the delay of a decoder reading the ``.fba`` as it arrives (default 1 s of
        frames; each packet costs ~5 bytes).

    Returns
    -------
    CompressionResult
        Size, rate, and the PSNR of the decoded stream against the input over the sent FAPs.
    """
    from .atomic import atomic_output
    from .mpeg4.fapcoder import decode_faps, encode_faps, fap_psnr
    from .mpeg4.fapfile import read_fap

    output = Path(output)
    quant = _quant(quant)
    if isinstance(faps, str):
        faps = parse_fap_list(faps)
    if packet is not None and (isinstance(packet, bool) or not isinstance(packet, int) or packet < 1):
        raise InputError(f"--packet {packet}: give a whole number of frames from 1")
    check_outputs({"-o": (output, ".fba")}, inputs={"IN.fap": source})
    stream = read_fap(source)
    try:
        data = encode_faps(stream, quant=quant, faps=faps, packet=packet)
    except ValueError as exc:  # a setting this stream cannot be coded with (a FAP list, a quant too fine)
        raise InputError(f"{source}: {exc}") from None
    decoded = decode_faps(data, source=str(output))
    sent = tuple(int(c) + 1 for c in np.flatnonzero(decoded.mask.any(axis=0)))
    carried = [n for n in sent if stream.mask[:, n - 1].any()]
    psnr = fap_psnr(stream, decoded, faps=carried) if carried else float("nan")
    with atomic_output(output) as tmp:
        tmp.write_bytes(data)
    return CompressionResult(size=len(data), frames=len(stream), fps=stream.fps, faps=sent, quant=quant, psnr=psnr)


def fap_decompress(source, output, *, speaker=None, temporal: bool | None = None, causal: bool = False,
                   chunk: int = 1 << 16) -> DecompressionResult:
    """``faceanim fap-decompress``: decode the ``.fba`` at ``source`` into the ``.fap`` at ``output``;
    with ``speaker`` (a model file from ``faceanim speaker build``), the decoded FAPs are interpreted
    through it first (:meth:`~faceanim.speaker.SpeakerModel.regularise`: the model's FAPs regenerated
    from the parameters that best explain those received, filled in where they were not sent, each FAP
    weighed by the step it was coded with).

    ``temporal`` (default: wherever the model has a temporal prior, files from version 2 on): through
    the model's temporal prior, as a smoother within each packet of the stream (the frames a packet
    brings arrive together, so a frame is estimated from those after it in its packet as well as from
    all before, at no delay beyond the packet's) and with every FAP kept within its quantiser cell
    (``regularise(window=...)``); ``causal``: the prior's causal filter instead, frame by frame;
    ``False``: each frame alone. ``benchmarks/fap_coding.py`` measures the three.

    The file is decoded as it is read, ``chunk`` bytes at a time, a packet of frames at a time
    (:func:`~faceanim.mpeg4.fapcoder.read_fba_pieces`), interpreted and written out as they come: memory
    does not grow with the stream. The ``.fap`` appears only once the ``.fba``'s end check has passed.

    Returns a :class:`DecompressionResult` (frames, fps, the FAPs written); read the ``.fap`` for the
    values (they are not held).
    """
    from .atomic import atomic_output
    from .mpeg4.fapcoder import read_fba_pieces
    from .mpeg4.fapfile import fap_frame_lines, fap_header_line
    from .speaker.speakerfile import refusals_named

    output = Path(output)
    check_outputs({"-o": (output, ".fap")}, inputs={"IN.fba": source, "--speaker": speaker})
    model = None
    if speaker is not None:  # read first: a bad model file is found before the stream is decoded
        from .speaker import read_speaker

        model = read_speaker(speaker)
        if temporal is None:
            temporal = model.persistence is not None
        if temporal:  # a model without a prior is refused before the stream is decoded
            model.interpreter(temporal=True)
    pieces = read_fba_pieces(source, chunk=chunk)
    decoder = next(pieces)
    if round(decoder.fps) < 1:
        raise InputError(f"{source}: {decoder.fps:g} fps cannot be written as a .fap (whole frame rates from 1)")
    interpret = None
    frames, active = 0, np.zeros(FAP_COUNT, dtype=bool)

    def write(handle, piece):
        nonlocal frames, active
        if piece is not None:
            handle.write("\n".join(fap_frame_lines(piece)) + "\n")
            frames += len(piece)
            active |= piece.mask.any(axis=0)

    with atomic_output(output) as tmp, open(tmp, "w", encoding="utf-8") as handle, refusals_named(source, speaker):
        handle.write(fap_header_line(output, decoder.name, decoder.fps, decoder.frame_count) + "\n")
        for piece in pieces:
            if model is not None and interpret is None:  # at the first packet: its length is the window
                window = None
                if temporal and not causal:
                    window = decoder.packet_frames or max(1, round(decoder.fps))  # version 1: a second
                interpret = model.interpreter(quant=decoder.quant, temporal=bool(temporal), window=window)
            write(handle, piece if interpret is None else interpret(piece))
        if interpret is not None:
            write(handle, interpret.finish())
    return DecompressionResult(frames=frames, fps=decoder.fps, faps=tuple(int(c) + 1 for c in np.flatnonzero(active)))


@dataclass(frozen=True)
class DecompressionResult:
    """What ``fap_decompress`` wrote: ``frames`` frames at ``fps`` carrying the FAPs ``faps`` (1-based)."""

    frames: int
    fps: float
    faps: tuple[int, ...]

    def __len__(self) -> int:
        return self.frames
