"""Lips kept out of the teeth.

A lip pressed against the teeth in the video, or one whose motion is interpolated a little too far
back, would pass through them. The teeth sets are rigid (the upper with the skull, the lower turned
with the jaw), so each frame's lip vertices are taken into a set's own rest frame, measured against
its surface there (the nearest tooth vertex and its outward normal), and pushed back out by however
much deeper they went than they sat at rest (a lip resting on the teeth stays where it rests).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..parts import INNER_LIP_POINTS, FaceParts
from ..target import Target

__all__ = ["TeethContact"]


@dataclass(frozen=True, eq=False)
class _RigidSet:
    """One rigid teeth set: its share of the jaw's turn (0 or 1), its rest vertices and outward normals
    with a KD-tree over them, and how deep each lip vertex sits behind its surface at rest (>= 0)."""

    turn_share: float
    tree: cKDTree
    surface: np.ndarray
    normals: np.ndarray
    at_rest: np.ndarray

    def depth(self, points: np.ndarray):
        """How far ``points (..., 3)`` (this set's rest frame) lie behind its surface, their distance
        to it, and the outward normal there."""
        distance, nearest = self.tree.query(points.reshape(-1, 3))
        distance, nearest = distance.reshape(points.shape[:-1]), nearest.reshape(points.shape[:-1])
        return ((self.surface[nearest] - points) * self.normals[nearest]).sum(axis=-1), distance, self.normals[nearest]


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
    displacements of lip vertices that went into the teeth, in place.
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
            ids = np.flatnonzero(parts.mask(role) & (parts.jaw_weight == share))
            if len(ids) and len(self.lips):
                unfilled = _RigidSet(share, cKDTree(rest[ids]), rest[ids], target.mesh.vertex_normals[ids], None)
                at_rest = np.maximum(unfilled.depth(self.lip_rest)[0], 0.0)
                self.sets.append(_RigidSet(share, unfilled.tree, unfilled.surface, unfilled.normals, at_rest))

    def __call__(self, skin_field: np.ndarray, angles) -> None:
        h, a = self.parts.hinge, self.parts.axes[0]
        for teeth in self.sets:
            p = self.lip_rest[None] + skin_field[:, self.lips]  # (T, N, 3)
            turn = teeth.turn_share * np.asarray(angles, dtype=np.float64)[:, None, None]
            cos, sin = np.cos(turn), np.sin(turn)
            r = p - h
            # Into the set's rest frame: undo its turn about the hinge (Rodrigues, by -turn).
            local = h + r * cos - np.cross(a, r) * sin + a * (r @ a)[..., None] * (1 - cos)
            depth, distance, normal = teeth.depth(local)
            inside = (depth > teeth.at_rest + 1e-9) & (distance < self.reach)
            if not inside.any():
                continue
            push = np.where(inside, depth - teeth.at_rest + 0.01 * self.reach, 0.0)[..., None] * normal
            # Back to the posed frame: the push turns with the teeth.
            skin_field[:, self.lips] += push * cos + np.cross(a, push) * sin + a * (push @ a)[..., None] * (1 - cos)
