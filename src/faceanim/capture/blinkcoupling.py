"""What the tracker moves with a blink that the face does not: learned, and taken out.

The Face Landmarker's mesh is held to a learned face shape, so when an eye shuts its other points move
too: on the round trip's ICT renders (``benchmarks/roundtrip_ict.py``) the chin went about a
millimetre down and back and the cheeks up with every blink, the lower lid rose with the upper and
the upper lid stopped short, and half of the blink's error lay on skin the blink does not move. The
move is a bias of the tracker's, the same blink after blink (over seed 3's still landmarks 0.004 cm
of 0.065 is faster than a 7-frame mean), so it is learned once and taken out.

Each point moves, on top of what the face does, by ``ES0 x (shut_left x F_left + shut_right x
F_right)``. How far an eye is shut is read from its tracked lids: its closure (1 - the middle lid
points' opening over their opening at rest) counted from :data:`OPEN_BELOW` up, 0 to 1. ``F`` is a
vector per point and eye, in ES0, fitted by least squares to the tracker's error on ICT identities
that wink and blink (never the round trip's tuning or reporting pairs; ``data/blink_coupling.json``,
made by ``benchmarks/blink_bias.py``, which says how), on the eyes that shut and that the tracker saw
at least half shut: an eye it hardly saw shut has a large error at a small closure and pulled the fit
up. On real faces, with no truth, real blinks move the tracked points the way the table says (the
benchmark's test against random open stretches: a gain of 1.5 round the eyes and 1.5 far from them,
where the null stays within 0.2 and 1.0), so the coupling is the tracker's, not the renders'. The
closure is read from the lids as they are tracked, after the other corrections; a frame whose lids are
not seen (NaN) is left as it is.
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass
from importlib import resources

import numpy as np

from ..landmarks import EYE_LIDS
from ..validation import as_array

__all__ = ["BlinkCoupling", "MIDDLE_LIDS", "OPEN_BELOW", "closure", "coupling_field", "shutting"]

#: MediaPipe's middle upper and lower lid points, left eye then right: an eye's closure is read there.
MIDDLE_LIDS = ((386, 374), (159, 145))
_FACE_MESH = 468  # the field covers MediaPipe's face mesh; the irises move with the eyeballs
#: A closure under this counts as open. The tracked lids jitter at rest (closure 0.02-0.1 at the 80th
#: percentile on the shared videos unfiltered), and the jitter taken only when it closes would move the
#: face on average: d0's neutral frames then missed the rest by 0.006 cm (tests/test_animate_cli.py).
OPEN_BELOW = 0.1
_LID_PAIRS = tuple(pair for upper, lower in EYE_LIDS.values() for pair in zip(upper, lower, strict=True))


@functools.cache
def coupling_field() -> np.ndarray:
    """``(2, 468, 3)`` ES0 per unit of the left and the right eye's closure, per point and axis (head
    frame), from ``data/blink_coupling.json``."""
    with resources.files(__package__).joinpath("data", "blink_coupling.json").open() as handle:
        return np.array(json.load(handle)["es0_per_closure"], dtype=np.float64)


def closure(displacements: np.ndarray, neutral: np.ndarray) -> np.ndarray:
    """``(t, 2)`` how far the left and the right eye are shut by the tracked lids, 0 to 1 (NaN where
    the lids are not seen), from ``displacements (t, L, 3)`` about ``neutral (L, 3)`` (head frame, +y
    up, MediaPipe's layout)."""
    shut = []
    for upper, lower in MIDDLE_LIDS:
        opening = neutral[upper, 1] - neutral[lower, 1]
        now = opening + displacements[:, upper, 1] - displacements[:, lower, 1]
        shut.append(np.clip(1.0 - now / opening, 0.0, 1.0))
    return np.stack(shut, axis=1)


def shutting(shut: np.ndarray) -> np.ndarray:
    """``shut`` (a :func:`closure`) as the table is driven by: 0 up to :data:`OPEN_BELOW`, then rising
    to 1 at a shut eye."""
    return np.clip((shut - OPEN_BELOW) / (1.0 - OPEN_BELOW), 0.0, 1.0)


@dataclass(frozen=True, eq=False)
class BlinkCoupling:
    """The coupling taken out of a video's displacements.

    Parameters
    ----------
    neutral : (L, 3) float64
        The face at rest (head frame, cm; MediaPipe's layout, L >= 468).
    field : (2, 468, 3) float64
        Each eye's move per unit closure, in ES0 (:func:`coupling_field`).
    es0 : float
        The face's ES0 (cm).
    """

    neutral: np.ndarray
    field: np.ndarray
    es0: float

    def __post_init__(self):
        object.__setattr__(self, "neutral", as_array(self.neutral, "neutral", shape=("L", 3), frozen=True))
        object.__setattr__(self, "field", as_array(self.field, "field", shape=(2, _FACE_MESH, 3), frozen=True))
        if len(self.neutral) < _FACE_MESH:
            raise ValueError(f"neutral holds {len(self.neutral)} points; the coupling needs MediaPipe's {_FACE_MESH}")
        if not self.es0 > 0:
            raise ValueError(f"es0 must be positive, got {self.es0}")

    @classmethod
    def of_face(cls, neutral, fapu) -> BlinkCoupling | None:
        """For a face at rest ``neutral (L, 3)`` with its FAPU, the packaged field; None for a layout
        without MediaPipe's face mesh (fewer than 468 points)."""
        if len(neutral) < _FACE_MESH:
            return None
        return cls(neutral, coupling_field(), float(fapu.es0))

    def apply(self, displacements, start: int) -> np.ndarray:
        """``displacements (t, L, 3)`` (head frame, cm) changed in place: each point less the move the
        eyes' closure couples to it; returned. ``start`` is unused (the closure is read from the frames
        themselves); it is there so the capture applies this like its other drives."""
        shut = np.nan_to_num(shutting(closure(displacements, self.neutral)), nan=0.0)
        move = self.es0 * np.einsum("tk,klc->tlc", shut, self.field)
        self._lids_held_where_they_meet(displacements, move)
        displacements[:, :_FACE_MESH] -= move
        return displacements

    def _lids_held_where_they_meet(self, displacements, move) -> None:
        """``move (t, 468, 3)`` changed in place: on each facing pair of lid points whose taking out would
        bring the lids past each other, its height taken back on both, in proportion, to where they
        meet (or to where the tracker had them, if it had them past each other already).

        The table can ask more of a lid than a shut eye can give: made before the eyes the tracker
        hardly saw shut were left out of its fit (tall eyes half shut by ICT's blink, read as 0.1-0.2
        of it), it had the lids pass each other by 0.2-0.6 of the eye's opening on the shared videos'
        fullest blinks. A target's lids are held short of meeting anyway (at :data:`faceanim.retarget.lids.SHUT`
        of its opening); the motion, its FAPs and its exports are held here, where the lids meet."""
        for upper, lower in _LID_PAIRS:
            top, bottom = self.neutral[upper, 1], self.neutral[lower, 1]
            allowed = np.maximum((top + displacements[:, upper, 1]) - (bottom + displacements[:, lower, 1]), 0.0)
            closing = move[:, upper, 1] - move[:, lower, 1]  # how much nearer the move brings the two
            over = closing > allowed
            share = np.where(over, allowed / np.where(over, closing, 1.0), 1.0)
            move[:, upper, 1] *= share
            move[:, lower, 1] *= share
