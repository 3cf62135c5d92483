"""FAPs onto a target: per-frame control-point displacements, then the whole mesh."""

from __future__ import annotations

import numpy as np

from ..geometry.animation import Animation
from ..mpeg4 import ANGLE_UNIT, fap_table, feature_points
from ..mpeg4.fapstream import FapStream, held
from ..mpeg4.jaw import JAW_CARRIED, jaw_hinge, jaw_swing
from ..parts import FaceParts
from ..target import Target
from .deform import parts_frames

__all__ = ["fap_displacements", "animate_faps", "turn_head"]



def fap_displacements(stream: FapStream, target: Target) -> tuple[tuple[str, ...], np.ndarray]:
    """The target's feature points that FAPs move, and their displacements ``(T, K, 3)`` (model units,
    MPEG-4 axes: +X the face's left, +Y up, +Z out of the face)."""
    table = fap_table()
    values = held(stream)
    scale = target.fapu.scale()
    moved: dict[str, np.ndarray] = {}
    for j in range(2, len(table.names)):
        points = table.feature_points[j]
        if len(points) != 1 or points[0] not in target.points or not table.direction[j].any():
            continue
        step = values[:, j:j + 1] * scale[j] * table.direction[j]
        moved[points[0]] = moved.get(points[0], 0.0) + step
    if "2.1" in moved:
        opening = table.number("open_jaw") - 1
        at = {n: target.mesh.vertices[i] for n, i in target.points.items()}
        jaw = jaw_swing(jaw_hinge(at, target.fapu), at["2.1"], values[:, opening] * scale[opening])
        for name in ("2.1", *sorted(JAW_CARRIED)):  # the points encoding measured after the jaw's swing
            if name in target.points:
                drop = values[:, opening:opening + 1] * scale[opening] * table.direction[opening]
                others = moved.get(name, 0.0) - (drop if name == "2.1" else 0)
                moved[name] = others + jaw(at[name])
    names = tuple(moved)
    return names, np.stack([moved[n] for n in names], axis=1) if names else np.zeros((len(stream), 0, 3))


def head_rotations(stream: FapStream) -> np.ndarray:
    """(T, 3, 3) head rotations from FAPs 48-50 (pitch, yaw, roll), ``R = R_y R_x R_z``."""
    table = fap_table()
    values = held(stream)
    pitch, yaw, roll = (values[:, table.number(n) - 1] * ANGLE_UNIT for n in ("head_pitch", "head_yaw", "head_roll"))
    c, s = np.cos, np.sin
    R = np.zeros((len(stream), 3, 3))
    Rx = np.stack([np.ones_like(pitch), 0 * pitch, 0 * pitch, 0 * pitch, c(pitch), -s(pitch), 0 * pitch, s(pitch),
                   c(pitch)], 1).reshape(-1, 3, 3)
    Ry = np.stack([c(yaw), 0 * yaw, s(yaw), 0 * yaw, np.ones_like(yaw), 0 * yaw, -s(yaw), 0 * yaw, c(yaw)],
                  1).reshape(-1, 3, 3)
    Rz = np.stack([c(roll), -s(roll), 0 * roll, s(roll), c(roll), 0 * roll, 0 * roll, 0 * roll, np.ones_like(roll)],
                  1).reshape(-1, 3, 3)
    R[:] = Ry @ Rx @ Rz
    return R


def animate_faps(stream: FapStream, target: Target, *, head_motion: bool = False, pivot=None,
                 parts: FaceParts | None = None) -> Animation:
    """The target animated by ``stream``, streamed (its frames are made as they are read).

    Feature-point displacements (in the target's FAPU) move the head part by part
    (:class:`~.deform.PartsDeformer`: the jaw turned about its hinge, the rest spread by surface-aware
    interpolation, rigid teeth, eyeballs turned by FAPs 23-26); feature points no FAP moves are held still, so the
    motion stays where MPEG-4 puts it (other named points of the target are not used here). With
    ``head_motion`` the whole mesh also turns by FAPs 48-50
    about ``pivot`` (default: the centre of the target's feature points).
    """
    names, moving = fap_displacements(stream, target)
    # Pin the MPEG-4 feature points no FAP moves; other control points (a tracker's extra points) are
    # left free, or they would nail the skin between the feature points in place.
    feature = set(feature_points().names)
    still = [n for n in target.points if n not in names and n in feature]
    controls = list(names) + still
    displacements = np.concatenate([moving, np.zeros((len(stream), len(still), 3))], axis=1)
    ids = target.ids(controls)
    unique, first = np.unique(ids, return_index=True)  # two names on one vertex: keep the first
    animation = Animation.streamed(target.mesh, parts_frames(target, parts, unique, displacements[:, first], stream),
                                   len(stream), stream.fps)
    if head_motion:
        centre = target.mesh.vertices[target.ids(list(target.points))].mean(axis=0) if pivot is None else pivot
        rotations = head_rotations(stream)
        animation = animation.map(lambda a, b, positions: turn_head(positions, rotations[a:b], centre))
    return animation


def turn_head(positions: np.ndarray, rotations: np.ndarray, centre) -> np.ndarray:
    """``positions (T, V, 3)`` turned frame by frame by ``rotations (T, 3, 3)`` about ``centre (3,)``."""
    return np.einsum("tij,tvj->tvi", rotations, positions - centre) + centre
