"""The face that muscles act on: a `Target` seen through its feature points.

Muscles are placed by named feature points, never by vertex ids, so one muscle set sits on any face
with control points. :class:`MuscleFace` holds what every muscle needs from the face: where its
feature points are, a face frame (+x the face's left, +y up, +z out of the face) measured from them,
a length unit (the eye separation ES0), which vertices are skin, and the weight fields that say how
much of the skin the jaw and each eyelid carry.

The jaw and lid weights are surface fields (biharmonic interpolation along the skin,
:class:`~faceanim.geometry.surface.BiharmonicInterpolation`) pinned to 1 on the feature points the
part carries and to 0 on those it does not. Along the skin the lower lip is far from the upper lip
(the mouth is an opening of the mesh), so the fields separate the lips of a closed mouth, which no
function of position alone can do.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph

from ..errors import InputError
from ..geometry.mesh import Mesh
from ..geometry.surface import BiharmonicInterpolation
from ..geometry.topology import component_labels, submesh
from ..target import Target

__all__ = ["MuscleFace", "mirror_name", "SIDES"]

SIDES = ("L", "R")
# MPEG-4 feature points of the face's left side and their right-side twins (shared/mpeg4/fdp_points.csv).
_LEFT_RIGHT = {
    "2.4": "2.5", "2.6": "2.7", "2.8": "2.9", "2.11": "2.12", "2.13": "2.14",
    "3.1": "3.2", "3.3": "3.4", "3.5": "3.6", "3.7": "3.12", "3.9": "3.10", "3.11": "3.8", "3.13": "3.14",
    "4.1": "4.2", "4.3": "4.4", "4.5": "4.6", "5.1": "5.2", "5.3": "5.4",
    "8.3": "8.4", "8.5": "8.6", "8.7": "8.8", "8.10": "8.9", "9.1": "9.2", "9.5": "9.4", "9.7": "9.6",
}
_MIRROR = {**_LEFT_RIGHT, **{right: left for left, right in _LEFT_RIGHT.items()}}

# Feature points every muscle face needs: they set the frame, the unit and the weight fields.
_FRAME_POINTS = ("3.7", "3.12", "3.11", "3.8", "8.3", "8.4", "8.1", "8.2", "2.1", "9.15")
# Fields are pinned at these points: value 1 where the part carries the point, 0 where it does not.
_JAW_PINS = {"2.1": 1.0, "2.3": 1.0, "8.2": 1.0, "2.8": 1.0, "2.9": 1.0, "8.7": 1.0, "8.8": 1.0, "2.10": 1.0,
             "2.11": 1.0, "2.12": 1.0, "8.3": 0.5, "8.4": 0.5, "2.4": 0.5, "2.5": 0.5,
             "2.2": 0.0, "8.1": 0.0, "2.6": 0.0, "2.7": 0.0, "8.5": 0.0, "8.6": 0.0, "8.9": 0.0, "8.10": 0.0,
             "9.15": 0.0, "9.1": 0.0, "9.2": 0.0, "9.3": 0.0, "3.7": 0.0, "3.12": 0.0, "3.11": 0.0, "3.8": 0.0,
             "4.1": 0.0, "4.2": 0.0, "4.3": 0.0, "4.4": 0.0, "4.5": 0.0, "4.6": 0.0}
# Extra jaw pins off the feature points, in the face frame (ES0 units, x mirrored): the jaw line
# below the ears moves with the jaw; the cheek beside the nose and the throat do not (the skin under
# the chin stretches between them).
_JAW_ANCHORS = (("2.1", (0.55, 0.45, -0.45), 1.0), ("2.1", (0.0, -0.5, -0.8), 0.0),
                ("8.3", (0.22, 0.35, -0.1), 0.0), ("9.15", (0.0, 0.0, 0.0), 0.0))
_LID_FALLOFF = 0.5


def mirror_name(name: str, side: str) -> str:
    """A left-side feature point's name on ``side`` ("L" keeps it, "R" takes its right twin)."""
    return name if side == "L" else _MIRROR.get(name, name)


class MuscleFace:
    """A target's geometry as muscles see it; fields are computed on first use and kept.

    Parameters
    ----------
    target : Target
        A mesh with at least the feature points in ``_FRAME_POINTS`` and the eyes' and brows'
        points the muscles use (a missing one is named when a muscle asks for it).

    Attributes
    ----------
    axes : (3, 3) float64
        Rows: the face's +x (its left), +y (up), +z (out of the face), in model coordinates.
    unit : float
        ES0, the eye separation, in model units: muscle offsets and strengths are in this unit.
    skin : (V,) bool
        Vertices muscles move: the connected parts holding feature points, less parts labelled
        eyes or teeth.
    """

    def __init__(self, target: Target):
        self.target = target
        self.mesh: Mesh = target.mesh
        missing = [n for n in _FRAME_POINTS if n not in target.points]
        if missing:
            raise InputError(f"the target lacks feature point{'s' if len(missing) > 1 else ''} "
                             f"{', '.join(missing)}, which place the muscles")
        self._positions = {n: self.mesh.vertices[i] for n, i in target.points.items()}
        p = self._positions
        x = (p["3.7"] - p["3.12"])
        x /= np.linalg.norm(x)
        eyes = 0.25 * (p["3.7"] + p["3.12"] + p["3.11"] + p["3.8"])
        mouth = 0.5 * (p["8.3"] + p["8.4"])
        y = eyes - mouth
        y -= (y @ x) * x
        y /= np.linalg.norm(y)
        self.axes = np.stack([x, y, np.cross(x, y)])
        self.unit = float(target.fapu.es0) if target.fapu.es0 > 0 else float(np.linalg.norm(p["3.7"] - p["3.12"]))
        labels = component_labels(self.mesh)
        skin = np.isin(labels, labels[list(target.points.values())])
        if self.mesh.parts is not None and self.mesh.part_names:
            rigid = [k for k, n in enumerate(self.mesh.part_names)
                     if any(word in n.lower() for word in ("eye", "teeth", "tooth"))]
            on_rigid = np.unique(self.mesh.triangles[np.isin(self.mesh.parts, rigid)])
            on_soft = np.unique(self.mesh.triangles[~np.isin(self.mesh.parts, rigid)])
            skin[np.setdiff1d(on_rigid, on_soft)] = False
        self.skin = skin
        self.skin_ids = np.flatnonzero(skin)

    # ---- places

    def point(self, name: str, side: str = "L") -> np.ndarray:
        """Position of feature point ``name`` (a left-side name, mirrored for ``side="R"``)."""
        actual = mirror_name(name, side)
        if actual not in self._positions:
            raise InputError(f"the target lacks feature point {actual}, which a muscle needs")
        return self._positions[actual]

    def has(self, name: str, side: str = "L") -> bool:
        return mirror_name(name, side) in self._positions

    def place(self, points, offset=(0.0, 0.0, 0.0), side: str = "L") -> np.ndarray:
        """A weighted mean of feature points ``((name, weight), ...)`` moved by ``offset`` (ES0 units,
        face frame, written for the left side: x is mirrored on the right)."""
        total = sum(w for _, w in points)
        base = sum(w * self.point(n, side) for n, w in points) / total
        return base + self.vector(offset, side)

    def vector(self, local, side: str = "L") -> np.ndarray:
        """A face-frame vector (ES0 units, left-side x) in model coordinates and units."""
        local = np.asarray(local, dtype=np.float64) * self.unit
        if side == "R":
            local = local * np.array([-1.0, 1.0, 1.0])
        return local @ self.axes

    def local(self, vectors) -> np.ndarray:
        """Model-space vectors ``(..., 3)`` in the face frame (model units)."""
        return np.asarray(vectors) @ self.axes.T

    @cached_property
    def skin_vertices(self) -> np.ndarray:
        return self.mesh.vertices[self.skin_ids]

    @cached_property
    def skin_normals(self) -> np.ndarray:
        return self.mesh.vertex_normals[self.skin_ids]

    # ---- weight fields over the skin, (S,) each, in [0, 1]

    @cached_property
    def _skin_mesh(self) -> tuple[Mesh, np.ndarray]:
        """The skin as a mesh of its own, and each mesh vertex's index in it (-1 off the skin)."""
        return submesh(self.mesh, self.skin)

    def _field(self, pins: dict, falloff: float = 0.0) -> np.ndarray:
        """The smoothest skin field through ``pins`` (skin index -> value), clipped to [0, 1]; with a
        ``falloff`` it relaxes to 0 away from the pins (see BiharmonicInterpolation)."""
        mesh, _ = self._skin_mesh
        ids = np.array(list(pins), dtype=np.int64)
        values = np.array([pins[i] for i in ids])
        field = BiharmonicInterpolation(mesh, ids, falloff=falloff)(values[:, None])[:, 0]
        return np.clip(field, 0.0, 1.0)

    def nearest_skin(self, position) -> int:
        """Skin index of the skin vertex nearest ``position``."""
        return int(np.argmin(((self.skin_vertices - position) ** 2).sum(axis=1)))

    def _pin_points(self, values: dict, anchors=(), sides=SIDES) -> dict:
        """Skin index -> value for the named feature points in ``values`` and for the skin vertices
        nearest the ``anchors`` ``(point, offset, value)`` placed on each of ``sides``."""
        _, index = self._skin_mesh
        pins = {}
        for name, value in values.items():
            if name in self.target.points and index[self.target.points[name]] >= 0:
                pins[int(index[self.target.points[name]])] = value
        for name, offset, value in anchors:
            for side in sides:
                if self.has(name, side):
                    pins.setdefault(self.nearest_skin(self.place(((name, 1.0),), offset, side)), value)
        return pins

    @cached_property
    def jaw_weight(self) -> np.ndarray:
        """``(S,)`` how much of the jaw's motion each skin vertex follows: 1 on the lower lip and chin,
        0 on the upper lip and above, 0.5 at the lip corners."""
        return self._field(self._pin_points(_JAW_PINS, _JAW_ANCHORS))

    def lid_weight(self, side: str, lid: str) -> np.ndarray:
        """``(S,)`` how much of an eyelid's turn each skin vertex follows (``lid``: "upper"/"lower")."""
        cache = self.__dict__.setdefault("_lid_weights", {})
        if (side, lid) not in cache:
            upper, lower = mirror_name("3.1", side), mirror_name("3.3", side)
            for name in (upper, lower, mirror_name("4.3", side)):
                if name not in self._positions:
                    raise InputError(f"the target lacks feature point {name}, which the eyelids need")
            moving, still = (upper, lower) if lid == "upper" else (lower, upper)
            values = {moving: 1.0, still: 0.0, mirror_name("3.7", side): 0.0, mirror_name("3.11", side): 0.0}
            for brow in ("4.1", "4.3", "4.5"):
                values[mirror_name(brow, side)] = 0.0
            # Skin 0.32 ES0 beyond the moving lid's margin (above the fold, or down on the cheek) keeps
            # still, so the lid's own skin between follows it part of the way.
            sign = 1.0 if lid == "upper" else -1.0
            beyond = ("3.1" if lid == "upper" else "3.3", (0.0, sign * 0.32, -0.02), 0.0)
            pins = self._pin_points(values, (beyond,), sides=(side,))
            # A lid is small beside the face: away from its pins the field must die out rather than
            # extrapolate its slope over the forehead.
            cache[(side, lid)] = self._field(pins, falloff=_LID_FALLOFF)
        return cache[(side, lid)]

    def eye_centre(self, side: str) -> np.ndarray:
        """The eyeball's centre: behind the middle of the eye's corners by 0.2 ES0 (about 1.2 cm)."""
        corners = 0.5 * (self.point("3.7", side) + self.point("3.11", side))
        return corners + self.vector((0.0, 0.0, -0.19), side)

    def eyeball_vertices(self, side: str) -> np.ndarray:
        """Mesh vertex ids of the eyeball on ``side``: of the pieces off the skin (connected through
        off-skin vertices, so an eye part stitched to the lids still counts), the one whose centre is
        nearest the eye's, if within half the eye's width, and any other piece as near as it give or
        take 0.15 eye widths (a sclera and an iris modelled apart); lashes and the like sit farther out.
        None on a face without eyeballs."""
        pieces = self._off_skin_pieces
        if not len(pieces):
            return np.zeros(0, dtype=np.int64)
        corners = (self.point("3.7", side), self.point("3.11", side))
        reach = 0.5 * np.linalg.norm(corners[0] - corners[1])
        centre = self.eye_centre(side)
        distance = [np.linalg.norm(self.mesh.vertices[ids].mean(axis=0) - centre) for ids in pieces]
        nearest = min(distance)
        chosen = [ids for ids, d in zip(pieces, distance, strict=True) if d < min(reach, nearest + 0.3 * reach)]
        return np.concatenate(chosen) if chosen else np.zeros(0, dtype=np.int64)

    @cached_property
    def _off_skin_pieces(self) -> list[np.ndarray]:
        off = np.flatnonzero(~self.skin)
        if not len(off):
            return []
        e = self.mesh.edges
        e = e[~self.skin[e[:, 0]] & ~self.skin[e[:, 1]]]
        V = len(self.mesh.vertices)
        graph = sparse.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(V, V))
        labels = csgraph.connected_components(graph, directed=False)[1]
        return [off[labels[off] == k] for k in np.unique(labels[off])]
