"""`FaceParts`: what each vertex of a target is (its role) and how it follows the jaw; the role names
and the control points that tell parts apart."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ROLES", "FaceParts", "INNER_LIP_POINTS"]

ROLES = ("skin", "upper_teeth", "lower_teeth", "eye_left", "eye_right", "lid_layer", "socket", "static")
_ROLE = {name: k for k, name in enumerate(ROLES)}
# Points on the eyeballs, not the skin (placement puts the irises on the eyeball where there is one).
_EYEBALL_POINTS = frozenset({"3.5", "3.6", *(f"mp{i}" for i in range(468, 478))})
# The lips' control points: MPEG-4's and MediaPipe's (inner rims as automatic placement names them).
_UPPER_LIP = ("2.2", "2.6", "2.7", "8.1", "8.5", "8.6",
              *(f"mp{i}" for i in (191, 80, 81, 82, 13, 312, 311, 310, 415, 0, 37, 39, 40, 267, 269, 270)))
_LOWER_LIP = ("2.3", "2.8", "2.9", "8.2", "8.7", "8.8",
              *(f"mp{i}" for i in (95, 88, 178, 87, 14, 317, 402, 318, 324, 17, 84, 181, 314, 405)))
# Control points on the lips' inner rims, where lips meet teeth.
INNER_LIP_POINTS = ("2.2", "2.3", "2.4", "2.5", "2.6", "2.7", "2.8", "2.9",
                    *(f"mp{i}" for i in (13, 14, 78, 308, 82, 87, 312, 317, 80, 88, 310, 318)))


@dataclass(frozen=True, eq=False)
class FaceParts:
    """What each vertex of a target is and how it follows the jaw.

    Attributes
    ----------
    role : (V,) int64
        Index into :data:`ROLES` for every vertex.
    jaw_weight : (V,) float64
        How much of the jaw's turn a vertex follows, in [0, 1]: 1 on the chin and the lower teeth,
        0 on the upper lip, the skull and the upper teeth.
    hinge : (3,) float64
        A point on the jaw's axis (model units).
    axes : (3, 3) float64
        Rows: the face's +x (its left, also the jaw's axis), +y (up) and +z (out of the face).
    eye_centres : (2, 3) float64
        Left and right eyeball centres.
    """

    role: np.ndarray
    jaw_weight: np.ndarray
    hinge: np.ndarray
    axes: np.ndarray
    eye_centres: np.ndarray

    def __post_init__(self):
        for name in ("role", "jaw_weight", "hinge", "axes", "eye_centres"):
            array = np.array(getattr(self, name))
            array.flags.writeable = False
            object.__setattr__(self, name, array)

    def mask(self, *roles: str) -> np.ndarray:
        """``(V,) bool``: the vertices with any of ``roles``."""
        unknown = [r for r in roles if r not in _ROLE]
        if unknown:
            raise ValueError(f"unknown role {unknown[0]!r}; roles are {', '.join(ROLES)}")
        return np.isin(self.role, [_ROLE[r] for r in roles])

    def counts(self) -> dict:
        """Vertices per role (roles with none left out)."""
        found = np.bincount(self.role, minlength=len(ROLES))
        return {name: int(n) for name, n in zip(ROLES, found, strict=True) if n}
