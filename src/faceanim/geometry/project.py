"""Projection of points onto a triangle surface: closest point, its triangle, barycentric coordinates.

Exact, not approximate: candidate triangles come from a k-d tree over triangle centroids, and a
query is settled only once no unexamined triangle can be closer (its centroid would have to lie
within ``best distance + largest centroid-to-corner radius``); unsettled queries look at more
candidates. An optional normal test skips triangles facing away from the query's own normal, which
keeps the underside of an upper lip from landing on the top of the lower lip it touches.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.spatial import cKDTree

from ..validation import as_array
from .mesh import Mesh

__all__ = ["Projection", "project_points", "closest_point_on_triangles"]


def closest_point_on_triangles(points: np.ndarray, corners: np.ndarray):
    """Closest point on each triangle to each point (Ericson, *Real-Time Collision Detection* 5.1.5).

    Parameters
    ----------
    points : (M, 3) float64
    corners : (M, 3, 3) float64
        Triangle ``i``'s corners ``a, b, c`` for point ``i``.

    Returns
    -------
    closest : (M, 3) float64
    barycentric : (M, 3) float64
        Weights of ``a, b, c``; non-negative, summing to 1.

    Examples
    --------
    >>> tri = np.array([[[0., 0, 0], [1, 0, 0], [0, 1, 0]]])
    >>> closest_point_on_triangles(np.array([[0.25, 0.25, 2.0]]), tri)[1]
    array([[0.5 , 0.25, 0.25]])
    """
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    ab, ac, ap = b - a, c - a, points - a
    d1, d2 = _dot(ab, ap), _dot(ac, ap)
    bp = points - b
    d3, d4 = _dot(ab, bp), _dot(ac, bp)
    cp = points - c
    d5, d6 = _dot(ab, cp), _dot(ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2

    bary = np.zeros((len(points), 3))
    done = np.zeros(len(points), dtype=bool)

    def settle(mask, u, v, w):
        nonlocal done
        mask = mask & ~done
        bary[mask] = np.stack([u[mask], v[mask], w[mask]], axis=1)
        done |= mask

    one, zero = np.ones(len(points)), np.zeros(len(points))
    with np.errstate(divide="ignore", invalid="ignore"):
        settle((d1 <= 0) & (d2 <= 0), one, zero, zero)                       # vertex a
        settle((d3 >= 0) & (d4 <= d3), zero, one, zero)                      # vertex b
        t = d1 / (d1 - d3)
        settle((vc <= 0) & (d1 >= 0) & (d3 <= 0), 1 - t, t, zero)            # edge ab
        settle((d6 >= 0) & (d5 <= d6), zero, zero, one)                      # vertex c
        t = d2 / (d2 - d6)
        settle((vb <= 0) & (d2 >= 0) & (d6 <= 0), 1 - t, zero, t)           # edge ac
        t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        settle((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), zero, 1 - t, t)  # edge bc
        denom = va + vb + vc
        v, w = vb / denom, vc / denom
        settle(np.ones(len(points), dtype=bool), 1 - v - w, v, w)            # interior
    degenerate = ~np.isfinite(bary).all(axis=1)
    if degenerate.any():  # zero-area triangles: take the nearest corner
        dist = np.linalg.norm(corners[degenerate] - points[degenerate, None], axis=2)
        bary[degenerate] = np.eye(3)[dist.argmin(axis=1)]
    closest = np.einsum("mk,mkd->md", bary, corners)
    return closest, bary


def _dot(x, y):
    return np.einsum("ij,ij->i", x, y)


@dataclass(frozen=True, eq=False)
class Projection:
    """Where points land on a surface.

    ``points (N, 3)`` the closest surface points, ``triangles (N,)`` their triangles,
    ``barycentric (N, 3)`` weights of those triangles' corners, ``distances (N,)``.
    """

    points: np.ndarray
    triangles: np.ndarray
    barycentric: np.ndarray
    distances: np.ndarray
    corner_vertices: np.ndarray  # (N, 3) vertex ids of each landing triangle

    def interpolate(self, values) -> np.ndarray:
        """Per-vertex ``values (V, C)`` or ``(T, V, C)`` interpolated at the landing points."""
        values = np.asarray(values, dtype=np.float64)
        return np.einsum("nk,...nkc->...nc", self.barycentric, values[..., self.corner_vertices, :])

    def matrix(self, vertex_count: int) -> sparse.csr_matrix:
        """Sparse ``(N, V)`` matrix of barycentric weights: ``matrix @ values == interpolate(values)``."""
        rows = np.repeat(np.arange(len(self.triangles)), 3)
        return sparse.csr_matrix((self.barycentric.ravel(), (rows, self.corner_vertices.ravel())),
                                 shape=(len(self.triangles), vertex_count))


def project_points(mesh: Mesh, points, *, normals=None, max_angle: float = 90.0) -> Projection:
    """Project points onto the closest point of ``mesh``'s surface.

    Parameters
    ----------
    mesh : Mesh
    points : (N, 3) float64
    normals : (N, 3) float64, optional
        The points' own normals. Triangles whose normal makes an angle of ``max_angle`` degrees or
        more with a point's normal are skipped for that point; a point with no such triangle at all
        falls back to the unrestricted closest point.
    max_angle : float
        In degrees, in (0, 180].

    Examples
    --------
    >>> m = Mesh([[0., 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    >>> project_points(m, [[0.2, 0.2, -3.0]]).distances
    array([3.])
    """
    points = as_array(points, "points", shape=("N", 3))
    if not 0 < max_angle <= 180:
        raise ValueError(f"max_angle must be in (0, 180] degrees, got {max_angle}")
    cos_limit = np.cos(np.radians(max_angle))
    if normals is not None:
        normals = as_array(normals, "normals", shape=(len(points), 3))
    tri_corners = mesh.vertices[mesh.triangles]
    best_d = np.full(len(points), np.inf)
    best_f = np.zeros(len(points), dtype=np.int64)
    best_bary = np.zeros((len(points), 3))
    # A point's nearest vertex bounds its distance, and so where its triangle can be; near points are
    # settled by that bound alone. A normal test can rule out every triangle within it, so those go
    # straight to the search by growing candidate sets below.
    unsettled = (np.arange(len(points)) if normals is not None
                 else _settled_near(mesh, points, tri_corners, best_d, best_f, best_bary))
    for bucket in _size_buckets(mesh):
        # Search each size class with its own reach, small triangles (the most numerous) first, so the
        # best distance found there lets the classes of large triangles settle after a few candidates.
        pending = unsettled
        k = min(16, bucket.size)
        while len(pending):
            cdist, local = bucket.tree.query(points[pending], k=k)
            cdist, local = cdist.reshape(len(pending), k), local.reshape(len(pending), k)
            cand = bucket.faces[local]
            q = np.repeat(pending, k)
            closest, bary = closest_point_on_triangles(points[q], tri_corners[cand.ravel()])
            d = np.linalg.norm(closest - points[q], axis=1).reshape(len(pending), k)
            if normals is not None:
                facing = np.einsum("nd,nkd->nk", normals[pending], mesh.face_normals[cand]) > cos_limit
                d = np.where(facing, d, np.inf)
            j = d.argmin(axis=1)
            row = np.arange(len(pending))
            improve = d[row, j] < best_d[pending]
            idx = pending[improve]
            best_d[idx] = d[row, j][improve]
            best_f[idx] = cand[row, j][improve]
            best_bary[idx] = bary.reshape(len(pending), k, 3)[row, j][improve]
            settled = (k >= bucket.size) | (cdist[:, -1] >= best_d[pending] + bucket.reach)
            pending = pending[~settled]
            k = min(4 * k, bucket.size)

    unmatched = ~np.isfinite(best_d)
    if unmatched.any():
        fallback = project_points(mesh, points[unmatched])
        best_d[unmatched], best_f[unmatched] = fallback.distances, fallback.triangles
        best_bary[unmatched] = fallback.barycentric
    corner_vertices = mesh.triangles[best_f]
    landing = np.einsum("nk,nkd->nd", best_bary, mesh.vertices[corner_vertices])
    return Projection(landing, best_f, best_bary, best_d, corner_vertices)


def _settled_near(mesh: Mesh, points, tri_corners, best_d, best_f, best_bary) -> np.ndarray:
    """The closest points of ``points`` within a few triangles of ``mesh``, written into ``best_*`` in
    place; returns the indices of the rest.

    The nearest vertex's distance ``u`` bounds the closest point's, and a triangle that holds it has its
    centroid within ``u`` plus its own radius of the point, so one ball query per size class gives every
    candidate at once. For points near the surface that is a few dozen triangles, about a third as
    many as growing nearest-centroid sets until they settle (the lips against the teeth in
    ``animate``: 27 candidates a point against 64 and more). Far from the surface the ball would take in
    much of it, so far points are left to the growing search.
    """
    if not len(mesh.triangles) or not len(points):
        return np.arange(len(points))
    tree, buckets, near = _near_index(mesh)
    bound = tree.query(points)[0]
    close = np.flatnonzero(bound <= near)
    for start in range(0, len(close), _NEAR_CHUNK):
        which = close[start:start + _NEAR_CHUNK]
        p = points[which]
        # Widened by a hair so that a triangle exactly at the bound is not lost to rounding.
        radius = bound[which] * (1 + 1e-9) + 1e-12
        for bucket in buckets:
            lists = bucket.tree.query_ball_point(p, radius + bucket.reach, return_sorted=False)
            counts = np.fromiter((len(found) for found in lists), np.int64, len(lists))
            if not counts.sum():
                continue
            faces = bucket.faces[np.fromiter((i for found in lists for i in found), np.int64, int(counts.sum()))]
            q = np.repeat(np.arange(len(p)), counts)
            closest, bary = closest_point_on_triangles(p[q], tri_corners[faces])
            d = np.linalg.norm(closest - p[q], axis=1)
            order = np.lexsort((d, q))
            first = order[np.r_[True, q[order][1:] != q[order][:-1]]]  # each point's closest candidate
            who = which[q[first]]
            better = d[first] < best_d[who]
            best_d[who[better]] = d[first][better]
            best_f[who[better]] = faces[first][better]
            best_bary[who[better]] = bary[first][better]
    # The far points, and any the bound left unsettled (a rounding at a degenerate sliver), search on.
    return np.flatnonzero(~np.isfinite(best_d))


def _near_index(mesh: Mesh):
    """What :func:`_settled_near` searches, cached on the mesh: a k-d tree over the vertices triangles
    use, the triangles in finer size classes (powers of the square root of two of their radius:
    a class's reach is what every candidate ball is widened by), and how near a point must be."""
    def compute():
        used = np.unique(mesh.triangles)
        corners = mesh.vertices[mesh.triangles]
        centroids = corners.mean(axis=1)
        radius = np.linalg.norm(corners - centroids[:, None], axis=2).max(axis=1)
        smallest = max(float(radius.min()), 1e-12 * max(float(radius.max()), 1e-300), 1e-300)
        level = np.floor(2 * np.log2(np.maximum(radius, smallest) / smallest)).astype(int)
        buckets = []
        for value in np.unique(level):
            faces = np.flatnonzero(level == value)
            buckets.append(_Bucket(faces, cKDTree(centroids[faces]), float(radius[faces].max())))
        return cKDTree(mesh.vertices[used]), tuple(buckets), _NEAR_RADII * float(np.median(radius))

    return mesh._cached("projection_near", compute)


_NEAR_RADII = 4.0  # points this many median triangle radii from the nearest vertex are settled by the bound
_NEAR_CHUNK = 8192  # points settled at once by the bound (their candidates held together)


@dataclass(frozen=True, eq=False)
class _Bucket:
    faces: np.ndarray  # triangle ids in this size class
    tree: cKDTree      # over their centroids
    reach: float       # largest centroid-to-corner distance among them

    @property
    def size(self) -> int:
        return len(self.faces)


def _size_buckets(mesh: Mesh) -> tuple[_Bucket, ...]:
    """Triangles grouped by size (powers of two of their radius), cached on the (immutable) mesh."""
    def compute():
        corners = mesh.vertices[mesh.triangles]
        centroids = corners.mean(axis=1)
        radius = np.linalg.norm(corners - centroids[:, None], axis=2).max(axis=1)
        floor = max(np.median(radius), 1e-300)
        level = np.floor(np.log2(np.maximum(radius, floor) / floor)).astype(int)
        buckets = []
        for value in np.unique(level):
            faces = np.flatnonzero(level == value)
            buckets.append(_Bucket(faces, cKDTree(centroids[faces]), float(radius[faces].max())))
        return tuple(buckets)

    return mesh._cached("projection_buckets", compute)
