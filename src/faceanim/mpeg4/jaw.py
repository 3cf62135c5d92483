"""How a player realises ``open_jaw``: the jaw turns about its hinge until the chin has dropped by the FAP.

The encoder and the decoder share this model. The decoder swings the chin and the points the jaw
carries (lower lip, chin contour); the encoder measures ``thrust_jaw`` and the carried points' own
FAPs after taking the same swing out, so a stream encoded from a face and decoded onto it gives the
face back instead of swinging the jaw back twice.
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
    them, 2 MNS0 above the chin and 1.2 MW0 behind it.
    """
    chin = np.asarray(points["2.1"], dtype=np.float64)
    hinge_y = points["9.15"][1] if "9.15" in points else chin[1] + 2 * fapu.mns0
    corners = [points[n][2] for n in ("2.13", "2.14") if n in points]
    hinge_z = np.mean(corners) if corners else chin[2] - 1.2 * fapu.mw0
    return np.array([chin[0], hinge_y, hinge_z])


def jaw_swing(hinge: np.ndarray, chin: np.ndarray, drop: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """For chin drops ``drop (T,)`` (down positive, model units), a function from a point ``(3,)`` on
    the jaw to its displacements ``(T, 3)``: a turn about the hinge's x axis, solved so the chin's
    vertical drop is exactly ``drop``."""
    arm = np.asarray(chin, dtype=np.float64) - hinge
    # The chin falls by a (1 - cos t) + b sin t = a + R sin(t + phi) after turning by t; solve for t.
    a, b = arm[1], arm[2]
    radius, phi = np.hypot(a, b), np.arctan2(-a, b)
    drop = np.asarray(drop, dtype=np.float64)
    theta = np.arcsin(np.clip((drop - a) / radius, -1.0, 1.0)) - phi
    theta[drop == 0] = 0.0  # exactly at rest, not a rounding error away from it
    c, s = np.cos(theta), np.sin(theta)

    def swing(point: np.ndarray) -> np.ndarray:
        r = np.asarray(point, dtype=np.float64) - hinge
        y = r[1] * c - r[2] * s
        z = r[1] * s + r[2] * c
        return np.stack([np.zeros_like(theta), y - r[1], z - r[2]], axis=1)

    return swing
