"""A surface as seen along one axis: which of its triangles a viewer ahead of it sees, and how far
along the axis from a point the furthest of them lies (:class:`SightLines`)."""

from __future__ import annotations

import numpy as np

from .mesh import Mesh

__all__ = ["SightLines"]

# Cells across a median triangle. A point meets every triangle whose box overlaps its cell, and a cell
# a triangle wide is overlapped by the boxes of its neighbours too: the ICT head's teeth find their
# seen triangles in 0.26-0.30 s with a third of a triangle, 0.87-1.03 s with a whole one (same result).
_CELLS_ACROSS = 3


class SightLines:
    """A surface as seen along one axis, from ahead: the triangles a viewer there sees (a triangle
    whose centre and corners all have another in front is dropped: anything ahead of a point has a
    seen triangle ahead of it too), binned by where they fall on the plane across that axis (a grid
    of cells a third of a median triangle wide), so a line along the axis meets only the few triangles
    over its cell.

    :meth:`furthest` gives, for points, how far along the axis (either way) the furthest crossing of
    the seen surface within a length lies.
    """

    def __init__(self, surface: Mesh, axes: np.ndarray):
        self.surface = surface
        self.across = np.asarray(axes[:2], dtype=np.float64)  # the plane the grid lies in
        self.along = np.asarray(axes[2], dtype=np.float64)
        corners = surface.vertices[surface.triangles]
        flat = corners @ self.across.T  # (F, 3, 2): each triangle as seen along the axis
        self._corner = flat[:, 0]
        edges = np.stack([flat[:, 1] - flat[:, 0], flat[:, 2] - flat[:, 0]], axis=2)  # (F, 2, 2) columns
        det = edges[:, 0, 0] * edges[:, 1, 1] - edges[:, 0, 1] * edges[:, 1, 0]
        self._flat = np.abs(det) > 1e-12  # seen edge-on, a triangle covers nothing
        safe = np.where(self._flat, det, 1.0)
        self._inverse = np.stack([np.stack([edges[:, 1, 1], -edges[:, 0, 1]], axis=1),
                                  np.stack([-edges[:, 1, 0], edges[:, 0, 0]], axis=1)], axis=1) / safe[:, None, None]
        self._depth = corners @ self.along  # (F, 3)
        self._bin(np.arange(len(surface.triangles)))
        centre = corners.mean(axis=1, keepdims=True)
        samples = np.concatenate([centre, centre + 0.9 * (corners - centre)], axis=1)  # (F, 4, 3)
        depth = float(np.ptp(surface.vertices @ self.along)) + 1.0
        lift = 1e-6 * depth * self.along
        covered = self.furthest(samples.reshape(-1, 3) + lift, 1.0, depth).reshape(-1, 4) > 0
        self._bin(np.flatnonzero(~covered.all(axis=1)))

    def _bin(self, seen: np.ndarray) -> None:
        corners = self.surface.vertices[self.surface.triangles[seen]] @ self.across.T  # (F, 3, 2)
        low, high = corners.min(axis=1), corners.max(axis=1)
        self.cell = float(np.median((high - low).max(axis=1))) / _CELLS_ACROSS or 1.0
        self.origin = low.min(axis=0)
        first = np.floor((low - self.origin) / self.cell).astype(np.int64)
        last = np.floor((high - self.origin) / self.cell).astype(np.int64)
        self.columns = int(last[:, 0].max()) + 1
        span = last - first + 1
        cells, triangles = [], []
        for di in range(int(span[:, 0].max())):
            for dj in range(int(span[:, 1].max())):
                inside = np.flatnonzero((di < span[:, 0]) & (dj < span[:, 1]))
                cells.append((first[inside, 1] + dj) * self.columns + first[inside, 0] + di)
                triangles.append(seen[inside])
        cells, triangles = np.concatenate(cells), np.concatenate(triangles)
        order = np.argsort(cells, kind="stable")
        self.cells, self.triangles = cells[order], triangles[order]

    def furthest(self, points: np.ndarray, sign: float, length: float) -> np.ndarray:
        """``(N,)``: how far from each of ``points (N, 3)``, along ``sign`` (+1 or -1) times the axis,
        the furthest crossing of the surface within ``length`` lies; 0 where none does."""
        points = np.asarray(points, dtype=np.float64)
        out = np.zeros(len(points))
        if not len(points):
            return out
        cell = np.floor((points @ self.across.T - self.origin) / self.cell).astype(np.int64)
        valid = (cell >= 0).all(axis=1) & (cell[:, 0] < self.columns)
        key = np.where(valid, cell[:, 1] * self.columns + cell[:, 0], -1)
        start = np.searchsorted(self.cells, key, side="left")
        stop = np.searchsorted(self.cells, key, side="right")
        counts = np.where(valid, stop - start, 0)
        if not counts.sum():
            return out
        which = np.repeat(np.arange(len(points)), counts)
        offsets = np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)
        tri = self.triangles[np.repeat(start, counts) + offsets]
        # In the grid's plane: the point's barycentric coordinates in the triangle, and the triangle's
        # depth along the axis there.
        at = points[which] @ self.across.T - self._corner[tri]
        u = np.einsum("nij,nj->ni", self._inverse[tri], at)
        inside = (u >= 0).all(axis=1) & (u.sum(axis=1) <= 1) & self._flat[tri]
        depth = self._depth[tri, 0] + np.einsum("ni,ni->n", u, self._depth[tri, 1:] - self._depth[tri, :1])
        ahead = sign * (depth - points[which] @ self.along)
        hit = inside & (ahead >= 0) & (ahead <= length)
        np.maximum.at(out, which[hit], ahead[hit])
        return out
