"""Choosing the neutral face that displacements are measured from."""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..framestore import FrameStore

__all__ = ["relaxed_window", "parse_neutral"]

_MEDIAN_FRAMES = 2000  # frames the median face is taken over, spread across the video
_BLOCK = 512  # frames scored at once


def relaxed_window(points, usable, fps: float, *, seconds: float = 0.5, mouth=None) -> tuple[int, int]:
    """``(start, end)`` frames (end exclusive) of the most relaxed stretch of a performance.

    Relaxed means: close to the performance's median face (a face spends most of its time near
    rest), still (slow), and, when ``mouth (T,)`` gives the inner-lip gap, with the mouth closed.
    ``points (T, K, 3)`` in the head frame (an array, or a :class:`~faceanim.framestore.FrameStore`:
    it is read a block at a time); ``usable (T,)`` frames with data.
    """
    p = points if isinstance(points, FrameStore) else np.asarray(points, dtype=np.float64)
    usable = np.asarray(usable, dtype=bool)
    if not usable.any():
        raise ValueError("no usable frame to choose a neutral from")
    seen = np.flatnonzero(usable)
    # The median face of at most _MEDIAN_FRAMES frames spread over the performance: as good a guide
    # to rest, and what it holds does not grow with the video.
    median = np.median(p[seen[np.linspace(0, len(seen) - 1, min(len(seen), _MEDIAN_FRAMES)).astype(int)]], axis=0)
    spread, speed = np.empty(len(p)), np.zeros(len(p))
    for start in range(0, len(p), _BLOCK):
        block = p[start:start + _BLOCK]
        spread[start:start + len(block)] = np.sqrt(((block - median) ** 2).sum(-1).mean(-1))
        before = p[max(start - 1, 0):start + len(block) - 1]
        steps = np.sqrt(((block[len(block) - len(before):] - before) ** 2).sum(-1).mean(-1)) * fps
        speed[start + len(block) - len(steps):start + len(block)] = steps
    # A frame after one without a face has no speed (NaN): it is scored by its spread alone, so that a
    # face seen in single frames between gaps is still chosen, never a window without a face.
    score = spread + 0.1 * np.nan_to_num(speed, nan=0.0) / max(fps, 1.0)
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


def parse_neutral(spec: str, frame_count: int | None = None):
    """Read ``--neutral``: ``FRAME``, ``START:END`` (frames, end exclusive) or an image path.
    ``frame_count``: the video's length, or None where it is not known yet (a video not yet
    tracked: the window is checked against it once it is).

    Returns ``(start, end)`` or the image path as a string.
    """
    text = spec.strip()
    if not text:  # would be read as the path "." and the folder's images taken for the face at rest
        raise InputError("--neutral is empty; give FRAME, START:END or an image of the face at rest")
    try:
        if ":" in text:
            start, end = (int(x) for x in text.split(":", 1))
        else:
            start = int(text)
            end = start + 1
    except ValueError:
        return text  # an image
    if frame_count is None and not 0 <= start < end:
        raise InputError(f"--neutral {spec}: frames count from 0, with START < END")
    if frame_count is not None and not 0 <= start < end <= frame_count:
        raise InputError(f"--neutral {spec}: frames must lie in [0, {frame_count}) with START < END")
    return start, end
