"""Folds relaxed out of a deformed surface.

Interpolated motion can fold a surface where the motion it interpolates disagrees with itself: two
tracked points a few millimetres apart that move a centimetre apart (a lip's rim against its inner
side, the corner of the mouth where the lining creases back). The triangles between turn over.

Here each frame's folded neighbourhoods have their displacement *over a base motion* replaced by its
harmonic fill (cotangent Laplacian) from the neighbourhood's edge, growing the neighbourhood until no
triangle in it is turned over. The base is a motion known not to fold (the jaw's turn, whose weights
:func:`faceanim.parts.jaw.unfolded_jaw_weight` keeps from folding), so what is smoothed is only the
part that disagrees with itself, and a fold next to the chin does not flatten the chin's drop.
Harmonic, not averaged: an average over a few rounds leaves a fold across a crease of tiny triangles
(it moves each vertex a little towards its neighbours), and can make one where none was; the fill is
the smoothest field with the edge's values, so the crease moves as one piece. Vertices away from
folds are untouched, so a control point off a fold still lands exactly.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.sparse.linalg import splu

from .mesh import Mesh
from .surface import cotangent_laplacian
from .topology import vertex_adjacency

__all__ = ["FoldRelaxer"]

_YIELD_RINGS = (1, 2, 4, 8)  # how far from a fold held by pins they yield, tried in turn
_PASSES = 3  # fresh starts of a frame's relaxation
_BLEND = 3  # rings of blend, per ring of a seeded patch, between the patch put on the base and the rest


class FoldRelaxer:
    """Relaxes turned-over triangles out of deformed copies of one mesh.

    Parameters
    ----------
    rest : (V, 3) float64
        The rest positions.
    triangles : (F, 3) int64
        The triangles to keep from turning over (those of the surface that must not fold).
    rounds : int
        At most this many fills per frame, the neighbourhood growing by ``grow`` rings after each.
    rings, grow : int
        The first neighbourhood is the folded triangles' vertices and ``rings`` rings around them.
        Kept small: a fill that takes in the mouth corner's control points flattens a smile (the
        demo's avatar smile, read back by the tracker, fell from 0.34 to 0.17 in correlation with
        2 rings and growth by 2).
    largest : float
        A neighbourhood stops growing at this share of the vertices (what folds is local; filling the
        whole surface would flatten the motion it is meant to keep).

    Calling it with positions ``(T, V, 3)`` (and optionally the base positions ``(T, V, 3)`` that do
    not fold, default the rest; ``pinned (T, V) bool``, vertices kept where they are given, which the
    fills take as edge values; and ``seeds (T, V) bool``, vertices put on the base with ``seed_rings``
    rings around them and blended into the rest over :data:`_BLEND` times as many, for a caller that
    knows of faults other than folds) returns relaxed positions and, per frame, how many triangles
    stay turned over. With ``pins_yield=True`` a fold the pinned vertices hold in place (pinned
    corners of their own, or a ring of pins around it that the neighbourhood cannot grow past) frees
    the pins within 1, 2, 4 and then 8 rings of it, one step at a time, until it relaxes: for a caller
    whose pins are a preference (a lip pushed out of the teeth) and for whom a fold is worse.

    Examples
    --------
    >>> rest = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [2, 0, 0], [2, 1, 0]])
    >>> tris = np.array([[0, 1, 2], [1, 3, 2], [1, 4, 3], [4, 5, 3]])
    >>> folded = rest.copy(); folded[3] = [-0.5, -0.5, 0]  # vertex 3 pulled through its neighbours
    >>> relaxed, left = FoldRelaxer(rest, tris)(folded[None])
    >>> int(left[0])
    0
    """

    def __init__(self, rest, triangles, *, rounds: int = 24, rings: int = 0, grow: int = 1, largest: float = 0.25):
        self.rest = np.asarray(rest, dtype=np.float64)
        self.triangles = np.asarray(triangles, dtype=np.int64)
        self.rounds, self.rings, self.grow = int(rounds), int(rings), int(grow)
        V = len(self.rest)
        self._largest = max(1, int(largest * V))
        e = np.sort(self.triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
        e = np.unique(e, axis=0)
        self._adjacency = vertex_adjacency(e, V)
        L, _ = cotangent_laplacian(Mesh(self.rest, self.triangles))
        # A neighbourhood holding a whole island has no edge to fill from: the tiny diagonal term
        # makes the island take the base's motion instead of a singular solve.
        self._laplacian = (L + sparse.diags(np.full(V, 1e-9 * max(abs(L.diagonal()).max(), 1e-300)))).tocsr()
        self._corners = tuple(np.ascontiguousarray(self.triangles[:, c]) for c in range(3))
        self._rest_normals = self._normals(self.rest)  # (3, F)

    def _normals(self, positions: np.ndarray, which=slice(None)) -> np.ndarray:
        """``(3, F')``: the triangles' ``which`` (unnormalised) normals, coordinate by coordinate
        (a gather per corner and six products: five times faster than ``np.cross`` on gathered
        corners, and this is the relaxer's inner loop)."""
        p = np.ascontiguousarray(positions.T)
        i, j, k = (c[which] for c in self._corners)
        a = p[:, i]
        u, w = p[:, j] - a, p[:, k] - a
        return np.stack([u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]])

    def turned(self, positions: np.ndarray) -> np.ndarray:
        """``(F,) bool``: the triangles turned over in one frame ``(V, 3)``."""
        return self._turned_among(positions, slice(None))

    def __call__(self, positions, base=None, pinned=None, *, pins_yield: bool = False,
                 seeds=None, seed_rings: int = 0) -> tuple[np.ndarray, np.ndarray]:
        out = np.array(positions, dtype=np.float64)
        left = np.zeros(len(out), dtype=np.int64)
        for t in range(len(out)):
            frame_base = self.rest if base is None else np.asarray(base[t], dtype=np.float64)
            pins = None if pinned is None else np.array(pinned[t], dtype=bool)
            if seeds is not None and np.any(seeds[t]):
                self._based(out[t], frame_base, np.flatnonzero(seeds[t]), seed_rings, pins)
            left[t] = self._relaxed_again(out[t], frame_base, pins)
            for rings in _YIELD_RINGS if pins_yield and pins is not None else ():
                if not left[t] or not pins.any():
                    break
                pins &= ~self._grown(np.unique(self.triangles[self.turned(out[t])]), rings)
                left[t] = self._relaxed_again(out[t], frame_base, pins)
        return out, left

    def _based(self, frame: np.ndarray, base: np.ndarray, seeds: np.ndarray, rings: int, pinned) -> None:
        """The ``seeds`` and ``rings`` rings around them put on ``base`` in ``frame`` (in place), and
        :data:`_BLEND` times as many rings around those filled harmonically between the two, so the
        surface leaves the base smoothly (with as many rings as the patch, a crease ran round it)."""
        free = np.ones(len(frame), dtype=bool) if pinned is None else ~pinned
        core = self._grown(seeds, rings) & free
        frame[core] = base[core]
        inside = np.flatnonzero(self._grown(np.flatnonzero(core), _BLEND * rings) & ~core & free)
        if len(inside):
            edge_values = frame - base
            edge_values[inside] = 0.0
            frame[inside] = base[inside] + self._fill(inside, edge_values)

    def _relaxed_again(self, frame: np.ndarray, base: np.ndarray, pinned: np.ndarray | None) -> int:
        """:meth:`_relax`, started afresh on what a neighbourhood grown to its cap left: a large fill
        over the thin lips can fold them elsewhere, and what it leaves is then a small fold of its own."""
        left = self._relax(frame, base, pinned)
        for _ in range(_PASSES - 1):
            if not left:
                break
            left = self._relax(frame, base, pinned)
        return left

    def _relax(self, frame: np.ndarray, base: np.ndarray, pinned: np.ndarray | None) -> int:
        """Relax one frame in place; returns the triangles still turned over."""
        turned = self.turned(frame)
        if not turned.any():
            return 0
        free = np.ones(len(frame), dtype=bool) if pinned is None else ~pinned
        region = self._grown(np.unique(self.triangles[turned]), self.rings) & free
        residual = frame - base
        for _ in range(self.rounds):
            inside = np.flatnonzero(region)
            edge_values = residual.copy()
            edge_values[inside] = 0.0
            frame[inside] = base[inside] + self._fill(inside, edge_values)
            # Only triangles touching the region changed; the rest were checked above.
            touching = np.flatnonzero(region[self.triangles].any(axis=1))
            now = touching[self._turned_among(frame, touching)]
            turned[touching] = False
            turned[now] = True
            if not turned.any() or region.sum() >= self._largest:
                break
            region |= self._grown(np.unique(self.triangles[turned]), 0)
            region = self._grown(np.flatnonzero(region), self.grow) & free
        return int(turned.sum())

    def _fill(self, inside: np.ndarray, edge_values: np.ndarray) -> np.ndarray:
        """The harmonic fill of the vertices ``inside`` (sorted ids) from ``edge_values (V, 3)`` (zero
        inside): their ``(len(inside), 3)`` values."""
        L = self._laplacian[inside]
        # The block is symmetric: a symmetric ordering factors it about a fifth faster. (Keeping the
        # factorisations of recent neighbourhoods, which often come back, saved 0.3-0.7 s of d18's
        # deformation but held 0.4 GB more at its peak on a minute of video: not done.)
        return splu(L[:, inside].tocsc(), permc_spec="MMD_AT_PLUS_A",
                    options={"SymmetricMode": True}).solve(-(L @ edge_values))

    def _turned_among(self, positions: np.ndarray, which) -> np.ndarray:
        """Of the triangles ``which`` (ids or a slice), those turned over in ``positions (V, 3)``."""
        return (self._normals(positions, which) * self._rest_normals[:, which]).sum(axis=0) < 0

    def _grown(self, vertices: np.ndarray, rings: int) -> np.ndarray:
        mask = np.zeros(len(self.rest), dtype=bool)
        mask[vertices] = True
        for _ in range(rings):
            mask |= (self._adjacency @ mask.astype(np.float64)) > 0
        return mask
