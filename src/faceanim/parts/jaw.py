"""How much of the jaw's turn each skin vertex follows: a harmonic field along the skin, eased away
from the lips (:func:`_eased`), kept from folding the skin at the widest turn (:func:`unfolded_jaw_weight`)."""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import dijkstra
from scipy.sparse.linalg import spsolve
from scipy.spatial import cKDTree

from ..geometry.mesh import Mesh
from ..geometry.surface import cotangent_laplacian
from ..geometry.topology import component_labels, submesh
from ..target import Target
from .faceparts import _LOWER_LIP, _UPPER_LIP
from .frame import _Frame, _smoothstep

__all__ = ["unfolded_jaw_weight", "turned_vectors"]

# How much of its rest length (along itself) a skin edge keeps, at least, under the jaw's turn alone.
KEPT_ALONG = 0.3
# The skin's jaw weight is eased over this many mouth widths (the diffusion's length), away from the
# lips: within LIPS_HELD mouth widths of the lips' control points it keeps its harmonic value.
EASED_OVER, LIPS_HELD = 0.3, 0.25


def turned_vectors(vectors, axis, angles) -> np.ndarray:
    """``vectors (..., 3)`` turned about the unit ``axis`` by ``angles`` (radians, broadcast against the
    vectors' leading axes), Rodrigues' formula: what the jaw's turn does to a vector."""
    vectors = np.asarray(vectors, dtype=np.float64)
    angles = np.asarray(angles, dtype=np.float64)[..., None]
    cos, sin = np.cos(angles), np.sin(angles)
    return vectors * cos + np.cross(axis, vectors) * sin + axis * (vectors @ axis)[..., None] * (1 - cos)


def _skin_jaw_weight(mesh: Mesh, skin: np.ndarray, frame: _Frame, target: Target) -> np.ndarray:
    """``(S,)`` the jaw's share of each skin vertex: harmonic along the skin between the chin (1) and
    the upper lip, the ears and the neck (0), then eased away from the lips (:func:`_eased`)."""
    ids = np.flatnonzero(skin)
    sub, index_of = submesh(mesh, skin)
    tris = sub.triangles
    local = frame.local(mesh.vertices[ids])
    x, y, z = local.T
    chin, mouth, hinge = frame.chin, frame.mouth, frame.hinge_local
    w = frame.mouth_width
    depth = chin[2] - hinge[2]
    # The jaw line runs from the chin back to below the hinge; the neck lies under it. The line the
    # jaw's skin ends at above runs from the lip line at the mouth back to the hinge.
    corners = [frame.local_points[n] for n in ("2.13", "2.14") if n in frame.local_points]
    gonion = np.mean(corners, axis=0) if corners else chin + 0.45 * (hinge - chin)
    slope = (gonion[1] - chin[1]) / max(chin[2] - gonion[2], 0.1 * w)
    under_jaw = chin[1] + slope * (chin[2] - z) - y
    back = np.clip((mouth[2] - z) / (mouth[2] - hinge[2]), 0.0, 1.0)
    above = y - (mouth[1] + (hinge[1] - mouth[1]) * back)
    # Beside the mouth the jaw's full share starts a band below that line; on the lower lip, at it.
    # In the middle the lips themselves are pinned (below); the jaw's full share starts under the lower lip.
    lip_bottom = frame.local_points["8.2"][1] if "8.2" in frame.local_points else mouth[1] - 0.1 * w
    band = np.maximum(0.3 * w * _smoothstep(np.abs(x - mouth[0]) / (0.5 * w)), mouth[1] - lip_bottom)
    fixed = np.full(len(ids), np.nan)
    fixed[(above < -band) & (under_jaw < 0.02 * w) & (z > hinge[2] + 0.25 * depth)] = 1.0
    fixed[above > 0.1 * w] = 0.0  # the upper lip and everything above
    fixed[z < hinge[2]] = 0.0  # the ears and the back of the head
    fixed[under_jaw > 0.8 * w] = 0.0  # the neck, well below the jaw line: the skin between stretches
    # The lips meet at the lip line, so height cannot tell them apart there; their control points can.
    for names, value in ((_UPPER_LIP, 0.0), (_LOWER_LIP, 1.0)):
        pinned = index_of[[target.points[n] for n in names if n in target.points]]
        fixed[pinned[pinned >= 0]] = value
    if not (fixed == 1).any():
        return np.zeros(len(ids))
    if not len(tris):
        return np.nan_to_num(fixed)
    L, mass = cotangent_laplacian(sub)
    # Vertices in no skin triangle, and skin islands with no fixed vertex, hold 0.
    used = np.zeros(len(ids), dtype=bool)
    used[np.unique(tris)] = True
    fixed[~used] = 0.0
    labels = component_labels(sub)
    for k in np.unique(labels):
        island = labels == k
        if np.isnan(fixed[island]).all():
            fixed[island] = 0.0
    free = np.isnan(fixed)
    out = np.nan_to_num(fixed)
    if free.any():
        L = sparse.csr_matrix(L)
        A = L[free][:, free]
        b = -L[free][:, ~free] @ out[~free]
        out[free] = spsolve(A.tocsc(), b)
    lips = mesh.vertices[[target.points[n] for n in _UPPER_LIP + _LOWER_LIP if n in target.points]]
    held = ~used
    if len(lips):
        held |= cKDTree(lips).query(mesh.vertices[ids], distance_upper_bound=LIPS_HELD * w)[0] < np.inf
    return np.clip(_eased(out, L, mass, held, (EASED_OVER * w) ** 2), 0.0, 1.0)


def _eased(weight, laplacian, mass, held, spread) -> np.ndarray:
    """``weight`` diffused over the surface for a time ``spread`` (a length squared), the ``held``
    vertices keeping their values: one implicit step, ``(M + spread L) w' = M w``.

    A harmonic weight runs straight from the edge of one region it is fixed in to the next and meets
    each with a kink; turned by the jaw, every kink is a crease in the skin (d18 onto the ICT head at
    its widest, frame 83: creases down the cheeks from the mouth's corners and along the jaw). The
    regions blur too: on the ICT head the chin's lowest point (2.1) falls from 1 to 0.87 and the jaw's
    corners (2.13, 2.14) to about 0.4, which the fit to the motion (``PartsDeformer.fitted_jaw_weight``)
    sets again at every control point. The caller holds the lips because, eased, the upper lip would
    take jaw weight from the corners between its control points and tear as the mouth opens."""
    free = np.flatnonzero(~held)
    if not len(free) or spread <= 0 or not (mass > 0).any():
        return weight
    mass = np.maximum(mass, mass[mass > 0].min())
    step = (sparse.diags(mass) + spread * sparse.csr_matrix(laplacian)).tocsr()
    out = np.array(weight, dtype=np.float64)
    still = np.flatnonzero(held)
    out[free] = spsolve(step[free][:, free].tocsc(), mass[free] * out[free] - step[free][:, still] @ out[still])
    return out


def unfolded_jaw_weight(rest, triangles, weight, hinge, axis, angles, *, movable=None) -> np.ndarray:
    """``(V,)`` ``weight`` raised where turning by it would fold the surface.

    A vertex turned by its weight ``w`` moves by ``w (R - I)(x - h)`` (``R`` the turn by an angle
    about ``axis`` through ``hinge``). Where ``w`` falls steeply along the way the turn swings (under
    the chin, towards the neck; across the mouth's corners when the jaw closes past rest), the skin
    with the higher weight swings into the skin beside it and the triangles between turn over. A
    triangle keeps each corner's height over the opposite edge at least :data:`KEPT_ALONG` of its rest
    height while the corner's weight and each of the edge's ends' differ by less than a bound set by
    that height and the swing across it (so a sliver, whose height is a hair, keeps its three weights
    nearly equal). These are difference constraints, so the least raise of the lower weights that
    meets them all is a shortest-path problem (Dijkstra from a virtual source, the bounds as edge
    lengths): the neck goes along with the chin a little further down, the chin keeps its weight.

    Parameters
    ----------
    rest : (V, 3) float64
    triangles : (F, 3) int64
        The triangles of the surface that must not fold.
    weight : (V,) float64
        In [0, 1].
    hinge, axis : (3,) float64
        The turn's centre and axis (opening turns are positive angles about ``axis``).
    angles : array-like of float
        The turns the motion makes (radians); its widest opening and its furthest closing are kept from folding.
    movable : (V,) bool, optional
        The vertices whose weight may be raised (default all).
    """
    weight = np.asarray(weight, dtype=np.float64)
    angles = np.asarray(angles, dtype=np.float64).ravel()
    extremes = [t for t in (angles.max(initial=0.0), angles.min(initial=0.0)) if t != 0]
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    if not extremes or not weight.any() or not len(triangles):
        return weight
    rest = np.asarray(rest, dtype=np.float64)
    a = np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)
    K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    high, low, room = [], [], []
    for corner in range(3):
        k, i, j = (triangles[:, (corner + n) % 3] for n in range(3))
        base = rest[j] - rest[i]
        up = rest[k] - rest[i]
        # The corner's height over the opposite edge, and the unit direction it is measured along.
        across = up - base * (np.einsum("ij,ij->i", up, base) / np.maximum(np.einsum("ij,ij->i", base, base),
                                                                           1e-300))[:, None]
        height = np.linalg.norm(across, axis=1)
        usable = height > 0
        k, i, j, across, height = k[usable], i[usable], j[usable], across[usable], height[usable]
        direction = across / height[:, None]
        apart = rest[k] - 0.5 * (rest[i] + rest[j])
        for angle in extremes:
            swing = np.sin(angle) * K + (1 - np.cos(angle)) * (K @ K)  # R - I
            # The corner's new height: height + w_mean (R - I) apart . dir + (w_k - w_edge) (R - I) r_k . dir.
            # The middle term is no lower than with w_mean = 1 (or 0), so the bound holds whatever the
            # weights become; w_k - w_edge is bounded through w_k - w_i and w_k - w_j.
            kept = height + np.minimum(0.0, np.einsum("ij,ij->i", apart @ swing.T, direction))
            lift = np.einsum("ij,ij->i", (rest[k] - hinge) @ swing.T, direction)
            bound = np.maximum(kept - KEPT_ALONG * height, 0.0) / np.maximum(np.abs(lift), 1e-300)
            for end in (i, j):
                high.append(np.where(lift < 0, k, end))  # the bound is on w[high] - w[low]
                low.append(np.where(lift < 0, end, k))
                room.append(bound)
    high, low, room = np.concatenate(high), np.concatenate(low), np.concatenate(room)
    V = len(weight)
    if movable is not None:
        free = np.asarray(movable, dtype=bool)[low]
        high, low, room = high[free], low[free], room[free]
    # Shortest paths of 1 - w: from the virtual source V to each vertex at its own 1 - w, and along
    # each pair from high to low at the tightest of its bounds (a sparse matrix would sum repeated
    # entries, so they are reduced first). A zero-length edge would vanish from a sparse graph,
    # hence the tiny length added.
    tiny = 1e-12
    key = high * (V + 1) + low
    order = np.lexsort((room, key))
    first = np.r_[True, key[order][1:] != key[order][:-1]]
    high, low, room = high[order][first], low[order][first], room[order][first]
    lengths = np.r_[room + tiny, 1.0 - weight + tiny]
    graph = sparse.csr_matrix((lengths, (np.r_[high, np.full(V, V)], np.r_[low, np.arange(V)])), shape=(V + 1, V + 1))
    raised = 1.0 - dijkstra(graph, directed=True, indices=V)[:V]
    return np.clip(raised, weight, 1.0)
