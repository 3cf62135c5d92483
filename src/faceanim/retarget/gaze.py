"""The eyeballs' turns from a FAP stream's gaze (FAPs 23-26), as rotations in the model's axes."""

from __future__ import annotations

import numpy as np

from ..mpeg4 import ANGLE_UNIT, fap_table
from ..mpeg4.fapstream import FapStream, held
from ..parts import FaceParts

__all__ = ["eye_rotations", "GAZE_LIMITS"]

GAZE_LIMITS = (0.6, 0.45)  # radians of yaw and pitch: about as far as eyes turn (35 and 25 degrees)


def eye_rotations(stream: FapStream, parts: FaceParts) -> np.ndarray:
    """``(T, 2, 3, 3)`` the left and right eyeballs' rotations (model axes) from FAPs 23-26 (a FAP
    absent from a frame keeps its last value): yaw about the face's +y (positive towards its left),
    then pitch about +x (positive down), each clipped to :data:`GAZE_LIMITS`."""
    table = fap_table()
    values = held(stream)
    out = np.zeros((len(stream), 2, 3, 3))
    for k, side in enumerate("lr"):
        yaw = np.clip(values[:, table.number(f"yaw_{side}_eyeball") - 1] * ANGLE_UNIT, -GAZE_LIMITS[0], GAZE_LIMITS[0])
        pitch = np.clip(values[:, table.number(f"pitch_{side}_eyeball") - 1] * ANGLE_UNIT,
                        -GAZE_LIMITS[1], GAZE_LIMITS[1])
        cy, sy, cp, sp = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch)
        Ry = np.zeros((len(stream), 3, 3))
        Ry[:, 0, 0], Ry[:, 0, 2], Ry[:, 1, 1], Ry[:, 2, 0], Ry[:, 2, 2] = cy, sy, 1.0, -sy, cy
        Rx = np.zeros((len(stream), 3, 3))
        Rx[:, 0, 0], Rx[:, 1, 1], Rx[:, 1, 2], Rx[:, 2, 1], Rx[:, 2, 2] = 1.0, cp, -sp, sp, cp
        out[:, k] = parts.axes.T @ (Ry @ Rx) @ parts.axes
    return out
