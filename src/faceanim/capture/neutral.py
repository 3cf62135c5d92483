"""Choosing the neutral face that displacements are measured from."""

from __future__ import annotations

import numpy as np

from ..errors import InputError

__all__ = ["relaxed_window", "parse_neutral"]


def relaxed_window(points, usable, fps: float, *, seconds: float = 0.5, mouth=None) -> tuple[int, int]:
    """``(start, end)`` frames (end exclusive) of the most relaxed stretch of a performance.

    Relaxed means: close to the performance's median face (a face spends most of its time near
    rest), still (slow), and, when ``mouth (T,)`` gives the inner-lip gap, with the mouth closed.
    ``points (T, K, 3)`` in the head frame; ``usable (T,)`` frames with data.
    """
    p = np.asarray(points, dtype=np.float64)
    usable = np.asarray(usable, dtype=bool)
    if not usable.any():
        raise ValueError("no usable frame to choose a neutral from")
    median = np.median(p[usable], axis=0)
    spread = np.sqrt(((p - median) ** 2).sum(-1).mean(-1))
    speed = np.r_[0.0, np.sqrt(((p[1:] - p[:-1]) ** 2).sum(-1).mean(-1)) * fps]
    score = spread + 0.1 * speed / max(fps, 1.0)
    if mouth is not None:
        gap = np.asarray(mouth, dtype=np.float64)
        score = score + np.maximum(gap - np.nanmedian(gap[usable]), 0)
    score = np.where(usable & np.isfinite(score), score, np.inf)
    width = max(1, min(int(round(seconds * fps)), int(usable.sum())))
    window = np.convolve(score, np.ones(width), mode="valid")
    start = int(np.argmin(window))
    if not np.isfinite(window[start]):  # no window of consecutive usable frames: take the best frame
        start, width = int(np.argmin(score)), 1
    return start, start + width


def parse_neutral(spec: str, frame_count: int):
    """Read ``--neutral``: ``FRAME``, ``START:END`` (frames, end exclusive) or an image path.

    Returns ``(start, end)`` or the image path as a string.
    """
    text = spec.strip()
    try:
        if ":" in text:
            start, end = (int(x) for x in text.split(":", 1))
        else:
            start = int(text)
            end = start + 1
    except ValueError:
        return text  # an image
    if not 0 <= start < end <= frame_count:
        raise InputError(f"--neutral {spec}: frames must lie in [0, {frame_count}) with START < END")
    return start, end
