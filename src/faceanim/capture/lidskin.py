"""The upper lids' skin the tracker holds still while the lash line comes down.

As the upper lid shuts, the Face Landmarker brings its lash line down (0.69 cm of the 0.82 the face
moved there on the round trip's tuning seed 3) but holds the next ring of points above it, half way
from the lash line to the brow, where it is (0.00 cm; the face moved them 0.2), and the target's lid
skin between the two is stretched instead of carried down: on the target the lash line then came down
less than the tracked one (the interpolation takes part of its motion from the ring held still).

So each point of that ring comes down, on top of its tracked movement, by :data:`SHARE` of the
descent of the lash-line point below it, less :data:`STILL` (a rise of the lash line adds nothing). Only the height
changes. ``SHARE`` was chosen on the round trip's tuning seeds 3, 4, 6 and 20 (blink segment, mean of
the per-seed medians, 2026-11-24, with the lids carried as a share of the eye's opening,
:mod:`faceanim.retarget.lids`): 0.786 without, 0.757 at 0.35, 0.756 at 0.5, 0.765 at 0.7; the other
segments moved by 0.001 or less. Their truth is ICT-FaceKit's own blink, where this skin moves 0.2-0.4
of the lash line's descent, so the share may flatter the benchmark somewhat.
"""

from __future__ import annotations

import numpy as np

__all__ = ["follow_lid_skin", "SHARE", "STILL", "LASH_TO_SKIN"]

SHARE = 0.5
# cm: a lash line less than this below rest counts as still. The tracker's jitter there, taken only when it
# points down, would move the skin on average: on d0 unfiltered, its neutral frames' mean then missed
# the rest by 0.005 cm (tests/test_animate_cli.py).
STILL = 0.02
#: MediaPipe's upper lash-line points and the point of the ring above each (left eye, then right).
LASH_TO_SKIN = ((466, 467), (388, 260), (387, 259), (386, 257), (385, 258), (384, 286), (398, 414),
                (246, 247), (161, 30), (160, 29), (159, 27), (158, 28), (157, 56), (173, 190))
_LASH = np.array([lash for lash, _ in LASH_TO_SKIN])
_SKIN = np.array([skin for _, skin in LASH_TO_SKIN])


def follow_lid_skin(displacements: np.ndarray) -> np.ndarray:
    """``displacements (t, L, 3)`` (head frame, MediaPipe's layout, +y up), changed in place: the ring
    above each upper lash line brought down by :data:`SHARE` of the lash line's descent; returned.
    A layout without MediaPipe's face mesh (fewer than 468 points) is returned as it is."""
    if displacements.shape[1] < 468:
        return displacements
    descent = np.minimum(displacements[:, _LASH, 1] + STILL, 0.0)
    displacements[:, _SKIN, 1] += SHARE * np.nan_to_num(descent, nan=0.0)
    return displacements
