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
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

from ..geometry.mesh import Mesh
from ..geometry.quality import signed_offsets
from ..geometry.sightlines import SightLines
from ..geometry.surface import edge_graph
from ..geometry.topology import submesh
from ..parts import INNER_LIP_POINTS, FaceParts
from ..parts.jaw import turned_vectors
from ..target import Target

__all__ = ["TeethContact", "TeethCover"]

_FRONT = 3.0  # lip reaches (0.12 of the mouth's width): how far behind the lips the teeth are kept
_LOOK = 3.0  # lip reaches: how far in front of or behind the skin the teeth are looked for
_COVER_CLEAR = 0.5  # lip reaches: skin at least this clear of the teeth at rest is kept in front of them
_PLANES = 4  # nearest tooth vertices whose tangent planes screen a lip vertex before the exact distance
_EASED_ROUNDS = 16  # eased pushes (TeethContact.eased) per frame, at most: each leaves a pushed vertex a little short


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


@dataclass(frozen=True, eq=False)
class _CoveredSet:
    """One rigid teeth set as :class:`TeethCover` watches it: its share of the jaw's turn, the set seen
    from ahead, the skin covering it (indices into the skin), how far each of those must move (in the
    set's frame) before it is looked at, and how far ahead a tooth is looked for."""

    turn_share: float
    sight: SightLines
    covering: np.ndarray
    clearance: np.ndarray
    look: float


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
        self.reach = 0.0  # nothing to push (set below when the target has lips and teeth)
        self.skin_rest = target.mesh.vertices[np.asarray(skin_ids, dtype=np.int64)]
        self._target_mesh, self._skin_ids, self._skin_graph = target.mesh, np.asarray(skin_ids, dtype=np.int64), None
        if not any(n in target.points for n in INNER_LIP_POINTS) or not {"8.3", "8.4"} <= target.points.keys():
            return
        rest = target.mesh.vertices
        self.reach = _lip_reach(target)
        skin_ids = np.asarray(skin_ids, dtype=np.int64)
        self.lips = np.flatnonzero(_lip_skin(target, skin_ids, self.reach))
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

    def eased(self, skin_field: np.ndarray, angles, radius: float) -> np.ndarray:
        """Pushes the lips in ``skin_field (T, S, 3)`` out of the teeth like a call does, but carries each
        push onto the skin within ``radius`` of the pushed vertex along the skin (0: each push alone), in
        place; returns which skin vertices it may have moved (``(T, S) bool``: those within reach of a push).

        A push moves one vertex by up to a millimetre, and the lips' triangles at the mouth's corners
        are slivers a quarter of that high: pushed alone, a corner turns them over. Carried, the
        neighbours move nearly as the pushed vertex does. The distance is taken along the skin's edges,
        so a push on one lip does not reach across the mouth to the other, which touches it at rest.
        The shares fall off with distance (Wendland's ``(1 - r)^4 (4 r + 1)``) and are averaged where
        pushes overlap (a pushed vertex's own share among them: given each its own push exactly, two
        neighbours pushed by different amounts turn the sliver between them over), so a pushed vertex
        can end short of its push; pushes are repeated until no lip vertex is in, at most
        :data:`_EASED_ROUNDS` times."""
        if not np.isfinite(radius) or radius < 0:
            raise ValueError(f"radius must be a finite distance of at least 0, got {radius}")
        moved = np.zeros(skin_field.shape[:2], dtype=bool)
        for _ in range(_EASED_ROUNDS):
            before = skin_field.copy()
            pushed = self(skin_field, angles)
            if not pushed.any():
                break
            for t in np.flatnonzero(pushed.any(axis=1)):
                ids = np.flatnonzero(pushed[t])
                push = skin_field[t, ids] - before[t, ids]
                near, share = (ids, np.eye(len(ids))) if radius == 0 else self._shares(ids, radius)
                skin_field[t] = before[t]
                skin_field[t, near] += share @ push
                moved[t, near] = True
        return moved

    def _shares(self, pushed: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
        """The skin within ``radius`` of the ``pushed`` skin vertices along the skin's edges, and ``(N, P)``
        each one's share of each push: Wendland weights, divided by their sum where it passes 1."""
        if self._skin_graph is None:
            skin = np.zeros(len(self._target_mesh.vertices), dtype=bool)
            skin[self._skin_ids] = True
            mesh, index = submesh(self._target_mesh, skin)
            order = index[self._skin_ids]  # the skin in the order the fields give it
            self._skin_graph = edge_graph(mesh)[order][:, order]
        distance = dijkstra(self._skin_graph, indices=pushed, limit=radius)  # (P, S), inf beyond
        near = np.flatnonzero(np.isfinite(distance).any(axis=0))
        r = np.minimum(distance[:, near].T / radius, 1.0)  # (N, P)
        share = (1 - r) ** 4 * (4 * r + 1)
        return near, share / np.maximum(share.sum(axis=1), 1.0)[:, None]


def _lip_reach(target: Target) -> float:
    """How far from the inner-lip points the lips reach: 0.12 of the mouth's width (8.3 to 8.4)."""
    return 0.12 * target.mouth_width


def _lip_skin(target: Target, skin_ids: np.ndarray, reach: float) -> np.ndarray:
    """``(S,) bool``: the skin within ``reach`` of the target's inner-lip points."""
    names = [n for n in INNER_LIP_POINTS if n in target.points]
    if not names:
        return np.zeros(len(skin_ids), dtype=bool)
    rest = target.mesh.vertices
    return cKDTree(rest[target.ids(names)]).query(rest[skin_ids], distance_upper_bound=reach)[0] < np.inf


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
        self.sets: list[_CoveredSet] = []
        skin_ids = np.asarray(skin_ids, dtype=np.int64)
        if not {"8.3", "8.4"} <= target.points.keys():
            return
        rest = target.mesh.vertices
        reach = _lip_reach(target)
        look = _LOOK * reach
        skin_rest = self.skin_rest = rest[skin_ids]
        lips = _lip_skin(target, skin_ids, reach)
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
            if share == 0.0:
                # In front of the upper teeth, only the lips: they alone reach past the crowns (pursed,
                # rolled in). The skin above them lies on the gums, which it grazes as the lip is raised;
                # put back at rest there, it dropped d18's raised upper lip over the teeth it bared and
                # tore its corners (onto the ICT head, frames 90-100). The lower teeth are watched whole:
                # the jaw's turn carries skin behind them where no control point holds it (d6).
                covering = covering[lips[covering]]
            if not len(covering):
                continue
            # Skin that moved (in the set's frame) well short of its distance from the teeth has not
            # gone round them: only the rest are looked at.
            self.sets.append(_CoveredSet(share, sight, covering, 0.5 * clearance[covering], look))

    def __call__(self, skin_field: np.ndarray, angles) -> np.ndarray:
        hidden = np.zeros(skin_field.shape[:2], dtype=bool)
        h, a = self.parts.hinge, self.parts.axes[0]
        angles = np.asarray(angles, dtype=np.float64)[:, None]
        for teeth in self.sets:
            rest = self.skin_rest[teeth.covering]
            # in the set's frame
            local = h + turned_vectors(rest + skin_field[:, teeth.covering] - h, a, -teeth.turn_share * angles)
            t, k = np.nonzero(np.linalg.norm(local - rest, axis=-1) >= teeth.clearance)
            if not len(t):
                continue
            seen = teeth.sight.furthest(local[t, k], 1.0, teeth.look) > 0
            hidden[t[seen], teeth.covering[k[seen]]] = True
        return hidden
