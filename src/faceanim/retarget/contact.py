"""Skin kept out of the teeth, and in front of them.

A lip pressed against the teeth in the video, or one whose motion is interpolated a little too far
back, would pass through them. The teeth sets are rigid (the upper with the skull, the lower turned
with the jaw), so each frame's lip vertices are taken into a set's own rest frame, measured against
its surface there (the signed distance to the closest point of its triangles, and the outward normal
there, :func:`~faceanim.geometry.quality.signed_offsets`), and pushed back out to the depth they sat
at at rest (a lip resting on or in the teeth at rest may stay as deep as it was): :class:`TeethContact`.

Skin carried right through a crown, or round the gums' open edge, is on the far side and the closest
point calls it clear. :class:`TeethCover` finds it the way a viewer does: in the set's frame, skin
that had the teeth straight behind it at rest and now has them ahead of it; the deformer puts such
skin back on the jaw's turn.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..geometry.mesh import Mesh
from ..geometry.quality import signed_offsets
from ..geometry.topology import submesh
from ..parts import INNER_LIP_POINTS, FaceParts
from ..parts.jaw import turned_vectors
from ..target import Target

__all__ = ["TeethContact", "TeethCover", "SightLines"]

_FRONT = 3.0  # lip reaches (0.12 of the mouth's width): how far behind the lips the teeth are kept
_LOOK = 3.0  # lip reaches: how far in front of or behind the skin the teeth are looked for
_COVER_CLEAR = 0.5  # lip reaches: skin at least this clear of the teeth at rest is kept in front of them
_PLANES = 4  # nearest tooth vertices whose tangent planes screen a lip vertex before the exact distance


@dataclass(frozen=True, eq=False)
class _RigidSet:
    """One rigid teeth set: its share of the jaw's turn (0 or 1), its rest surface with a KD-tree over
    its vertices and their normals, and each lip vertex's signed distance to it at rest and the deepest
    it may go (that distance, at most 0)."""

    turn_share: float
    surface: Mesh
    tree: cKDTree
    normals: np.ndarray
    slack: float
    at_rest: np.ndarray
    allowed: np.ndarray


class TeethContact:
    """Pushes lip vertices back in front of the rigid teeth.

    Parameters
    ----------
    target : Target
        Needs the mouth corners (8.3, 8.4) and some inner-lip points (:data:`~faceanim.parts.INNER_LIP_POINTS`);
        without them, or without rigid teeth, it does nothing.
    parts : FaceParts
    skin_ids : (S,) int64
        The skin vertices, in the order of the displacements it will be given.

    Calling it with skin displacements ``(T, S, 3)`` and the jaw's angles ``(T,)`` changes the
    displacements of lip vertices that went into the teeth, in place, and returns which it pushed
    (``(T, S) bool``). ``among (T, S) bool`` limits the check to those vertices (the ones that moved
    since they were last found clear); by default every lip vertex is checked.
    """

    def __init__(self, target: Target, parts: FaceParts, skin_ids):
        self.parts = parts
        self.lips = np.zeros(0, dtype=np.int64)
        self.sets: list[_RigidSet] = []
        names = [n for n in INNER_LIP_POINTS if n in target.points]
        if not names or not {"8.3", "8.4"} <= target.points.keys():
            return
        rest = target.mesh.vertices
        corners = rest[target.ids(["8.3", "8.4"])]
        self.reach = 0.12 * np.linalg.norm(corners[0] - corners[1])
        skin_ids = np.asarray(skin_ids, dtype=np.int64)
        near = cKDTree(rest[target.ids(names)]).query(rest[skin_ids], distance_upper_bound=self.reach)[0] < np.inf
        self.lips = np.flatnonzero(near)
        self.lip_rest = rest[skin_ids[self.lips]]
        for role, share in (("upper_teeth", 0.0), ("lower_teeth", 1.0)):
            # The teeth a lip can reach: those within a few reaches of the lips at rest (the front).
            mask = parts.mask(role) & (parts.jaw_weight == share)
            mask &= cKDTree(self.lip_rest).query(rest, distance_upper_bound=_FRONT * self.reach)[0] < np.inf
            surface = submesh(target.mesh, mask)[0] if mask.any() else None
            if surface is None or not len(surface.triangles) or not len(self.lips):
                continue
            at_rest = signed_offsets(self.lip_rest, surface)[0]
            edges = surface.vertices[surface.edges]
            # The nearest vertex's plane misjudges the surface by about an edge's length.
            slack = float(np.median(np.linalg.norm(edges[:, 0] - edges[:, 1], axis=1)))
            self.sets.append(_RigidSet(share, surface, cKDTree(surface.vertices), surface.vertex_normals, slack,
                                       at_rest, np.minimum(at_rest, 0.0)))

    def __call__(self, skin_field: np.ndarray, angles, among=None) -> np.ndarray:
        pushed = np.zeros(skin_field.shape[:2], dtype=bool)
        if not self.sets:
            return pushed
        checked = np.ones(pushed.shape, dtype=bool) if among is None else np.asarray(among, dtype=bool)
        checked = checked[:, self.lips].reshape(-1)
        h, a = self.parts.hinge, self.parts.axes[0]
        margin = 0.01 * self.reach
        for teeth in self.sets:
            p = self.lip_rest[None] + skin_field[:, self.lips]  # (T, N, 3)
            turn = teeth.turn_share * np.asarray(angles, dtype=np.float64)[:, None]
            local = h + turned_vectors(p - h, a, -turn)  # into the set's rest frame: its turn undone
            # A signed distance changes no faster than the point moves, so a lip vertex that has moved
            # (in the set's frame) less than it stood clear at rest cannot be in; of the others, the
            # exact distance is taken only where the planes of the nearest tooth vertices say it is
            # behind the surface or within about an edge of it.
            moved = np.linalg.norm(local - self.lip_rest, axis=-1)
            reachable = np.flatnonzero((moved >= teeth.at_rest - teeth.allowed - 1e-9).reshape(-1) & checked)
            flat = local.reshape(-1, 3)[reachable]
            distance, nearest = teeth.tree.query(flat, k=_PLANES, distance_upper_bound=self.reach)
            near = np.isfinite(distance[:, 0])
            ahead = np.full(len(flat), np.inf)
            found = nearest[near]
            valid = np.isfinite(distance[near])
            along = ((flat[near][:, None] - teeth.surface.vertices[np.where(valid, found, 0)])
                     * teeth.normals[np.where(valid, found, 0)]).sum(axis=2)
            ahead[near] = np.where(valid, along, np.inf).min(axis=1)
            close = reachable[ahead < teeth.slack]
            if not len(close):
                continue
            signed, normal = signed_offsets(local.reshape(-1, 3)[close], teeth.surface)
            allowed = np.broadcast_to(teeth.allowed, p.shape[:2]).reshape(-1)[close]
            inside = signed < allowed - 1e-9
            if not inside.any():
                continue
            push = np.zeros((p.shape[0] * p.shape[1], 3))
            push[close[inside]] = (allowed[inside] + margin - signed[inside])[:, None] * normal[inside]
            push = push.reshape(p.shape)
            pushed[:, self.lips] |= (push != 0).any(axis=2)
            # Back to the posed frame: the push turns with the teeth.
            skin_field[:, self.lips] += turned_vectors(push, a, turn)
        return pushed


class TeethCover:
    """The skin that covers the rigid teeth at rest (the teeth straight behind it, seen from ahead of
    the face, and none in front), and where in a frame the teeth have come through it.

    The lips' contact (:class:`TeethContact`) measures the closest point of the teeth, which cannot
    tell skin carried right through a thin crown, or past the gums' open lower edge, from skin in
    front: there the closest point is on the far side and says "clear". On d6 onto the ICT head
    (frames 788-789, lips pursed high while the jaw drops 25 degrees) the skin below the lower lip,
    interpolated between the raised lip and the dropped chin, passed behind the lower teeth and they
    showed through it. Seen along the face's forward axis the test is exact: skin is hidden where a
    tooth lies ahead of it.

    Parameters are :class:`TeethContact`'s. Calling it with skin displacements ``(T, S, 3)`` and the
    jaw's angles ``(T,)`` returns ``(T, S) bool``: the covering skin that has teeth ahead of it.
    """

    def __init__(self, target: Target, parts: FaceParts, skin_ids):
        self.parts = parts
        self.sets = []
        skin_ids = np.asarray(skin_ids, dtype=np.int64)
        self.count = len(skin_ids)
        if not {"8.3", "8.4"} <= target.points.keys():
            return
        rest = target.mesh.vertices
        corners = rest[target.ids(["8.3", "8.4"])]
        reach = 0.12 * np.linalg.norm(corners[0] - corners[1])
        look = _LOOK * reach
        skin_rest = self.skin_rest = rest[skin_ids]
        for role, share in (("upper_teeth", 0.0), ("lower_teeth", 1.0)):
            teeth = parts.mask(role) & (parts.jaw_weight == share)
            surface = submesh(target.mesh, teeth)[0] if teeth.any() else None
            if surface is None or not len(surface.triangles):
                continue
            sight = SightLines(surface, parts.axes)
            clearance = cKDTree(surface.vertices).query(skin_rest, distance_upper_bound=look)[0]
            # The lips' lining resting on the teeth is the contact's: here, the skin clear of them.
            near = np.flatnonzero((clearance < look) & (clearance > _COVER_CLEAR * reach))
            behind = sight.furthest(skin_rest[near], -1.0, look) > 0
            clear = sight.furthest(skin_rest[near], 1.0, look) == 0
            covering = near[behind & clear]
            if not len(covering):
                continue
            # Skin that moved (in the set's frame) well short of its distance from the teeth has not
            # gone round them: only the rest are looked at.
            self.sets.append((share, sight, covering, 0.5 * clearance[covering], look))

    def __call__(self, skin_field: np.ndarray, angles) -> np.ndarray:
        hidden = np.zeros(skin_field.shape[:2], dtype=bool)
        h, a = self.parts.hinge, self.parts.axes[0]
        angles = np.asarray(angles, dtype=np.float64)[:, None]
        for share, sight, covering, clearance, look in self.sets:
            rest = self.skin_rest[covering]
            local = h + turned_vectors(rest + skin_field[:, covering] - h, a, -share * angles)  # the set's frame
            moved = np.linalg.norm(local - rest, axis=-1) >= clearance
            t, k = np.nonzero(moved)
            if not len(t):
                continue
            seen = sight.furthest(local[t, k], 1.0, look) > 0
            hidden[t[seen], covering[k[seen]]] = True
        return hidden


class SightLines:
    """A surface as seen along one axis, from ahead: the triangles a viewer there sees (a triangle
    whose centre and corners all have another in front is dropped: anything ahead of a point has a
    seen triangle ahead of it too), binned by where they fall on the plane across that axis (a grid
    of cells about a median triangle wide), so a line along the axis meets only the few triangles in
    its cell.

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
        self.cell = float(np.median((high - low).max(axis=1))) or 1.0
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
