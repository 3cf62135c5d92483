"""The generic face: MediaPipe's canonical face mesh as a `Target`, at rest or at a tracked face's points.

This is faceanim's "simple generic face" (the role CANDIDE plays in the older literature): 468
vertices in centimetres, opened at the lid margins and the inner lips so the eyes and mouth can
move apart, with every MediaPipe point and every MPEG-4 feature point MediaPipe observes as a
control point. The same mesh at a tracked person's neutral points is the face the AU fitter makes
its basis on, so the AUs read from a video are the ones the muscles make on that person.
"""

from __future__ import annotations

import numpy as np

from .capture.avatar import opened_triangles
from .capture.metric import canonical_face
from .geometry.mesh import Mesh
from .landmarks import landmark_names
from .target import Target
from .validation import as_array

__all__ = ["generic_target", "landmark_target"]


def landmark_target(points) -> Target:
    """The canonical mesh at ``points (468, 3)`` (head frame, MPEG-4 axes), with its control points
    named as the capture names them (:func:`~faceanim.landmarks.landmark_names`)."""
    points = as_array(points, "points", shape=(468, 3))
    mesh = Mesh(points, opened_triangles(canonical_face().triangles))
    names = landmark_names(468)
    return Target.from_points(mesh, {name: i for i, name in enumerate(names)})


def generic_target() -> Target:
    """The canonical face at rest (centimetres, +x the face's left, +y up, +z out of the face)."""
    return landmark_target(np.asarray(canonical_face().vertices, dtype=np.float64))
