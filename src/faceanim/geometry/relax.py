"""Folds relaxed out of a deformed surface.

Interpolated motion can fold a surface where the motion it interpolates disagrees with itself: two
tracked points a few millimetres apart that move a centimetre apart (a lip's rim against its inner
side, the jaw's contour against the skin beneath it). The triangles between turn over. Here each
frame's folded neighbourhoods have their displacements smoothed (averaged with their neighbours'),
growing the neighbourhood until no triangle in it is turned over or a round limit is reached.
Vertices away from folds are untouched, so a control point off a fold still lands exactly.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse

__all__ = ["FoldRelaxer"]


class FoldRelaxer:
    """Relaxes turned-over triangles out of deformed copies of one mesh.

    Parameters
    ----------
    rest : (V, 3) float64
        The rest positions.
    triangles : (F, 3) int64
        The triangles to keep from turning over (those of the surface that must not fold).
    rounds : int
        At most this many smoothing passes per frame (each pass averages a neighbourhood once).

    Calling it with positions ``(T, V, 3)`` returns relaxed positions and, per frame, how many
    triangles stay turned over.

    Examples
    --------
    >>> rest = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [2, 0, 0], [2, 1, 0]])
    >>> tris = np.array([[0, 1, 2], [1, 3, 2], [1, 4, 3], [4, 5, 3]])
    >>> folded = rest.copy(); folded[3] = [-0.5, -0.5, 0]  # vertex 3 pulled through its neighbours
    >>> relaxed, left = FoldRelaxer(rest, tris)(folded[None])
    >>> int(left[0])
    0
    """

    def __init__(self, rest, triangles, *, rounds: int = 60):
        self.rest = np.asarray(rest, dtype=np.float64)
        self.triangles = np.asarray(triangles, dtype=np.int64)
        self.rounds = int(rounds)
        V = len(self.rest)
        e = np.sort(self.triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
        e = np.unique(e, axis=0)
        A = sparse.coo_matrix((np.ones(2 * len(e)), (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])),
                              shape=(V, V)).tocsr()
        degree = np.asarray(A.sum(axis=1)).ravel()
        self._adjacency = A
        self._average = sparse.diags(1.0 / np.maximum(degree, 1)) @ A
        self._rest_normals = self._normals(self.rest)

    def _normals(self, positions: np.ndarray) -> np.ndarray:
        v = positions[self.triangles]
        return np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])

    def turned(self, positions: np.ndarray) -> np.ndarray:
        """``(F,) bool``: the triangles turned over in one frame ``(V, 3)``."""
        return (self._normals(positions) * self._rest_normals).sum(axis=1) < 0

    def __call__(self, positions) -> tuple[np.ndarray, np.ndarray]:
        out = np.array(positions, dtype=np.float64)
        left = np.zeros(len(out), dtype=np.int64)
        for t in range(len(out)):
            left[t] = self._relax(out[t])
        return out, left

    def _relax(self, frame: np.ndarray) -> int:
        """Relax one frame in place; returns the triangles still turned over."""
        turned = self.turned(frame)
        if not turned.any():
            return 0
        region = self._grow(np.unique(self.triangles[turned]), 3)
        average, near = self._around(region)
        d = frame - self.rest
        for k in range(self.rounds):
            d[region] = 0.5 * d[region] + 0.5 * (average @ d)
            if k % 4 == 3:
                # Only triangles touching the region can have changed.
                turned = near[self._turned_among(self.rest + d, near)]
                if not len(turned):
                    break
                grown = np.union1d(region, self._grow(np.unique(self.triangles[turned]), 2))
                if len(grown) > len(region):
                    region = grown
                    average, near = self._around(region)
        frame[:] = self.rest + d
        return int(self.turned(frame).sum())

    def _around(self, region: np.ndarray):
        """The averaging rows of ``region`` and the triangles touching it."""
        inside = np.zeros(len(self.rest), dtype=bool)
        inside[region] = True
        return self._average[region], np.flatnonzero(inside[self.triangles].any(axis=1))

    def _turned_among(self, positions: np.ndarray, which: np.ndarray) -> np.ndarray:
        v = positions[self.triangles[which]]
        return (np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]) * self._rest_normals[which]).sum(axis=1) < 0

    def _grow(self, vertices: np.ndarray, rings: int) -> np.ndarray:
        mask = np.zeros(len(self.rest), dtype=bool)
        mask[vertices] = True
        for _ in range(rings):
            mask |= (self._adjacency @ mask.astype(np.float64)) > 0
        return np.flatnonzero(mask)
