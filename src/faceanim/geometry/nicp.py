"""Dense registration: non-rigid ICP in the optimal-step form (Amberg, Romdhani & Vetter, CVPR 2007).

A source mesh is deformed onto a target surface by an affine transform per source vertex,
``x_i' = X_i^T [x_i, 1]`` with ``X_i (4, 3)``. For a fixed set of closest-point correspondences the
best transforms solve one sparse linear least-squares problem,

    min  alpha^2 sum_edges ||G (X_i - X_j)||^2                 (stiffness; G = diag(1, 1, 1, gamma))
       + sum_i w_i ||X_i^T [x_i, 1] - u_i||^2                  (data: u_i the closest target point)
       + beta^2 sum_landmarks ||X_l^T [x_l, 1] - p_l||^2       (landmarks)

whose normal equations are factorised with SuperLU (:func:`scipy.sparse.linalg.splu`). The
stiffness ``alpha`` runs down a schedule (stiff to loose); at each stiffness, correspondences and
transforms alternate until the transforms stop changing. A correspondence is refused (``w_i = 0``)
when the closest target point lies on the target's open boundary, when the target triangle there
faces more than ``max_angle`` away from the source vertex's normal, or when it is farther than
``max_distance``.

Everything is solved in normalised coordinates (the source centred on its mean and divided by its
RMS radius), so the options mean the same for a face in millimetres, centimetres or metres.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.sparse import linalg as splinalg
from scipy.spatial import cKDTree

from ..errors import InputError
from ..validation import as_array
from .mesh import Mesh
from .project import closest_point_on_triangles, project_points
from .topology import open_edges

__all__ = ["NicpOptions", "Registration", "register_surface"]

_SHADOW = 0.7  # see _correspondences
_TIKHONOV = 1e-6  # weight of ||X - I||^2, in normalised units
_CANDIDATES = 24  # target triangles examined per source vertex, nearest centroids first


@dataclass(frozen=True)
class NicpOptions:
    """Settings of :func:`register_surface` (all lengths relative to the source's RMS radius).

    stiffness
        The schedule of ``alpha``, stiff to loose.
    landmark_weight
        ``beta`` at each stiffness (one value for all, or one per stage).
    iterations
        The most correspondence/solve rounds at one stiffness.
    tolerance
        A stage ends when no vertex's transform moved it by more than this.
    gamma
        Weight of the translation part of the stiffness (Amberg's ``gamma``).
    max_angle
        Degrees: correspondences across target triangles facing farther away are refused.
    max_distance
        Correspondences farther than this are refused.
    fit_tolerance, landmark_tolerance
        After the last stage: the median distance from the mesh that covers less onto the other (the
        target's vertices onto the registered source, or the source's onto the target, whichever is
        nearer: a face-only source on a whole head lies on it), and the RMS landmark error (weighted
        by the landmarks' weights), above which the registration is declared failed.
    reverse_weight
        Weight of the reverse data term, relative to the forward one: each target vertex pulls the
        closest compatible point of the source surface (the same angle and distance tests, refused
        on the source's open border) onto itself, so every part of the target is covered, up to its
        own border, even where the source runs on beyond it (a lip that turns into a mouth socket
        the target lacks). The term is scaled by the ratio of the vertex counts, so it weighs the
        same whatever the target's resolution. 0 turns it off (Amberg's one-way data term).
    """

    stiffness: tuple = (50.0, 20.0, 10.0, 5.0, 2.0, 1.0, 0.5)
    landmark_weight: tuple | float = 3.0
    iterations: int = 3
    tolerance: float = 1e-4
    gamma: float = 1.0
    max_angle: float = 45.0
    max_distance: float = 0.1
    fit_tolerance: float = 0.01
    landmark_tolerance: float = 0.02
    reverse_weight: float = 0.0

    def __post_init__(self):
        if not self.stiffness or any(not a > 0 for a in self.stiffness):
            raise ValueError(f"stiffness must be a non-empty schedule of positive numbers, got {self.stiffness}")
        weights = np.atleast_1d(np.asarray(self.landmark_weight, dtype=np.float64))
        if len(weights) not in (1, len(self.stiffness)) or (weights < 0).any():
            raise ValueError(f"landmark_weight must be one number >= 0 or one per stiffness stage "
                             f"({len(self.stiffness)}), got {self.landmark_weight}")
        if not 0 < self.max_angle <= 180:
            raise ValueError(f"max_angle must be in (0, 180] degrees, got {self.max_angle}")
        if self.iterations < 1:
            raise ValueError(f"iterations must be >= 1, got {self.iterations}")
        if not self.reverse_weight >= 0:
            raise ValueError(f"reverse_weight must be >= 0, got {self.reverse_weight}")

    def betas(self) -> np.ndarray:
        return np.broadcast_to(np.asarray(self.landmark_weight, dtype=np.float64), (len(self.stiffness),))


@dataclass(frozen=True, eq=False)
class Registration:
    """The source mesh deformed onto the target.

    ``vertices (V, 3)`` the registered source positions (target units and frame), ``matched (V,)``
    which source vertices had an accepted correspondence in the last round, ``fit`` the median of
    the target vertices' distances to the registered source surface or of the registered source's
    vertices' to the target's, the smaller, and
    ``landmark_error`` the RMS distance of the registered source landmarks from their targets, each
    weighted by its landmark weight (both in target units; 0 without landmarks), ``solves`` the number
    of sparse solves.
    """

    vertices: np.ndarray
    matched: np.ndarray
    fit: float
    landmark_error: float
    solves: int


def register_surface(source: Mesh, target: Mesh, *, source_landmarks=(), target_points=None,
                     landmark_weights=None, initial=None, options: NicpOptions | None = None) -> Registration:
    """Register ``source`` onto ``target``'s surface by optimal-step non-rigid ICP.

    Parameters
    ----------
    source, target : Mesh
        Any triangulations. Only source vertices used by a triangle are moved by the data term.
    source_landmarks : (L,) int64
        Source vertex ids held to ``target_points``.
    target_points : (L, 3) float64
        Where those vertices must land (points on or near the target surface, target units).
    landmark_weights : (L,) float64, optional
        Relative weight of each landmark (1 by default).
    initial : (V, 3) float64, optional
        Starting positions of the source vertices (for example a warp through the landmarks);
        the source's own positions by default.
    options : NicpOptions, optional

    Returns
    -------
    Registration

    Raises
    ------
    InputError
        The registration did not reach the target: the fit or the (weighted) landmark error after the last
        stage exceeds ``options.fit_tolerance`` / ``options.landmark_tolerance`` (times the
        source's RMS radius). The message gives the residuals reached.

    Examples
    --------
    >>> from faceanim.geometry.mesh import Mesh
    >>> g = np.linspace(0, 1, 6)
    >>> xy = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    >>> tris = np.array([[i * 6 + j, i * 6 + j + 1, i * 6 + j + 7] for i in range(5) for j in range(5)]
    ...                 + [[i * 6 + j, i * 6 + j + 7, i * 6 + j + 6] for i in range(5) for j in range(5)])
    >>> flat = Mesh(np.c_[xy, np.zeros(36)], tris)
    >>> reg = register_surface(flat, flat.with_vertices(flat.vertices + [0, 0, 0.01]))
    >>> bool(np.allclose(reg.vertices[:, 2], 0.01, atol=1e-6))
    True
    """
    options = NicpOptions() if options is None else options
    ids = np.asarray(source_landmarks, dtype=np.int64).reshape(-1)
    if len(ids) and (ids.min() < 0 or ids.max() >= len(source.vertices)):
        raise ValueError(f"source_landmarks must be vertex ids in [0, {len(source.vertices)}), "
                         f"got range [{ids.min()}, {ids.max()}]")
    points = as_array(np.zeros((0, 3)) if target_points is None else target_points, "target_points",
                      shape=(len(ids), 3))
    lw = np.ones(len(ids)) if landmark_weights is None else as_array(landmark_weights, "landmark_weights",
                                                                      shape=(len(ids),))
    start = source.vertices if initial is None else as_array(initial, "initial", shape=source.vertices.shape)

    origin = start.mean(axis=0)
    scale = float(np.sqrt(((start - origin) ** 2).sum(axis=1).mean())) or 1.0
    x = (start - origin) / scale
    tgt = Mesh((target.vertices - origin) / scale, target.triangles)
    lm_points = (points - origin) / scale
    corners = tgt.vertices[tgt.triangles]
    centroids = corners.mean(axis=1)
    reach = float(np.linalg.norm(corners - centroids[:, None], axis=2).max())
    search = (cKDTree(centroids), reach, *_border_flags(tgt))
    n = len(x)

    stiffness_matrix = _stiffness(source, options.gamma)
    spacing = float(np.median(np.linalg.norm(x[source.edges[:, 0]] - x[source.edges[:, 1]], axis=1)))
    homog = np.c_[x, np.ones(n)]
    D = sparse.csr_matrix((homog.ravel(), (np.repeat(np.arange(n), 4), np.arange(4 * n))), shape=(n, 4 * n))
    DL = D[ids]
    current = x.copy()
    identity = np.tile(np.vstack([np.eye(3), np.zeros((1, 3))]), (n, 1))  # (4n, 3): X_i = I for every vertex
    used = np.zeros(n, dtype=bool)
    used[np.unique(source.triangles)] = True
    reverse = None
    if options.reverse_weight > 0:
        t_used = np.unique(tgt.triangles)
        reverse = (t_used, tgt.vertex_normals[t_used], *_border_flags(Mesh(x, source.triangles)),
                   options.reverse_weight * used.sum() / len(t_used))
    solves = 0
    matched = np.zeros(n, dtype=bool)
    for alpha, beta in zip(options.stiffness, options.betas(), strict=True):
        for _ in range(options.iterations):
            u, matched = _correspondences(source.triangles, current, tgt, search, used, options.max_angle,
                                          options.max_distance, spacing)
            w = matched.astype(np.float64)
            Dw = sparse.diags(w) @ D
            lhs = alpha * alpha * stiffness_matrix + (Dw.T @ D)
            rhs = Dw.T @ u
            if reverse is not None:
                R, r_points, r_weight = _reverse(source.triangles, homog, current, tgt.vertices, reverse,
                                                 options.max_angle, options.max_distance)
                Rw = sparse.diags(np.full(R.shape[0], r_weight)) @ R
                lhs = lhs + Rw.T @ R
                rhs = rhs + Rw.T @ r_points
            if len(ids):
                Lw = sparse.diags(beta * beta * lw) @ DL
                lhs = lhs + Lw.T @ DL
                rhs = rhs + Lw.T @ lm_points
            # A faint pull towards the identity keeps directions no data reaches (a flat source's
            # normal) determined.
            lhs = lhs + _TIKHONOV * sparse.eye(4 * n)
            rhs = np.asarray(rhs) + _TIKHONOV * identity
            X_new = _solve(sparse.csc_matrix(lhs), rhs)
            solves += 1
            moved = D @ X_new
            change = np.sqrt(((moved - current) ** 2).sum(axis=1)).max()
            current = moved
            if change < options.tolerance:
                break

    vertices = current * scale + origin
    registered = Mesh(vertices, source.triangles)
    # Measured both ways, the nearer taken: a face-only source (the generic face) registered onto a whole head
    # lies on it while most of the head (scalp, neck, ears) lies far from the face, and the other way round
    # for ICT's head onto a face region.
    target_off = float(np.median(project_points(registered, target.vertices[np.unique(target.triangles)]).distances))
    source_off = float(np.median(project_points(target, vertices[used]).distances))
    fit = min(target_off, source_off)
    # Weighted: a landmark given a faint weight is a soft pull the registration need not reach (the eyelids' skin
    # placed by relative height, contours.lid_bands), and unweighted, many of them could fail a good registration.
    landmark_error = float(np.sqrt((lw * ((vertices[ids] - points) ** 2).sum(axis=1)).sum() / lw.sum())) \
        if len(ids) and lw.sum() > 0 else 0.0
    if fit > options.fit_tolerance * scale or landmark_error > options.landmark_tolerance * scale:
        raise InputError(
            f"the dense registration did not converge: half the target lies farther than {target_off:.3g} of the "
            f"registered source and half the source farther than {source_off:.3g} of the target (tolerance "
            f"{options.fit_tolerance * scale:.3g}) and the landmarks are {landmark_error:.3g} from "
            f"their places (weighted RMS; tolerance {options.landmark_tolerance * scale:.3g}), in the meshes' units; "
            + ("give corresponding landmarks to start from" if not len(ids) else
               "check that the control pairs mark the same places on both meshes"))
    return Registration(vertices, matched, fit, landmark_error, solves)


def _stiffness(mesh: Mesh, gamma: float) -> sparse.csr_matrix:
    """``(M kron G)^T (M kron G)`` for the mesh's edges: ``(4V, 4V)``."""
    e = mesh.edges
    n = len(mesh.vertices)
    m = len(e)
    incidence = sparse.csr_matrix((np.r_[np.ones(m), -np.ones(m)], (np.r_[np.arange(m), np.arange(m)],
                                                                     np.r_[e[:, 0], e[:, 1]])), shape=(m, n))
    laplacian = (incidence.T @ incidence).tocsr()
    return sparse.kron(laplacian, sparse.diags([1.0, 1.0, 1.0, gamma * gamma]), format="csr")


def _border_flags(mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
    """Per triangle, whether the edge opposite each corner is open ``(F, 3) bool``; per vertex, whether
    it lies on the open border ``(V,) bool``."""
    t = mesh.triangles
    border_edges = open_edges(t)
    opposite = np.zeros(t.shape, dtype=bool)
    if len(border_edges):
        keys = border_edges[:, 0] * len(mesh.vertices) + border_edges[:, 1]
        for corner in range(3):
            a, b = t[:, (corner + 1) % 3], t[:, (corner + 2) % 3]
            opposite[:, corner] = np.isin(np.minimum(a, b) * len(mesh.vertices) + np.maximum(a, b), keys)
    vertex = np.zeros(len(mesh.vertices), dtype=bool)
    vertex[border_edges.ravel()] = True
    return opposite, vertex


def _correspondences(source_triangles, current, target: Mesh, search, used, max_angle, max_distance, spacing):
    """Closest compatible target points ``(V, 3)`` for the current source positions, and which are accepted.

    Candidates are the ``_CANDIDATES`` target triangles whose centroids are nearest; a vertex whose
    compatible triangles all lie farther than ``max_distance`` is refused rather than searched for.
    """
    tree, reach, opposite, border_vertex = search
    normals = Mesh(current, source_triangles).vertex_normals
    cos_limit = np.cos(np.radians(max_angle))
    accepted = used.copy()
    rows = np.flatnonzero(used)
    k = min(_CANDIDATES, len(target.triangles))
    _, cand = tree.query(current[rows], k=k, distance_upper_bound=max_distance + reach)
    cand = cand.reshape(len(rows), k)
    valid = cand < len(target.triangles)
    cand = np.where(valid, cand, 0)
    q = np.repeat(rows, k)
    closest, bary = closest_point_on_triangles(current[q], target.vertices[target.triangles[cand.ravel()]])
    d = np.linalg.norm(closest - current[q], axis=1).reshape(len(rows), k)
    facing = np.einsum("nd,nkd->nk", normals[rows], target.face_normals[cand]) > cos_limit
    d = np.where(valid, d, np.inf)
    everywhere = _best(d, k, cand, bary)       # Amberg's test: the plain closest point must not be on the border
    compatible = _best(np.where(facing, d, np.inf), k, cand, bary)  # the closest one facing the same way
    eps = 1e-9
    beyond = np.zeros(len(rows), dtype=bool)
    for face, weights in (everywhere[1:3], compatible[1:3]):
        on_open_edge = (opposite[face] & (weights < eps)).any(axis=1)
        at_border_vertex = (border_vertex[target.triangles[face]] & (weights > 1 - eps)).any(axis=1)
        beyond |= on_open_edge | at_border_vertex
    best_d, _, _, pick = compatible
    ok = np.isfinite(best_d) & (best_d < max_distance) & ~beyond
    points = current.copy()
    points[rows] = closest[pick]
    # A vertex behind another layer of the source (a socket behind an eyelid) sees the target through
    # it: refused when another source vertex lies much nearer its target point than it does.
    nearest, which = cKDTree(current).query(points[rows])
    behind = (which != rows) & (nearest < _SHADOW * best_d) & (best_d > _SHADOW * spacing)
    accepted[rows] = ok & ~behind
    return points, accepted


def _reverse(source_triangles, homog, current, target_vertices, reverse, max_angle, max_distance):
    """The reverse data term: rows ``(R, 4V)`` mapping the transforms to the closest compatible source points
    of the accepted target vertices, and those target vertices ``(R, 3)``."""
    t_used, t_normals, opposite, border_vertex, weight = reverse
    tris = source_triangles
    corners = current[tris]
    centroids = corners.mean(axis=1)
    reach = float(np.linalg.norm(corners - centroids[:, None], axis=2).max())
    k = min(_CANDIDATES, len(tris))
    pts = target_vertices[t_used]
    _, cand = cKDTree(centroids).query(pts, k=k, distance_upper_bound=max_distance + reach)
    cand = cand.reshape(len(pts), k)
    valid = cand < len(tris)
    cand = np.where(valid, cand, 0)
    closest, bary = closest_point_on_triangles(np.repeat(pts, k, axis=0), corners[cand.ravel()])
    d = np.where(valid, np.linalg.norm(closest - np.repeat(pts, k, axis=0), axis=1).reshape(len(pts), k), np.inf)
    face_normals = Mesh(current, tris).face_normals
    facing = np.einsum("nd,nkd->nk", t_normals, face_normals[cand]) > np.cos(np.radians(max_angle))
    best_d, face, weights, _ = _best(np.where(facing, d, np.inf), k, cand, bary)
    eps = 1e-9
    on_border = (opposite[face] & (weights < eps)).any(axis=1) | \
        (border_vertex[tris[face]] & (weights > 1 - eps)).any(axis=1)
    ok = np.isfinite(best_d) & (best_d < max_distance) & ~on_border
    face, weights = face[ok], weights[ok]
    n = len(current)
    rows = np.repeat(np.arange(ok.sum()), 12)
    corner_ids = tris[face]                                    # (R, 3)
    cols = (4 * corner_ids[:, :, None] + np.arange(4)).reshape(-1, 12)
    vals = (weights[:, :, None] * homog[corner_ids]).reshape(-1, 12)
    R = sparse.csr_matrix((vals.ravel(), (rows, cols.ravel())), shape=(ok.sum(), 4 * n))
    return R, pts[ok], weight


def _best(d, k, cand, bary):
    """Per row of candidate distances ``d (N, k)``: the least distance, its triangle, barycentric weights
    and its flat index into the candidates."""
    j = d.argmin(axis=1)
    row = np.arange(len(d))
    pick = row * k + j
    return d[row, j], cand.ravel()[pick], bary[pick], pick


def _solve(lhs: sparse.csc_matrix, rhs: np.ndarray) -> np.ndarray:
    with warnings.catch_warnings():
        warnings.simplefilter("error", sparse.SparseEfficiencyWarning)
        lu = splinalg.splu(lhs, permc_spec="MMD_AT_PLUS_A", options={"SymmetricMode": True, "DiagPivotThresh": 0.0})
    return lu.solve(rhs)
