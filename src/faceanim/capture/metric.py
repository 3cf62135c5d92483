"""Head pose and metric face geometry from MediaPipe's normalised face-mesh landmarks.

A re-implementation of MediaPipe's face-geometry pipeline (``geometry_pipeline.cc``, Apache-2.0):
landmarks in normalised image coordinates are placed on the near plane of a perspective camera,
their depth is recovered in two passes of weighted Procrustes against MediaPipe's canonical metric
face, and the final Procrustes gives the head pose. The canonical face and the landmark weights come
with faceanim (``data/mediapipe_canonical_face.json``, from MediaPipe's metadata, Apache-2.0).

Coordinates: metric landmarks are in centimetres in the canonical face's frame (+x the subject's
left, +y up, +z towards the camera), the same axes as MPEG-4's. The pose maps that frame to camera
space: ``camera = pose @ [p, 1]``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import cache
from importlib import resources

import numpy as np

from ..geometry.align import batch_procrustes
from ..validation import as_array

__all__ = ["Camera", "CanonicalFace", "canonical_face", "metric_geometry", "metric_geometry_frames"]


@dataclass(frozen=True)
class Camera:
    """A perspective camera: vertical field of view (degrees) and near plane, as MediaPipe's default."""

    vertical_fov: float = 63.0
    near: float = 1.0


@dataclass(frozen=True, eq=False)
class CanonicalFace:
    """MediaPipe's canonical face: ``vertices (468, 3)`` cm, ``triangles (898, 3)``, ``uv (468, 2)``,
    and the Procrustes ``weights (468,)`` (zero for landmarks that move with expression). Read-only:
    :func:`canonical_face` shares one with every caller."""

    vertices: np.ndarray
    triangles: np.ndarray
    uv: np.ndarray
    weights: np.ndarray

    def __post_init__(self):
        for name in ("vertices", "triangles", "uv", "weights"):
            value = getattr(self, name)
            object.__setattr__(self, name, as_array(value, name, dtype=value.dtype, frozen=True))


@cache
def canonical_face() -> CanonicalFace:
    """The canonical face, read once from package data."""
    with resources.files(__package__).joinpath("data", "mediapipe_canonical_face.json").open() as handle:
        data = json.load(handle)
    vertices = np.array(data["vertices"], dtype=np.float64)
    weights = np.zeros(len(vertices))
    weights[data["procrustes_landmarks"]] = data["procrustes_weights"]
    return CanonicalFace(vertices, np.array(data["triangles"], dtype=np.int64), np.array(data["uv"]), weights)


def metric_geometry(landmarks, width: int, height: int, camera: Camera | None = None):
    """Metric landmarks and head pose from one frame's normalised landmarks.

    Parameters
    ----------
    landmarks : (L, 3) float64, L >= 468
        MediaPipe's normalised landmarks (x, y in [0, 1] of the image width and height from the top
        left; z relative, in units of the width). The pose is fitted on the first 468 (the iris
        points have no canonical counterpart); all L are converted.
    width, height : int
        Image size in pixels.

    Returns
    -------
    metric : (L, 3) float64
        The landmarks in the canonical face frame, centimetres (pose removed).
    pose : (4, 4) float64
        Canonical face frame to camera space (a similarity: scale, rotation, translation).
    """
    points = as_array(landmarks, "landmarks", shape=("L", 3))
    metric, pose = metric_geometry_frames(points[None], width, height, camera)
    return metric[0], pose[0]


def metric_geometry_frames(landmarks, width: int, height: int, camera: Camera | None = None):
    """:func:`metric_geometry` for ``(T, L, 3)`` frames at once: ``(T, L, 3)`` and ``(T, 4, 4)``."""
    camera = camera or Camera()
    face = canonical_face()
    points = np.array(landmarks, dtype=np.float64)
    if points.ndim != 3 or points.shape[1] < 468 or points.shape[2] != 3:
        raise ValueError(f"landmarks must have shape (T, L >= 468, 3), got {points.shape}")
    if not np.isfinite(points).all():
        raise ValueError("landmarks must be finite")
    if width <= 0 or height <= 0:
        raise ValueError(f"image size must be positive, got {width}x{height}")
    height_near = 2 * camera.near * np.tan(0.5 * np.radians(camera.vertical_fov))
    width_near = width * height_near / height
    left, bottom = -0.5 * width_near, -0.5 * height_near

    # Image coordinates (origin top left, z in width units) onto the near plane.
    points[..., 1] = 1.0 - points[..., 1]
    points *= [width_near, height_near, width_near]
    points += [left, bottom, 0.0]
    depth_offset = points[:, :468, 2].mean(axis=1)[:, None]

    def unproject(scale):
        p = points.copy()
        p[..., 2] = (p[..., 2] - depth_offset + camera.near) / scale[:, None]
        p[..., :2] *= p[..., 2:3] / camera.near
        p[..., 2] *= -1  # screen space is left-handed, metric space right-handed
        return p

    def scale_of(p):
        return np.linalg.norm(batch_procrustes(face.vertices, p[:, :468], face.weights)[:, :3, 0], axis=1)

    first = scale_of(points * [1, 1, -1])
    second = scale_of(unproject(first))
    metric = unproject(first * second)
    pose = batch_procrustes(face.vertices, metric[:, :468], face.weights)
    inverse = np.linalg.inv(pose)
    metric = np.einsum("tij,tlj->tli", inverse[:, :3, :3], metric) + inverse[:, None, :3, 3]
    return metric, pose
