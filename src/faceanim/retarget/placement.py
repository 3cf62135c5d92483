"""Automatic placement of control points on any mesh: render it, find the face, cast the points back.

The mesh is rendered shaded (no texture needed) from the front, MediaPipe's face mesh runs on the
picture, and each of its 478 points is cast back onto the surface through the depth buffer and the
camera, then snapped to the nearest vertex. A first pass finds the face; a second, framed tightly on
it, places the points. A result that is not left-right consistent is refused.
"""

from __future__ import annotations

import numpy as np

from ..capture.landmarks import FEATURE_POINT_LANDMARK
from ..errors import InputError
from ..geometry.mesh import Mesh
from ..geometry.project import project_points
from ..geometry.topology import component_labels
from ..render.camera import front_camera
from ..target import Target, measure_fapu

__all__ = ["place_landmarks", "auto_target"]

_MIRROR_PAIRS = ((33, 263), (133, 362), (61, 291), (70, 300), (234, 454), (159, 386), (145, 374))


def _track_render(mesh, camera, renderer, tracker):
    image, depth = renderer.render(mesh, camera, depth=True)
    faces = tracker.all_faces(image)
    if not faces:
        return None
    face = max(faces, key=lambda f: np.prod(np.ptp(f[:, :2], axis=0)))
    pixels = face[:, :2] * [camera.width, camera.height]
    return pixels, depth


def _surface_points(pixels, depth, camera):
    """World points behind landmark pixels; points on the silhouette take the nearest surface seen."""
    H, W = depth.shape
    cols = np.clip(np.round(pixels[:, 0] - 0.5).astype(int), 0, W - 1)
    rows = np.clip(np.round(pixels[:, 1] - 0.5).astype(int), 0, H - 1)
    distance = depth[rows, cols]
    for radius in (1, 2, 4, 8):  # landmarks on the face's outline can fall just off the surface
        missing = ~np.isfinite(distance)
        if not missing.any():
            break
        for i in np.flatnonzero(missing):
            window = depth[max(rows[i] - radius, 0):rows[i] + radius + 1, max(cols[i] - radius, 0):cols[i] + radius + 1]
            distance[i] = window.min()
    if not np.isfinite(distance).all():
        raise InputError("automatic placement: some face points do not lie on the mesh")
    return camera.unproject(pixels, distance)


def place_landmarks(mesh: Mesh, *, size: int = 512, yaws=(0.0, -12.0, 12.0)) -> np.ndarray:
    """Vertex ids ``(478,)`` of MediaPipe's face-mesh points on ``mesh`` (a face looking along +z, +y up).

    Raises
    ------
    InputError
        No face is found in the renders (also slightly turned), or the points found are not
        left-right consistent.
    """
    from ..capture.tracker import FaceTracker, TrackerOptions
    from ..render.rasterizer import Renderer

    with Renderer(size, size) as renderer, FaceTracker(TrackerOptions(static=True, max_faces=1)) as tracker:
        found = None
        for yaw in yaws:
            camera = front_camera(mesh.vertices, size, size, vertical_fov=20.0, margin=1.05, yaw=yaw)
            found = _track_render(mesh, camera, renderer, tracker)
            if found is not None:
                break
        if found is None:
            raise InputError("automatic placement found no face on the rendered mesh (it should face +z with +y "
                             "up); give the control points as a JSON or .fdp file")
        rough = _surface_points(*found, camera)
        # Second pass: frame the face itself, so it fills the picture.
        camera = front_camera(rough, size, size, vertical_fov=20.0, margin=1.25, yaw=yaw)
        found = _track_render(mesh, camera, renderer, tracker)
        if found is None:
            raise InputError("automatic placement lost the face when framing it closely")
        points = _surface_points(*found, camera)
    # Snap to the part of the mesh (connected component) that most points land on: the skin. Points seen
    # through the eye or mouth openings would otherwise land on eyeballs or teeth.
    part = component_labels(mesh)
    first = project_points(mesh, points)
    skin = np.bincount(part[first.corner_vertices[:, 0]]).argmax()
    on_skin = part[mesh.triangles[:, 0]] == skin
    hit = project_points(Mesh(mesh.vertices, mesh.triangles[on_skin]), points)
    ids = hit.corner_vertices[np.arange(len(points)), hit.barycentric.argmax(axis=1)]
    _check_symmetry(mesh.vertices[ids])
    return ids


def _check_symmetry(points: np.ndarray) -> None:
    """Mirror pairs must sit at similar distances from the face's midline plane."""
    left, right = points[[b for _, b in _MIRROR_PAIRS]], points[[a for a, _ in _MIRROR_PAIRS]]
    axis = (left - right).mean(axis=0)
    axis /= np.linalg.norm(axis)
    middle = points[[1, 4, 6, 168, 152, 0, 17]] @ axis  # nose, bridge, chin and lip middles
    plane = np.median(middle)
    scale = np.linalg.norm(points[263] - points[33])
    offsets = np.abs((left @ axis - plane) - (plane - right @ axis)) / scale
    if offsets.max() > 0.15:  # a good placement (ICT neutral) stays under 0.07
        raise InputError(f"automatic placement found an asymmetric face (left and right points differ by up to "
                         f"{offsets.max():.0%} of the eye width); give the control points as a JSON or .fdp file")


def auto_target(mesh: Mesh) -> Target:
    """A Target whose control points are placed automatically: every MPEG-4 feature point MediaPipe
    observes (by number) and all 478 of its points (``mp<i>``)."""
    ids = place_landmarks(mesh)
    points = {f"mp{i}": int(v) for i, v in enumerate(ids)}
    points.update({name: int(ids[i]) for name, i in FEATURE_POINT_LANDMARK.items()})
    return Target(mesh, points, measure_fapu(mesh, points, source="automatic placement"))
