"""Motion under the tracker's noise floor is not shown: each point's small displacements shrunk to nothing.

What the tracker reads of a face that does not move is not still. On the round trip's ICT renders
(``benchmarks/roundtrip_ict.py``, tuning seed 3, after every other correction of the capture) the points
3 cm and more from the eyes moved 0.04-0.06 cm RMS through a blink that moves them 0.003 at most, and
the skin between them carried that onto the target: on the blink's frames about a third of the whole
face's error lay on skin far from the eyes. It is not jitter a filter in time takes out but a bias
that comes and goes with the expression; its size is about a millimetre whatever the expression, while
what an expression moves is several.

So a point's displacement ``d`` (head frame) is shrunk by the non-negative garrote,
``d * max(0, 1 - tau^2 / |d|^2)``, with ``tau`` = :data:`NOISE_FLOOR` x the face's ES0: nothing under
``tau``, continuous above it, and a move of 3 ``tau`` keeps 89% of its size, 5 ``tau`` 96%. Applied
last, after the blink's coupling and the scores' drives, to MediaPipe's face mesh but the lips: the lips
speak in millimetres (on the shared clip speech_man half their point-frames move less than ``tau``, and
the floor took 12% of their RMS motion), and the irises are left as tracked too (a millimetre's shift of
an iris is five degrees of gaze).

Chosen on the round trip's tuning seeds 3, 4, 6, 7, 8, 20 (mean of their medians, motion route; the
reporting pairs are scored in ``benchmarks/results/roundtrip_pairs.md``). Without a floor: all segments
0.513, blink 0.575, brows 0.525, smile 0.533, jawOpen 0.429. The garrote on every face point at tau =
0.06 / 0.08 / 0.1 / 0.12 / 0.14 cm gave 0.487 / 0.483 / 0.482 / 0.482 / 0.485 (these faces' ES0 is 6.3-7.0
cm as tracked, so 0.1 cm is about 0.015 ES0); with the lips left as tracked, at 0.012 / 0.015 / 0.018
ES0, 0.486 / 0.484 / 0.484. Taken: 0.015 ES0 without the lips, all 0.484, blink 0.466, brows 0.495, smile
0.527, jawOpen 0.427, every seed better (seed 4 0.506 -> 0.459, seed 6 0.574 -> 0.557). A gentler shrink,
``d |d|^2 / (|d|^2 + tau^2)``, reached 0.485 at tau = 0.1-0.14 cm; subtracting tau from the length (soft
thresholding) 0.490 at best, since it takes tau off every large move too. What the floor costs real
motion: put on A's exact motion (no tracker; ``roundtrip_ict.exact_run``), it takes the same seeds from
0.341 to 0.363 (blink 0.361 -> 0.390, brows 0.374 -> 0.402: the skin beside a lid or above a brow that
truly moves under a millimetre stays still).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..landmarks import LIP_INNER, LIP_OUTER

__all__ = ["NoiseFloor", "NOISE_FLOOR", "garrote"]

#: Of the face's ES0: a point's displacement under this is taken for the tracker's, not the face's.
NOISE_FLOOR = 0.015
_FACE_MESH = 468  # MediaPipe's face mesh; the irises after it move with the eyeballs
_FLOORED = np.setdiff1d(np.arange(_FACE_MESH), LIP_OUTER + LIP_INNER)  # the points the floor applies to


def garrote(displacements: np.ndarray, floor: float) -> np.ndarray:
    """``displacements (..., 3)`` each shrunk by the non-negative garrote at ``floor`` (same unit):
    ``d * max(0, 1 - floor^2 / |d|^2)``; NaN stays NaN.

    >>> garrote(np.array([[0.05, 0.0, 0.0], [0.0, 0.3, 0.4]]), 0.1)
    array([[0.   , 0.   , 0.   ],
           [0.   , 0.288, 0.384]])
    """
    d = np.asarray(displacements, dtype=np.float64)
    squared = (d * d).sum(axis=-1, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        kept = np.where(squared > floor * floor, 1.0 - floor * floor / squared, 0.0)
    return np.where(np.isnan(squared), np.nan, d * kept)


@dataclass(frozen=True)
class NoiseFloor:
    """The capture's drive that drops motion under the noise floor (see the module's text).

    Parameters
    ----------
    floor : float
        ``tau`` in the motion's unit (cm for a tracked video): :data:`NOISE_FLOOR` x the face's ES0.
    """

    floor: float

    def __post_init__(self):
        if not (np.isfinite(self.floor) and self.floor >= 0):
            raise ValueError(f"floor must be a finite length >= 0, got {self.floor}")

    @classmethod
    def of_face(cls, neutral, fapu) -> NoiseFloor | None:
        """For a face with its FAPU: the floor at :data:`NOISE_FLOOR` of its ES0; None for a layout
        without MediaPipe's face mesh (fewer than 468 points) or with the floor set to 0."""
        if len(neutral) < _FACE_MESH or NOISE_FLOOR <= 0:
            return None
        return cls(NOISE_FLOOR * float(fapu.es0))

    def apply(self, displacements, start: int) -> np.ndarray:
        """``displacements (t, L, 3)`` (head frame) changed in place, the face mesh's points but the lips'
        shrunk; returned. ``start`` is unused; it is there so the capture applies this like its other
        drives."""
        displacements[:, _FLOORED] = garrote(displacements[:, _FLOORED], self.floor)
        return displacements
