"""How well a deformed surface holds together: measures of an animation against its rest mesh.

Each function compares positions over time ``(T, V, 3)`` with the rest positions ``(V, 3)`` and
reports one number per frame, so a benchmark can take the worst frame or count the bad ones:

- :func:`turned_over` / :func:`turned_triangles`: triangles whose normal turned by more than 90
  degrees from rest (a fold or a flip: the surface passed through itself);
- :func:`rigid_residual`: how far a part that should move as a whole (a set of teeth) is from the
  best rigid motion of its rest shape;
- :func:`edge_stretch`: the worst change of an edge's length, as a ratio (a tear or a crease);
- :func:`signed_distance` / :func:`penetration_depth`: how deep points (the lips) went behind a
  surface (the teeth).

Lengths are in the mesh's own units (the caller converts, e.g. with the target's FAPU); ratios and
counts have none. Work is done a few frames at a time, so memory stays bounded by the frames of one
chunk, not by the animation's length.
"""

from __future__ import annotations

import numpy as np

from ..validation import as_array, as_index_array
from .align import weighted_procrustes
from .mesh import Mesh
from .project import project_points
from .topology import open_edges, shared_edges

__all__ = ["turned_over", "turned_triangles", "rigid_residual", "edge_stretch", "bend_change", "signed_distance",
           "signed_offsets", "penetration_depth"]

_CHUNK_VALUES = 4_000_000  # floats per working array (32 MB): frames are processed this many values at a time


def _sequence(rest, positions):
    rest = as_array(rest, "rest", shape=("V", 3), min_length=1)
    positions = as_array(positions, "positions", shape=("T", len(rest), 3))
    return rest, positions


def _chunks(frames: int, per_frame: int):
    step = max(1, _CHUNK_VALUES // max(per_frame, 1))
    for start in range(0, frames, step):
        yield slice(start, min(start + step, frames))


def turned_over(rest, positions, triangles, *, mask=None) -> np.ndarray:
    """Which triangles face the other way than at rest, frame by frame.

    A triangle counts when its normal turned by more than 90 degrees from its rest normal (the dot
    product of the two is negative). Triangles of zero area at rest are never counted; one that
    collapses to zero area counts only once it has turned past 90 degrees.

    Parameters
    ----------
    rest : (V, 3) float64
        Rest positions.
    positions : (T, V, 3) float64
        Positions in each frame, same vertex order.
    triangles : (F, 3) int64
        Vertex ids of each triangle.
    mask : (F,) bool, optional
        The triangles to look at (say, the skin's); all by default.

    Returns
    -------
    (T, F') bool
        For each frame, whether each looked-at triangle (``F' = mask.sum()``) is turned over.

    Examples
    --------
    >>> rest = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0]])
    >>> flipped = rest * [1, -1, 1]  # mirrored in y: the triangle now faces -z
    >>> turned_over(rest, np.stack([rest, flipped]), [[0, 1, 2]])
    array([[False],
           [ True]])
    """
    rest, positions = _sequence(rest, positions)
    triangles = as_index_array(triangles, "triangles", upper=len(rest), shape=("F", 3))
    if mask is not None:
        mask = as_array(mask, "mask", shape=(len(triangles),), dtype=bool)
        triangles = triangles[mask]
    a, b, c = triangles.T
    rest_normal = np.cross(rest[b] - rest[a], rest[c] - rest[a])
    out = np.zeros((len(positions), len(triangles)), dtype=bool)
    for frames in _chunks(len(positions), 9 * len(triangles)):
        p = positions[frames]
        normal = np.cross(p[:, b] - p[:, a], p[:, c] - p[:, a])
        out[frames] = np.einsum("tfd,fd->tf", normal, rest_normal) < 0
    return out


def turned_triangles(rest, positions, triangles, *, mask=None) -> np.ndarray:
    """``(T,) int64``: the number of triangles turned over in each frame (see :func:`turned_over`).

    Examples
    --------
    >>> rest = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    >>> folded = rest.copy(); folded[3] = [-1, -1, 0]  # the second triangle folds over the first
    >>> turned_triangles(rest, np.stack([rest, folded]), [[0, 1, 2], [1, 3, 2]])
    array([0, 1])
    """
    return turned_over(rest, positions, triangles, mask=mask).sum(axis=1)


def rigid_residual(rest, moved) -> np.ndarray:
    """How far points are from moving as one rigid body: per frame, the largest distance left after
    the best rigid fit (rotation and translation, no scale; least squares, Kabsch) of ``rest`` onto
    that frame's points.

    Parameters
    ----------
    rest : (N, 3) float64
        The points at rest (model units); at least 3, not all on one line, for the fit to be unique.
    moved : (T, N, 3) float64
        The same points in each frame.

    Returns
    -------
    (T,) float64
        Worst residual distance per frame, in the units of ``rest``.

    Examples
    --------
    >>> rest = np.array([[-1., 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0]])
    >>> turned = rest @ np.array([[0., -1, 0], [1, 0, 0], [0, 0, 1]]).T + [2, 0, 0]
    >>> widened = rest * [1.2, 1, 1]  # stretched along x: the best rigid fit stays put
    >>> np.round(rigid_residual(rest, np.stack([turned, widened])), 6)
    array([0. , 0.2])
    """
    rest = as_array(rest, "rest", shape=("N", 3), min_length=1)
    moved = as_array(moved, "moved", shape=("T", len(rest), 3))
    out = np.empty(len(moved))
    for t, points in enumerate(moved):
        M = weighted_procrustes(rest, points, scale=False)
        fitted = rest @ M[:3, :3].T + M[:3, 3]
        out[t] = np.linalg.norm(fitted - points, axis=1).max()
    return out


def edge_stretch(rest, positions, edges) -> np.ndarray:
    """The worst change of length among ``edges`` in each frame, as a ratio: ``max(l / l0, l0 / l)``
    over the edges (1 where none changed, 2 where one doubled or halved). Edges of zero length at
    rest are left out; an edge that shrinks to zero length gives infinity.

    Parameters
    ----------
    rest : (V, 3) float64
    positions : (T, V, 3) float64
    edges : (E, 2) int64
        Vertex ids of each edge (``Mesh.edges``).

    Returns
    -------
    (T,) float64
        At least 1.

    Examples
    --------
    >>> rest = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0]])
    >>> edge_stretch(rest, np.stack([rest, rest * [2, 1, 1]]), [[0, 1], [0, 2]])
    array([1., 2.])
    """
    rest, positions = _sequence(rest, positions)
    edges = as_index_array(edges, "edges", upper=len(rest), shape=("E", 2))
    rest_length = np.linalg.norm(rest[edges[:, 1]] - rest[edges[:, 0]], axis=1)
    edges, rest_length = edges[rest_length > 0], rest_length[rest_length > 0]
    out = np.ones(len(positions))
    if not len(edges):
        return out
    for frames in _chunks(len(positions), 6 * len(edges)):
        p = positions[frames]
        length = np.linalg.norm(p[:, edges[:, 1]] - p[:, edges[:, 0]], axis=2)
        with np.errstate(divide="ignore"):
            ratio = np.maximum(length / rest_length, rest_length / length)
        out[frames] = ratio.max(axis=1)
    return out


def bend_change(rest, positions, triangles, *, percentile: float = 95.0) -> np.ndarray:
    """How far a surface bends away from its rest shape, per frame: the ``percentile`` over the edges
    two of ``triangles`` share of the change in the signed angle between those two triangles' normals
    (degrees; a ridge turned into a valley counts both bends). 0 for any rigid motion, and for a
    surface that only stretches in its own plane; a crease that a deformation adds is a line of edges
    bent far more than the rest.

    Parameters
    ----------
    rest : (V, 3) float64
    positions : (T, V, 3) float64
    triangles : (F, 3) int64
    percentile : float or sequence of float
        In [0, 100].

    Returns
    -------
    (T,) float64, or (T, P) for P percentiles

    Examples
    --------
    >>> rest = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    >>> folded = rest.copy(); folded[3] = [0.5, 0.5, 0.7071]  # the second triangle turned up about the diagonal
    >>> bend_change(rest, np.stack([rest, folded]), [[0, 1, 2], [1, 3, 2]], percentile=100).round(1)
    array([ 0., 90.])
    """
    rest, positions = _sequence(rest, positions)
    triangles = as_index_array(triangles, "triangles", upper=len(rest), shape=("F", 3))
    q = np.asarray(percentile, dtype=np.float64)
    if q.ndim > 1 or not ((q >= 0) & (q <= 100)).all():
        raise ValueError(f"percentile must be in [0, 100], got {percentile}")
    ends, first, second = shared_edges(triangles)
    start, end = ends[:, 0], ends[:, 1]  # the edge as the first triangle runs along it
    out = np.zeros((len(positions), *q.shape))
    if not len(ends):
        return out

    def angles(p):  # (..., E) degrees between the two triangles' normals, signed by the way the edge bends
        corner = p[..., triangles, :]
        n = np.cross(corner[..., 1, :] - corner[..., 0, :], corner[..., 2, :] - corner[..., 0, :])
        n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-300)
        along = p[..., end, :] - p[..., start, :]
        along /= np.maximum(np.linalg.norm(along, axis=-1, keepdims=True), 1e-300)
        n1, n2 = n[..., first, :], n[..., second, :]
        return np.degrees(np.arctan2((np.cross(n1, n2) * along).sum(axis=-1), (n1 * n2).sum(axis=-1)))

    at_rest = angles(rest)
    for frames in _chunks(len(positions), 9 * len(triangles)):
        change = np.abs((angles(positions[frames]) - at_rest + 180.0) % 360.0 - 180.0)
        out[frames] = np.moveaxis(np.percentile(change, q, axis=1), 0, -1)
    return out


def signed_distance(points, vertices, triangles) -> np.ndarray:
    """Distance of each point to a surface, negative behind it.

    The closest point of the surface is found exactly (:func:`~faceanim.geometry.project.project_points`);
    the sign is that of the offset along the surface's outward normal there (the vertex normals
    interpolated at the closest point, which also settles points closest to an edge or a corner).
    "Outward" follows the triangles' winding (counter-clockwise seen from outside). A point whose
    closest point lies on the rim of an open surface (an edge of only one triangle, or a vertex on
    such an edge) is beside the surface, not behind it, and counts as in front (positive).

    Parameters
    ----------
    points : (N, 3) float64
    vertices : (W, 3) float64
        The surface's vertices.
    triangles : (F, 3) int64
        Its triangles, indexing ``vertices``.

    Returns
    -------
    (N,) float64
        In the units of ``vertices``.

    Examples
    --------
    >>> square = [[0., 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]  # faces +z
    >>> signed_distance([[0.5, 0.5, 0.2], [0.5, 0.5, -0.3]], square, [[0, 1, 2], [0, 2, 3]])
    array([ 0.2, -0.3])
    """
    points = as_array(points, "points", shape=("N", 3))
    return signed_offsets(points, Mesh(vertices, triangles))[0]


def signed_offsets(points: np.ndarray, surface: Mesh) -> tuple[np.ndarray, np.ndarray]:
    """:func:`signed_distance` of ``points (N, 3)`` to ``surface``, and the outward unit normal at
    each closest point ``(N, 3)`` (the direction that takes a point behind the surface out of it)."""
    found = project_points(surface, points)
    normal = found.interpolate(surface.vertex_normals)
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    side = np.einsum("nd,nd->n", points - found.points, normal)
    behind = (side < 0) & ~_on_rim(surface, found)
    return np.where(behind, -found.distances, found.distances), normal


def _on_rim(surface: Mesh, found) -> np.ndarray:
    """``(N,) bool``: whether each closest point lies on the surface's border (a corner or an edge
    of the landing triangle that belongs to no other triangle). Landings on an edge or a corner have
    exactly zero barycentric weights elsewhere (:func:`closest_point_on_triangles` sets them so)."""
    rim = surface._cached("open_edges", lambda: open_edges(surface.triangles))
    if not len(rim):
        return np.zeros(len(found.distances), dtype=bool)
    V = len(surface.vertices)
    rim_vertex = np.zeros(V, dtype=bool)
    rim_vertex[rim.ravel()] = True
    weighted = found.barycentric != 0
    used = weighted.sum(axis=1)
    out = np.zeros(len(found.distances), dtype=bool)
    at_corner = used == 1
    out[at_corner] = rim_vertex[found.corner_vertices[at_corner][weighted[at_corner]]]
    on_edge = np.flatnonzero(used == 2)
    if len(on_edge):
        ends = np.sort(found.corner_vertices[on_edge][weighted[on_edge]].reshape(-1, 2), axis=1)
        out[on_edge] = np.isin(ends[:, 0] * V + ends[:, 1], rim[:, 0] * V + rim[:, 1])
    return out


def penetration_depth(points, surface, triangles) -> np.ndarray:
    """How deep points went behind a moving surface: per frame, the largest depth of any point
    behind it (see :func:`signed_distance`), 0 where every point is in front.

    Used for lips and teeth: ``points`` are lip vertices that start in front of the teeth,
    ``surface`` the teeth's vertices in the same frames; a lip pressed through the teeth ends up
    inside them (or behind an open shell of them), and its depth is how far. A point beside an open
    surface's border is not behind it (see :func:`signed_distance`).

    Parameters
    ----------
    points : (T, N, 3) float64
        The points in each frame.
    surface : (T, W, 3) float64
        The surface's vertices in each frame.
    triangles : (F, 3) int64
        The surface's triangles, indexing its ``W`` vertices.

    Returns
    -------
    (T,) float64
        Non-negative, in the units of ``surface``.

    Examples
    --------
    >>> square = np.array([[0., 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    >>> lips = np.array([[[0.5, 0.5, 0.1]], [[0.5, 0.5, -0.3]]])  # in front, then 0.3 behind
    >>> penetration_depth(lips, np.stack([square, square]), [[0, 1, 2], [0, 2, 3]])
    array([0. , 0.3])
    """
    points = as_array(points, "points", shape=("T", "N", 3))
    surface = as_array(surface, "surface", shape=(len(points), "W", 3))
    triangles = as_index_array(triangles, "triangles", upper=surface.shape[1], shape=("F", 3))
    out = np.zeros(len(points))
    if points.shape[1] == 0:
        return out
    for t in range(len(points)):
        out[t] = max(0.0, -float(signed_distance(points[t], surface[t], triangles).min()))
    return out
