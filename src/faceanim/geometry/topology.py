"""Connectivity of a triangle mesh: its connected parts, the ordered loops of its open boundary, and what
follows from the edges alone (nearest neighbours along them, the graph Laplacian's harmonic fill)."""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph
from scipy.sparse.linalg import splu

from .mesh import Mesh

__all__ = ["component_labels", "boundary_loops", "open_edges", "shared_edges", "submesh", "nearest_neighbour_on",
           "harmonic_fill", "vertex_adjacency"]


def component_labels(mesh: Mesh) -> np.ndarray:
    """``(V,) int64``: the connected part (through triangle edges) each vertex belongs to; cached.

    A vertex in no triangle is a part of its own.

    >>> m = Mesh([[0., 0, 0], [1, 0, 0], [0, 1, 0], [5, 0, 0], [6, 0, 0], [5, 1, 0]], [[0, 1, 2], [3, 4, 5]])
    >>> component_labels(m).tolist()
    [0, 0, 0, 1, 1, 1]
    """
    def compute():
        V, e = len(mesh.vertices), mesh.edges
        graph = sparse.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(V, V))
        return csgraph.connected_components(graph, directed=False)[1].astype(np.int64)

    return mesh._cached("component_labels", compute)


def open_edges(triangles) -> np.ndarray:
    """``(E, 2) int64``: the edges (each row sorted) that only one triangle uses, the open border.

    >>> open_edges([[0, 1, 2], [0, 2, 3]]).tolist()
    [[0, 1], [0, 3], [1, 2], [2, 3]]
    """
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    edges, count = np.unique(np.sort(t[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1), axis=0, return_counts=True)
    return edges[count == 1]


def shared_edges(triangles) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The edges two of ``triangles`` share (the open ones, :func:`open_edges`, are the rest): ``(E, 2)
    int64`` the edge's two vertices in the order the first triangle runs along it, and ``(E,) int64``
    the first and the second triangle. An edge three or more triangles share (a non-manifold fin)
    gives a row for each consecutive pair.

    >>> ends, first, second = shared_edges([[0, 1, 2], [0, 2, 3]])
    >>> ends.tolist(), first.tolist(), second.tolist()
    ([[2, 0]], [0], [1])
    """
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    directed = t[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    edges = np.sort(directed, axis=1)
    owner = np.repeat(np.arange(len(t)), 3)
    order = np.lexsort((edges[:, 1], edges[:, 0]))
    edges, owner, directed = edges[order], owner[order], directed[order]
    pair = np.flatnonzero((edges[1:] == edges[:-1]).all(axis=1))
    return directed[pair], owner[pair], owner[pair + 1]


def submesh(mesh: Mesh, vertex_mask) -> tuple[Mesh, np.ndarray]:
    """The mesh of the vertices in ``vertex_mask (V,) bool`` and the triangles all of whose corners are
    among them, and ``(V,) int64``: each vertex's index in it (-1 for those left out).

    >>> m = Mesh([[0., 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], [[0, 1, 2], [1, 3, 2]])
    >>> part, index = submesh(m, np.array([True, True, True, False]))
    >>> part.triangles.tolist(), index.tolist()
    ([[0, 1, 2]], [0, 1, 2, -1])
    """
    ids = np.flatnonzero(vertex_mask)
    index = np.full(len(mesh.vertices), -1, dtype=np.int64)
    index[ids] = np.arange(len(ids))
    tris = index[mesh.triangles]
    return Mesh(mesh.vertices[ids], tris[(tris >= 0).all(axis=1)]), index


def boundary_loops(triangles) -> list[np.ndarray]:
    """The open boundary of a triangulation as closed loops of vertex ids, each in the direction the
    triangles' winding gives it (counter-clockwise around the surface seen from outside), longest first.

    Raises ``ValueError`` where the boundary is not a set of simple loops (a vertex where two holes
    touch, or a non-manifold edge).

    >>> boundary_loops([[0, 1, 2], [0, 2, 3]])[0].tolist()
    [0, 1, 2, 3]
    """
    t = np.asarray(triangles, dtype=np.int64)
    directed = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    key = np.sort(directed, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    if counts.max(initial=0) > 2:
        raise ValueError("the mesh has edges shared by more than two triangles (non-manifold)")
    open_edges = directed[counts[inverse.ravel()] == 1]
    if len(np.unique(open_edges[:, 0])) != len(open_edges):
        raise ValueError("the boundary is not a set of simple loops (two holes meet at a vertex)")
    following = dict(zip(open_edges[:, 0].tolist(), open_edges[:, 1].tolist(), strict=True))
    loops = []
    while following:
        start = min(following)
        loop = [start]
        while (nxt := following.pop(loop[-1])) != start:
            loop.append(nxt)
        loops.append(np.array(loop, dtype=np.int64))
    return sorted(loops, key=len, reverse=True)


def nearest_neighbour_on(mesh: Mesh, vertices: np.ndarray, on: np.ndarray) -> np.ndarray:
    """``(N,)`` for each of the sorted ``vertices``, the nearest vertex joined to it by an edge among those
    ``on`` (``(V,) bool``), or -1 where none is."""
    vertices = np.asarray(vertices, dtype=np.int64)
    if np.any(np.diff(vertices) <= 0):
        raise ValueError("vertices must be sorted and distinct")
    e = mesh.edges
    e = np.vstack([e, e[:, ::-1]])
    e = e[np.isin(e[:, 0], vertices) & on[e[:, 1]]]
    out = np.full(len(vertices), -1, dtype=np.int64)
    if not len(e):
        return out
    length = np.linalg.norm(mesh.vertices[e[:, 0]] - mesh.vertices[e[:, 1]], axis=1)
    e = e[np.lexsort((length, e[:, 0]))]  # by vertex, nearest neighbour first
    first = np.r_[True, e[1:, 0] != e[:-1, 0]]
    out[np.searchsorted(vertices, e[first, 0])] = e[first, 1]
    return out


def vertex_adjacency(edges, count: int) -> sparse.csr_matrix:
    """``(count, count)``: 1 where two vertices share one of the undirected ``edges`` (each given once),
    0 elsewhere and on the diagonal."""
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    rows, cols = np.r_[edges[:, 0], edges[:, 1]], np.r_[edges[:, 1], edges[:, 0]]
    return sparse.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(count, count)).tocsr()


def harmonic_fill(triangles: np.ndarray, count: int, inner, rim) -> np.ndarray:
    """``(I, R)``: the values at ``inner`` vertices that are the mean of their neighbours' (the graph
    Laplacian's harmonic fill), given values at the held vertices ``rim``; inner vertices no held vertex
    reaches hold 0."""
    edges = np.sort(triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    edges = np.unique(edges, axis=0)
    A = vertex_adjacency(edges, count)
    L = sparse.diags(np.asarray(A.sum(axis=1)).ravel()) - A
    L_ii = L[inner][:, inner] + sparse.eye(len(inner)) * 1e-9
    return -splu(L_ii.tocsc()).solve(L[inner][:, rim].toarray())
