"""The face's own frame and the levels parts are told apart by (FAPU-relative, unit-free)."""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..mpeg4.jaw import jaw_hinge
from ..target import Target

__all__ = ["face_axes"]

_FRAME_POINTS = ("3.7", "3.8", "3.11", "3.12", "8.3", "8.4", "2.1")


def face_axes(points: dict) -> np.ndarray:
    """Rows +x (the face's left), +y (up), +z (out of the face) from feature-point positions."""
    missing = [n for n in _FRAME_POINTS if n not in points]
    if missing:
        raise InputError(f"the target lacks feature point{'s' if len(missing) > 1 else ''} {', '.join(missing)}, "
                         "which place its parts")
    x = (points["3.7"] + points["3.11"]) - (points["3.8"] + points["3.12"])
    y = 0.25 * (points["3.7"] + points["3.8"] + points["3.11"] + points["3.12"]) - 0.5 * (points["8.3"] + points["8.4"])
    size = np.linalg.norm(y)
    x_length = np.linalg.norm(x)
    if not np.isfinite(size) or x_length <= 1e-6 * max(size, 1e-300):
        raise InputError("the target's eyes have no width (feature points 3.7/3.11 and 3.8/3.12 coincide); "
                         "its parts cannot be placed")
    x /= x_length
    y -= (y @ x) * x
    if np.linalg.norm(y) <= 1e-6 * x_length:
        raise InputError("the target's mouth (8.3/8.4) lies level with its eyes; its parts cannot be placed")
    y /= np.linalg.norm(y)
    return np.stack([x, y, np.cross(x, y)])


def _smoothstep(s) -> np.ndarray:
    """0 below 0, 1 above 1, and the cubic with level ends between."""
    s = np.clip(s, 0.0, 1.0)
    return s * s * (3 - 2 * s)


class _Frame:
    """Face-frame coordinates and the levels parts are told apart by (FAPU-relative)."""

    def __init__(self, axes: np.ndarray, at: dict, target: Target):
        self.axes = axes
        self.hinge = _turning_centre(at, target, axes)
        self.origin = at["2.1"]
        self.local_points = {n: self.local(p[None])[0] for n, p in at.items()}
        p = self.local_points
        self.chin = p["2.1"]
        self.mouth = 0.5 * (p["8.3"] + p["8.4"])
        self.mouth_width = float(np.linalg.norm(p["8.3"] - p["8.4"]))
        self.eye_width = 0.5 * float(np.linalg.norm(p["3.7"] - p["3.11"]) + np.linalg.norm(p["3.8"] - p["3.12"]))
        self.hinge_local = self.local(self.hinge[None])[0]
        # Where upper and lower teeth meet, y = bite[0] + bite[1] * z: the lip line until the teeth say
        # otherwise (the bite rises towards the back of the mouth).
        self.bite = (float(self.mouth[1]), 0.0)
        self.eyes = {"eye_left": 0.5 * (p["3.7"] + p["3.11"]), "eye_right": 0.5 * (p["3.8"] + p["3.12"])}

    def move_centre(self, local: np.ndarray) -> None:
        """Put the jaw's turning centre at ``local`` (face frame)."""
        self.hinge_local = np.asarray(local, dtype=np.float64)
        self.hinge = self.hinge_local @ self.axes + self.origin

    def local(self, points: np.ndarray) -> np.ndarray:
        return (np.asarray(points) - self.origin) @ self.axes.T

    def below_bite(self, points: np.ndarray) -> np.ndarray:
        """1 below the bite, 0 above, a smooth step of a tenth of the mouth's width between."""
        local = self.local(points)
        y = local[:, 1] - self.bite[1] * local[:, 2]
        band = 0.1 * self.mouth_width
        return _smoothstep((self.bite[0] + 0.5 * band - y) / band)

    def in_mouth(self, centre: np.ndarray) -> bool:
        """Whether a point (face frame) lies behind the lips, between the chin and the nose."""
        top = self.local_points["9.15"][1] if "9.15" in self.local_points else self.mouth[1] + 0.4 * self.mouth_width
        return (abs(centre[0] - self.mouth[0]) < 0.8 * self.mouth_width and self.chin[1] - 0.1 * self.mouth_width
                < centre[1] < top and centre[2] < self.mouth[2] + 0.1 * self.mouth_width)


def _turning_centre(at: dict, target: Target, axes: np.ndarray) -> np.ndarray:
    """Where the jaw turns about as it opens: not the condyles (the MPEG-4 hinge of
    :func:`~faceanim.mpeg4.jaw.jaw_hinge`, level with the nose's base) but below them, level with the
    jaw's corners (2.13/2.14; halfway to the chin without them). The condyles slide forward as the jaw
    opens, so the opening turns about a centre low on the ramus; about the condyles, the jaw's lower
    border would swing back by centimetres where it hardly moves. Where the lower teeth are known,
    :func:`_centre_behind_the_teeth` moves it behind them."""
    hinge = jaw_hinge(at, target.fapu)
    corners = [at[n] for n in ("2.13", "2.14") if n in at]
    low = np.mean(corners, axis=0) @ axes[1] if corners else (hinge @ axes[1] + at["2.1"] @ axes[1]) / 2
    return hinge + (low - hinge @ axes[1]) * axes[1]
