"""Surface-aware interpolation: values spread along the mesh instead of through space.

Two points on either side of a closed mouth are a millimetre apart in space but a mouth-width
apart along the skin, because the lips meet at an opening in the mesh. An RBF on Euclidean distance
lets the upper lip drag the lower one. Two ways to respect the surface are here:

* :class:`BiharmonicInterpolation`: the smoothest field on the surface (least integrated squared
  Laplacian, with the cotangent Laplacian) that takes the given values at the control vertices,
  optionally fading with distance from them; nothing crosses an opening of the mesh. This is the
  one faceanim uses.
* :class:`SurfaceRbf`: the RBF kernels on geodesic distance (heat method, Crane et al. 2013, from
  potpourri3d). Measured on ICT-FaceKit it is far worse than either: kernels of geodesic distance are
  not positive definite, and the fitted weights blow up between centres
  (``benchmarks/results/transfer_ict.md``). It stays for that comparison.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.sparse.linalg import splu

from ..validation import as_index_array
from .mesh import Mesh
from .rbf import apply_operator, rbf_operator_from_distances
from .topology import component_labels

__all__ = ["edge_graph", "geodesic_distances", "cotangent_laplacian", "BiharmonicInterpolation", "SurfaceRbf",
           "EASE", "eased_weights"]


def edge_graph(mesh: Mesh) -> sparse.csr_matrix:
    """Symmetric ``(V, V)`` sparse matrix of edge lengths, cached on the mesh."""
    def compute():
        e = mesh.edges
        length = np.linalg.norm(mesh.vertices[e[:, 0]] - mesh.vertices[e[:, 1]], axis=1)
        V = len(mesh.vertices)
        graph = sparse.coo_matrix((np.r_[length, length], (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])),
                                  shape=(V, V)).tocsr()
        for array in (graph.data, graph.indices, graph.indptr):
            array.flags.writeable = False  # handed out from the mesh's cache
        return graph

    return mesh._cached("edge_graph", compute)


def geodesic_distances(mesh: Mesh, sources) -> np.ndarray:
    """``(S, V)`` geodesic distances from each source vertex to every vertex (heat method).

    Uses potpourri3d's heat-method solver (Crane, Weischedel and Wardetzky 2013), factorised once per
    mesh. Shortest paths along edges would be simpler, but on a regular triangulation they overestimate
    diagonal distances by up to 41%. Vertices in a part of the mesh without a source get ``inf``.

    >>> m = Mesh([[0., 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0], [1, 1, 0], [2, 1, 0]],
    ...          [[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4]])
    >>> bool(abs(geodesic_distances(m, [0])[0, 2] - 2.0) < 0.1)  # within the heat method's accuracy
    True
    """
    sources = as_index_array(sources, "sources", upper=len(mesh.vertices))
    def heat_solver():
        import potpourri3d

        return potpourri3d.MeshHeatMethodDistanceSolver(mesh.vertices, mesh.triangles)

    solver = mesh._cached("heat_solver", heat_solver)
    part = component_labels(mesh)
    out = np.stack([solver.compute_distance(int(s)) for s in sources]) if len(sources) else np.zeros((0, len(part)))
    out[part[None, :] != part[sources][:, None]] = np.inf
    return out


def cotangent_laplacian(mesh: Mesh):
    """The cotangent Laplacian ``L (V, V)`` (positive semi-definite) and lumped mass ``(V,)``.

    ``L`` weights each edge by half the sum of the cotangents of the angles facing it; the mass of
    a vertex is a third of the area of its triangles. Cotangents are clamped to [-1e3, 1e3] so a
    needle triangle cannot dominate.
    """
    v, t = mesh.vertices, mesh.triangles
    V = len(v)
    rows, cols, weights = [], [], []
    for k in range(3):
        i, j, o = t[:, (k + 1) % 3], t[:, (k + 2) % 3], t[:, k]  # edge (i, j) faces the corner o
        u, w = v[i] - v[o], v[j] - v[o]
        cross = np.linalg.norm(np.cross(u, w), axis=1)
        cot = np.clip(np.einsum("ij,ij->i", u, w) / np.maximum(cross, 1e-300), -1e3, 1e3)
        rows += [i, j]
        cols += [j, i]
        weights += [0.5 * cot, 0.5 * cot]
    W = sparse.coo_matrix((np.concatenate(weights), (np.concatenate(rows), np.concatenate(cols))), shape=(V, V)).tocsr()
    L = sparse.diags(np.asarray(W.sum(axis=1)).ravel()) - W
    mass = np.zeros(V)
    np.add.at(mass, t.ravel(), np.repeat(mesh.face_areas / 3.0, 3))
    return L.tocsr(), mass


class BiharmonicInterpolation:
    """The smoothest surface field through given values at control vertices, fading with distance.

    Minimises ``f' Q f`` over the free vertices with ``f`` fixed at the controls, where
    ``Q = (k^2 M + L) M^-1 (k^2 M + L)``, ``L`` is the cotangent Laplacian, ``M`` the lumped mass and
    ``k = 1 / falloff_length``. With ``falloff=0`` (``k = 0``) this is biharmonic interpolation: the
    least integrated squared Laplacian. With ``k > 0`` it is the posterior mean of a Gaussian process
    on the surface with a Matern covariance (the SPDE view of Lindgren, Rue and Lindstroem 2011): the
    field is still exact at the controls, but relaxes to zero beyond a few ``falloff_length`` from
    them instead of extrapolating their slope. Facial motion is local (a raised brow does not move
    the scalp), and on ICT-FaceKit this prior halves the error of sparse transfer
    (``benchmarks/transfer_ict.py``). Nothing spreads across openings in the mesh (mouth, eyes).

    Parameters
    ----------
    mesh : Mesh
    control_vertices : (K,) int64
        Distinct vertex ids; every connected part of the mesh needs at least one.
    falloff : float
        Falloff length as a fraction of the controls' RMS distance from their centroid (so it does
        not depend on units); 0 for plain biharmonic interpolation.
    bounded : bool or (V,) float64
        True: no vertex moves past its controls. Each vertex's weights are the biharmonic field's made
        non-negative (:func:`eased_weights`) and scaled back to the sum the vertex had, so it takes a
        weighted mean of the controls' values (faded by the falloff as before), a uniform motion is
        carried as before, and each control lands exactly. The biharmonic weights have negative lobes,
        which overshoot wherever close controls move differently: a face's upper lid skin, between a lash
        line coming down and the skin above it held, came down past the lash line (1.06 cm against 0.91,
        ICT round trip, seed 3), and a tracker's independent errors at neighbouring points are amplified
        there rather than averaged (the median vertex of an ICT face sums 0.17 of negative weight, some
        vertices 2). Without the lobes the field is smooth but less so. An array: per vertex, the share of
        its weights so bounded (the rest biharmonic), for a field bounded in some places only. False: the
        biharmonic field.

    The ``(V, K)`` operator is computed once with a sparse factorisation; ``__call__`` maps values
    ``(K, C)`` or ``(T, K, C)`` to ``(V, C)`` or ``(T, V, C)``.

    Examples
    --------
    >>> m = Mesh([[0., 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]])
    >>> BiharmonicInterpolation(m, [0, 1, 2], falloff=0)(np.array([[1.], [1.], [1.]]))[3]
    array([1.])
    """

    def __init__(self, mesh: Mesh, control_vertices, *, falloff: float = 0.25, bounded=False):
        ids = _distinct_ids(mesh, control_vertices)
        falloff = float(falloff)
        if not np.isfinite(falloff) or falloff < 0:
            raise ValueError(f"falloff must be a finite number >= 0, got {falloff}")
        V = len(mesh.vertices)
        unconstrained = np.setdiff1d(np.arange(V), np.unique(mesh.triangles))
        if len(unconstrained):
            raise ValueError(f"{len(unconstrained)} vertices (first: {unconstrained[:5].tolist()}) belong to no "
                             "triangle; remove them before interpolating on the surface")
        part = component_labels(mesh)
        uncovered = np.setdiff1d(np.unique(part), part[ids])
        if len(uncovered):
            first = np.flatnonzero(part == uncovered[0])[:5].tolist()
            raise ValueError(f"{len(uncovered)} connected parts of the mesh hold no control vertex "
                             f"(vertices {first}, ...); give each part a control vertex or remove it")
        L, mass = cotangent_laplacian(mesh)
        mass = np.maximum(mass, mass[mass > 0].min())
        centres = mesh.vertices[ids]
        radius = np.sqrt(((centres - centres.mean(axis=0)) ** 2).sum(axis=1).mean())
        k2 = 0.0 if falloff == 0 or radius == 0 else 1.0 / (falloff * radius) ** 2
        A = (k2 * sparse.diags(mass) + L).tocsr()
        Q = (A.T @ sparse.diags(1.0 / mass) @ A).tocsc()
        free = np.ones(V, dtype=bool)
        free[ids] = False
        free_ids = np.flatnonzero(free)
        operator = np.zeros((V, len(ids)))
        operator[ids, np.arange(len(ids))] = 1.0
        if len(free_ids):
            Qff = Q[free_ids][:, free_ids].tocsc()
            Qfc = Q[free_ids][:, ids].toarray()
            operator[free_ids] = -splu(Qff).solve(Qfc)
        share = np.broadcast_to(np.asarray(bounded, dtype=np.float64), (V,))
        if not (np.isfinite(share).all() and (share >= 0).all() and (share <= 1).all()):
            raise ValueError("bounded must be a bool or shares in [0, 1], one per vertex")
        if share.any():
            operator = (1.0 - share[:, None]) * operator + share[:, None] * _nonnegative_weights(operator)
            operator[ids] = 0.0
            operator[ids, np.arange(len(ids))] = 1.0  # exact at the controls, whatever the rounding
        self.control_vertices = ids
        self.falloff = falloff
        self.operator = operator

    def __call__(self, values) -> np.ndarray:
        return apply_operator(self.operator, values)


EASE = 0.05  # a weight under this is eased in (``w^2 / (2 EASE)``) rather than cut at 0: see eased_weights


def eased_weights(weights: np.ndarray) -> np.ndarray:
    """``weights`` with the negative ones set to 0 along a curve with no kink: ``w^2 / (2 EASE)`` for
    ``0 <= w < EASE``, ``w - EASE / 2`` above. Cut at 0 outright, a weight leaves a crease in the field
    along the line where it crosses 0, which showed on a raised brow (ICT round trip, seed 3)."""
    w = np.maximum(weights, 0.0)
    return np.where(w < EASE, w * w / (2 * EASE), w - EASE / 2)


def _nonnegative_weights(operator: np.ndarray) -> np.ndarray:
    """``operator (V, K)`` with each row's weights eased to non-negative (:func:`eased_weights`) and scaled
    to the row's former sum (a row whose sum is not positive, or which has no positive weight, becomes 0).
    On the round trip's tuning seeds the eased cut and the plain one scored alike (all segments 0.512 and
    0.511, mean of the medians; blink 0.582 and 0.571)."""
    total = operator.sum(axis=1)
    positive = eased_weights(operator)
    kept = positive.sum(axis=1)
    scale = np.divide(np.maximum(total, 0.0), kept, out=np.zeros_like(kept), where=kept > 0)
    positive *= scale[:, None]
    return positive


class SurfaceRbf:
    """An RBF over a mesh's vertices that measures distance along the surface.

    Fitted to a set of control vertices; maps values at them (displacements ``(K, 3)`` or frames
    ``(T, K, 3)``) to values at every vertex.

    Parameters
    ----------
    mesh : Mesh
    control_vertices : (K,) int64
        Distinct vertex ids.
    kernel, smoothing
        As for :class:`~faceanim.geometry.rbf.RbfWarp`. The affine term of ``thin_plate``,
        ``cubic`` and ``linear`` uses the vertices' positions, so rigid and affine motion are still
        reproduced exactly.

    Raises
    ------
    ValueError
        Repeated control vertices, or a vertex that no control vertex can reach along the surface.
    """

    def __init__(self, mesh: Mesh, control_vertices, *, kernel: str = "thin_plate", smoothing: float | None = None):
        ids = _distinct_ids(mesh, control_vertices)
        distances = geodesic_distances(mesh, ids)  # (K, V)
        unreachable = ~np.isfinite(distances).any(axis=0)
        if unreachable.any():
            raise ValueError(f"{int(unreachable.sum())} vertices (first: {np.flatnonzero(unreachable)[:5].tolist()}) "
                             "are not connected to any control vertex along the surface")
        # A vertex in a component without some control vertex is infinitely far from it; the kernel
        # then must not see inf, so such distances are capped at the largest finite one.
        finite_max = distances[np.isfinite(distances)].max()
        distances = np.where(np.isfinite(distances), distances, 2 * finite_max)
        # Heat-method distances are close to, but not exactly, symmetric with a zero diagonal; the
        # kernel system needs both.
        between = 0.5 * (distances[:, ids] + distances[:, ids].T)
        np.fill_diagonal(between, 0.0)
        to_points = distances.T.copy()
        to_points[ids] = between
        self.control_vertices = ids
        self.operator = rbf_operator_from_distances(
            between, to_points, kernel=kernel, smoothing=smoothing,
            centre_positions=mesh.vertices[ids], point_positions=mesh.vertices)

    def __call__(self, values) -> np.ndarray:
        """Values at every vertex: ``(V, C)`` or ``(T, V, C)``."""
        return apply_operator(self.operator, values)


def _distinct_ids(mesh: Mesh, control_vertices) -> np.ndarray:
    ids = as_index_array(control_vertices, "control_vertices", upper=len(mesh.vertices))
    unique, counts = np.unique(ids, return_counts=True)
    if (counts > 1).any():
        raise ValueError(f"control_vertices must be distinct; repeated: {unique[counts > 1][:10].tolist()}")
    return ids
