"""`Mesh`: a triangle mesh as plain arrays, with optional UVs, texture and part labels.

UVs are stored the way OBJ and libigl store them: a table of UV coordinates ``uv (U, 2)`` and a
second index array ``uv_triangles (F, 3)`` giving each triangle corner's UV. A vertex on a UV seam
therefore keeps one position and one index while its corners carry different UVs, so the vertex
order of a file is preserved exactly and deformation never tears a seam. Renderers and glTF need
one UV per vertex; :meth:`Mesh.split_at_seams` derives that layout on demand.

A mesh never changes: its arrays are read-only copies (new positions make a new Mesh, see
:meth:`Mesh.with_vertices`), so what it derives from them (normals, areas, edges, the seam split and
what other modules keep through ``Mesh._cached``) is computed once and can never go stale.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..validation import as_array, as_index_array, restore_frozen

__all__ = ["Mesh", "SeamSplit"]


@dataclass(frozen=True, eq=False)
class Mesh:
    """A triangle mesh, immutable: its arrays are read-only and checked on construction.

    Parameters
    ----------
    vertices : (V, 3) float64
        Positions, in the model's own units and frame.
    triangles : (F, 3) int64
        Vertex indices of each triangle, counter-clockwise seen from outside.
    uv : (U, 2) float64, optional
        Texture coordinates, origin at the bottom left of the image (OBJ and OpenGL convention).
    uv_triangles : (F, 3) int64, optional
        Index into ``uv`` for each triangle corner. Defaults to ``triangles`` when ``uv`` has one row
        per vertex.
    texture : (H, W, 3) uint8, optional
        The texture image, first row at the top.
    parts : (F,) int64, optional
        Part label of each triangle, an index into ``part_names`` (OBJ materials or groups).
    part_names : tuple of str
        Names of the parts.

    Arrays are copied (unless already owned and read-only) and marked read-only; writing to one
    raises ``ValueError``. Make a new mesh instead (:meth:`with_vertices`, :func:`dataclasses.replace`).

    Examples
    --------
    >>> m = Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    >>> m.vertices.shape, m.triangles.dtype
    ((3, 3), dtype('int64'))
    >>> m.face_normals[0]
    array([0., 0., 1.])
    >>> m.vertices[0] = 1
    Traceback (most recent call last):
    ...
    ValueError: assignment destination is read-only
    """

    vertices: np.ndarray
    triangles: np.ndarray
    uv: np.ndarray | None = None
    uv_triangles: np.ndarray | None = None
    texture: np.ndarray | None = None
    parts: np.ndarray | None = None
    part_names: tuple[str, ...] = field(default=())
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self):
        vertices = as_array(self.vertices, "vertices", shape=("V", 3), min_length=1, frozen=True)
        triangles = as_index_array(self.triangles, "triangles", upper=len(vertices), shape=("F", 3), frozen=True)
        if len(triangles) == 0:
            raise ValueError("triangles must have at least 1 entries, got 0")
        object.__setattr__(self, "vertices", vertices)
        object.__setattr__(self, "triangles", triangles)
        if self.uv is not None:
            uv = as_array(self.uv, "uv", shape=("U", 2), frozen=True)
            uv_tri = triangles if self.uv_triangles is None else self.uv_triangles
            if self.uv_triangles is None and len(uv) != len(vertices):
                raise ValueError(
                    f"uv without uv_triangles must have one row per vertex ({len(vertices)}), got {len(uv)}")
            uv_tri = as_index_array(uv_tri, "uv_triangles", upper=len(uv), shape=(len(triangles), 3), frozen=True)
            object.__setattr__(self, "uv", uv)
            object.__setattr__(self, "uv_triangles", uv_tri)
        elif self.uv_triangles is not None:
            raise ValueError("uv_triangles given without uv")
        if self.texture is not None:
            tex = np.asarray(self.texture)
            if tex.ndim != 3 or tex.shape[2] != 3 or tex.dtype != np.uint8:
                raise ValueError(f"texture must be an (H, W, 3) uint8 image, got {tex.shape} {tex.dtype}")
            object.__setattr__(self, "texture", as_array(self.texture, "texture", dtype=np.uint8, frozen=True))
        names = tuple(str(n) for n in self.part_names)
        object.__setattr__(self, "part_names", names)
        if self.parts is not None:
            parts = as_index_array(self.parts, "parts", upper=max(len(names), 1), shape=(len(triangles),),
                                   frozen=True)
            object.__setattr__(self, "parts", parts)

    def __getstate__(self):
        state = dict(self.__dict__)
        state["_cache"] = {}  # derived data is recomputed; some of it (solvers) does not pickle
        return state

    def __setstate__(self, state):
        restore_frozen(self, state)

    def _cached(self, name: str, compute: Callable[[], Any]) -> Any:
        """The derived value ``name``, made by ``compute()`` on first use and kept on this mesh.

        The one place derived data lives, for faceanim's own modules too (projection buckets, the
        edge graph, a factorised solver). An array made here is handed out read-only. The mesh never
        changes, so a kept value never goes stale.
        """
        try:
            return self._cache[name]
        except KeyError:
            pass
        value = compute()
        if isinstance(value, np.ndarray):
            value.flags.writeable = False
        self._cache[name] = value
        return value

    # ---- derived data, computed once per mesh (a mesh never changes: new positions make a new Mesh)

    @property
    def face_normals(self) -> np.ndarray:
        """(F, 3) unit normals; degenerate triangles get zero vectors."""
        return self._cached("face_normals", self._face_normals)

    def _face_normals(self) -> np.ndarray:
        v = self.vertices[self.triangles]
        n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
        length = np.linalg.norm(n, axis=1, keepdims=True)
        return np.divide(n, length, out=np.zeros_like(n), where=length > 0)

    @property
    def face_areas(self) -> np.ndarray:
        """(F,) triangle areas (squared model units)."""
        return self._cached("face_areas", self._face_areas)

    def _face_areas(self) -> np.ndarray:
        v = self.vertices[self.triangles]
        return 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)

    @property
    def vertex_normals(self) -> np.ndarray:
        """(V, 3) area-weighted unit normals; isolated vertices get zero vectors."""
        return self._cached("vertex_normals", self._vertex_normals)

    def _vertex_normals(self) -> np.ndarray:
        v = self.vertices[self.triangles]
        weighted = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
        n = np.zeros_like(self.vertices)
        for corner in range(3):
            np.add.at(n, self.triangles[:, corner], weighted)
        length = np.linalg.norm(n, axis=1, keepdims=True)
        return np.divide(n, length, out=np.zeros_like(n), where=length > 0)

    @property
    def edges(self) -> np.ndarray:
        """(E, 2) unique undirected edges, each row sorted."""
        return self._cached("edges", self._edges)

    def _edges(self) -> np.ndarray:
        e = np.sort(self.triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
        return np.unique(e, axis=0)

    @property
    def has_seams(self) -> bool:
        """Whether some vertex has corners with different UVs."""
        return self.uv is not None and len(self.split_at_seams().source_vertex) != len(self.vertices)

    # ---- new meshes from this one

    def with_vertices(self, vertices) -> Mesh:
        """The same mesh (topology, UVs, texture, parts) with new positions ``(V, 3)``."""
        vertices = as_array(vertices, "vertices", shape=(len(self.vertices), 3))
        return replace(self, vertices=vertices)

    def split_at_seams(self) -> SeamSplit:
        """One UV per vertex: vertices on seams are duplicated, once per distinct UV.

        The first ``V`` output vertices are the mesh's own, in order; duplicates follow. Without
        UVs the mesh is returned unchanged (``uv`` is None). Its arrays are read-only, like the mesh's.
        """
        return self._cached("seam_split", self._seam_split)

    def _seam_split(self) -> SeamSplit:
        if self.uv is None:
            return SeamSplit(self.vertices, self.triangles, None, np.arange(len(self.vertices)))
        V = len(self.vertices)
        corner_v = self.triangles.ravel()
        corner_uv = self.uv_triangles.ravel()
        pairs, inverse = np.unique(np.stack([corner_v, corner_uv], axis=1), axis=0, return_inverse=True)
        inverse = inverse.ravel()
        # The first pair seen for each vertex keeps the vertex's own index; others are appended.
        first_of_vertex = np.full(V, -1)
        order = np.argsort(pairs[:, 0], kind="stable")
        vid = pairs[order, 0]
        is_first = np.r_[True, vid[1:] != vid[:-1]]
        first_of_vertex[vid[is_first]] = order[is_first]
        new_index = np.empty(len(pairs), dtype=np.int64)
        new_index[first_of_vertex[first_of_vertex >= 0]] = pairs[first_of_vertex[first_of_vertex >= 0], 0]
        extra = np.setdiff1d(np.arange(len(pairs)), first_of_vertex[first_of_vertex >= 0])
        new_index[extra] = V + np.arange(len(extra))
        source = np.concatenate([np.arange(V), pairs[extra, 0]])
        uv = np.zeros((len(source), 2))
        uv[new_index] = self.uv[pairs[:, 1]]
        triangles = new_index[inverse].reshape(-1, 3)
        return SeamSplit(self.vertices[source], triangles, uv, source)


@dataclass(frozen=True, eq=False)
class SeamSplit:
    """A mesh laid out with one UV per vertex, as GPUs and glTF want it.

    ``vertices (S, 3)``, ``triangles (F, 3)``, ``uv (S, 2)`` or None, and ``source_vertex (S,)``:
    the original vertex each one copies, so new positions ``P (V, 3)`` map as ``P[source_vertex]``.
    All read-only.
    """

    vertices: np.ndarray
    triangles: np.ndarray
    uv: np.ndarray | None
    source_vertex: np.ndarray

    def __post_init__(self):
        for name in ("vertices", "triangles", "uv", "source_vertex"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, as_array(value, name, dtype=value.dtype, finite=False, frozen=True))
