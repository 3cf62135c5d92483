"""How a player realises ``open_jaw``: the jaw turns about its hinge until the chin has dropped by the FAP.

The encoder and the decoder share this model. The decoder swings the chin and the points the jaw
carries (lower lip, chin contour); the encoder measures ``thrust_jaw`` and the carried points' own
FAPs after taking the same swing out, so a stream encoded from a face and decoded onto it gives the
face back.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

from .fapu import Fapu

__all__ = ["JAW_CARRIED", "jaw_hinge", "jaw_swing"]

# Points on the lower lip and chin, which the jaw carries: a player applies open_jaw to them first,
# so their own FAPs are measured after the jaw's swing.
JAW_CARRIED = frozenset({"2.3", "2.8", "2.9", "2.10", "8.2", "8.7", "8.8"})


def jaw_hinge(points: Mapping[str, np.ndarray], fapu: Fapu) -> np.ndarray:
    """The hinge ``(3,)`` for a face whose feature points are ``points`` (name -> position; needs 2.1).

    Level with the bottom of the nose (9.15) and as far back as the jaw corners (2.13/2.14); without
    them, or where they are not behind the chin (a mesh placed oddly), 2 MNS0 above the chin and
    1.2 MW0 behind it.
    """
    chin = np.asarray(points["2.1"], dtype=np.float64)
    hinge_y = points["9.15"][1] if "9.15" in points else chin[1] + 2 * fapu.mns0
    corners = [points[n][2] for n in ("2.13", "2.14") if n in points]
    hinge_z = np.mean(corners) if corners and np.mean(corners) < chin[2] else chin[2] - 1.2 * fapu.mw0
    return np.array([chin[0], hinge_y, hinge_z])


def jaw_swing(hinge: np.ndarray, chin: np.ndarray, drop: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """For chin drops ``drop (T,)`` (down positive, model units), a function from a point ``(3,)`` on
    the jaw to its displacements ``(T, 3)``.

    The jaw turns about the hinge's x axis, to first order: a turn by ``t`` moves a point ``p`` by
    ``t * (0, -r_z, r_y)`` with ``r = p - hinge``, and ``t`` is chosen so the chin drops by exactly
    ``drop``. An exact rotation cannot do that: about a hinge this close behind the chin, the drop it
    can reach tops out (at 1.4 cm on MediaPipe's face), and a wide-open jaw would swing the chin
    straight back instead. The first-order turn always meets the FAP's drop, and is linear in it.
    """
    arm_z = float(np.asarray(chin, dtype=np.float64)[2] - hinge[2])
    if arm_z <= 0:
        raise ValueError(f"the jaw's hinge must lie behind the chin, got {arm_z:g} in front")
    turn = np.asarray(drop, dtype=np.float64) / arm_z

    def swing(point: np.ndarray) -> np.ndarray:
        r = np.asarray(point, dtype=np.float64) - hinge
        return turn[:, None] * np.array([0.0, -r[2], r[1]])

    return swing
