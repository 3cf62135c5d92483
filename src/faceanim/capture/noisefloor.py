"""Motion under the tracker's noise floor is not shown: each point's small displacements shrunk to nothing.

What the tracker reads of a face that does not move is not still. On the round trip's ICT renders
(``benchmarks/roundtrip_ict.py``, tuning seed 3, after every other correction of the capture) the points
3 cm and more from the eyes moved 0.04-0.06 cm RMS through a blink that moves them 0.003 at most, and
the skin between them carried that onto the target: on the blink's frames about a third of the whole
face's error lay on skin far from the eyes. It is not jitter a filter in time takes out but a bias
that comes and goes with the expression; its size is about a millimetre whatever the expression, while
what an expression moves is several.

So a point's displacement ``d`` (head frame) is shrunk by the non-negative garrote,
``d * max(0, 1 - tau^2 / |d|^2)``, with ``tau`` = :data:`NOISE_FLOOR` x the face's ES0 (about 1 mm):
nothing under ``tau``, continuous above it, and a move of 3 ``tau`` keeps 89% of its size, 5 ``tau`` 96%.
It is the capture's last drive, after the blink's coupling and the scores' drives, on MediaPipe's face
mesh but the lips (their two contours and the red between them, :data:`~faceanim.landmarks.LIP_OUTER`,
``LIP_INNER``, ``LIP_BETWEEN``): lips speak in millimetres (on the shared clip speech_man half the lip
contours' point-frames move less than ``tau``, and the floor took 12% of their RMS motion). The irises
are left as tracked too: a millimetre's shift of an iris is five degrees of gaze.

Chosen on the round trip's tuning seeds 3, 4, 6, 7, 8, 20 (mean of their medians, motion route; the
reporting pairs are scored in ``benchmarks/results/roundtrip_pairs.md``). Without a floor: all segments
0.513, blink 0.575, brows 0.525, smile 0.533, jawOpen 0.429. The garrote on every face point at tau =
0.06 / 0.08 / 0.1 / 0.12 / 0.14 cm gave 0.487 / 0.483 / 0.482 / 0.482 / 0.485 (these faces' ES0 is 6.3-7.0
cm as tracked, so 0.1 cm is about 0.015 ES0); with the lips' contours left as tracked, at 0.012 / 0.015 /
0.018 ES0, 0.486 / 0.484 / 0.484; with the whole lips left (taken), at 0.015 ES0, 0.486: blink 0.472,
brows 0.499, smile 0.526, jawOpen 0.427, every seed better. A gentler shrink, ``d |d|^2 / (|d|^2 +
tau^2)``, reached 0.485 at tau = 0.1-0.14 cm on every point; subtracting tau from the length (soft
thresholding) 0.490 at best, since it takes tau off every large move too. What the floor costs real
motion: put on A's exact motion (no tracker; ``roundtrip_ict.exact_run``), it takes the same seeds from
0.341 to 0.363 (the lips' contours left; blink 0.361 -> 0.390, brows 0.374 -> 0.402: the skin beside a
lid or above a brow that truly moves under a millimetre stays still).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..landmarks import LIP_BETWEEN, LIP_INNER, LIP_OUTER

__all__ = ["NoiseFloor", "NOISE_FLOOR", "garrote"]

#: Of the face's ES0: a point's displacement under this is taken for the tracker's, not the face's.
NOISE_FLOOR = 0.015
_FACE_MESH = 468  # MediaPipe's face mesh; the irises after it move with the eyeballs
_FLOORED = np.setdiff1d(np.arange(_FACE_MESH), LIP_OUTER + LIP_INNER + LIP_BETWEEN)  # the points it applies to


def garrote(displacements, tau: float) -> np.ndarray:
    """A new float64 array: ``displacements (..., 3)`` each shrunk by the non-negative garrote at ``tau``
    (a length in their unit), ``d * max(0, 1 - tau^2 / |d|^2)``; a vector with a NaN stays NaN.

    >>> garrote(np.array([[0.05, 0.0, 0.0], [0.0, 0.3, 0.4]]), 0.1)
    array([[0.   , 0.   , 0.   ],
           [0.   , 0.288, 0.384]])
    """
    tau = _length(tau)
    d = np.asarray(displacements, dtype=np.float64)
    squared = (d * d).sum(axis=-1, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        kept = np.where(squared > tau * tau, 1.0 - tau * tau / squared, 0.0)
    return np.where(np.isnan(squared), np.nan, d * kept)


@dataclass(frozen=True)
class NoiseFloor:
    """The capture's drive that drops motion under the noise floor (see the module's text).

    Parameters
    ----------
    tau : float
        In the motion's unit (cm for a tracked video): :data:`NOISE_FLOOR` x the face's ES0 from
        :meth:`of_face`.
    """

    tau: float

    def __post_init__(self):
        object.__setattr__(self, "tau", _length(self.tau))

    @classmethod
    def of_face(cls, neutral, fapu) -> NoiseFloor | None:
        """For a face at rest ``neutral (L, 3)`` with its FAPU: the floor at :data:`NOISE_FLOOR` of its
        ES0; None for a layout without MediaPipe's face mesh (fewer than 468 points)."""
        if len(neutral) < _FACE_MESH:
            return None
        return cls(NOISE_FLOOR * float(fapu.es0))

    def apply(self, displacements, start: int) -> np.ndarray:
        """``displacements (t, L, 3)`` (head frame) changed in place, the face mesh's points but the lips'
        shrunk; returned. Each frame and point on its own, so a capture read a run of frames at a time
        gives the same. ``start`` is unused; it is there so the capture applies this like its other drives."""
        displacements[:, _FLOORED] = garrote(displacements[:, _FLOORED], self.tau)
        return displacements


def _length(tau) -> float:
    """``tau`` as a float, or a ValueError naming it unless it is a finite length >= 0."""
    try:
        value = float(tau)
    except (TypeError, ValueError):
        raise TypeError(f"tau must be a number (a length), got {type(tau).__name__}") from None
    if not (np.isfinite(value) and value >= 0):
        raise ValueError(f"tau must be a finite length >= 0, got {tau}")
    return value
