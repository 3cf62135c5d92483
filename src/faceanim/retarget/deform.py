"""Control-point motion onto a whole head, part by part.

The skin turns with the jaw about its hinge (each vertex by its jaw weight: smooth skinning along the
surface) and the tracked motion's residual after that turn is spread on top by surface-aware
interpolation, so every control point still lands exactly where the motion puts it. The teeth are
rigid: the upper set with the skull, the lower set (and the tongue) turned by the same jaw. Eyeballs
turn about their centres with the gaze. Lashes and other lid layers ride on the skin beneath them;
a separate mouth socket's rim rides on the lips and its floor on the jaw. See :mod:`faceanim.parts`.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..geometry.mesh import Mesh
from ..geometry.project import project_points
from ..mpeg4 import ANGLE_UNIT, fap_table
from ..mpeg4.fapstream import FapStream
from ..parts import FaceParts
from ..target import Target
from .transfer import SparseTransfer

__all__ = ["PartsDeformer", "jaw_angles", "eye_rotations", "JAW_LIMITS"]

JAW_LIMITS = (-0.05, 0.6)  # radians: a little closing past rest, about 34 degrees open
GAZE_LIMITS = (0.6, 0.45)  # radians of yaw and pitch: about as far as eyes turn (35 and 25 degrees)


def jaw_angles(parts: FaceParts, chin, chin_displacements) -> np.ndarray:
    """``(T,)`` the jaw's turn (radians, opening positive) that takes the chin ``(3,)`` along its
    displacements ``(T, 3)``: the change of the chin's angle about the hinge, in the plane across
    the jaw's axis. Clipped to :data:`JAW_LIMITS`."""
    x, y, z = parts.axes
    r = np.asarray(chin, dtype=np.float64) - parts.hinge
    moved = r + np.asarray(chin_displacements, dtype=np.float64)
    angle = np.arctan2(moved @ z, moved @ y) - np.arctan2(r @ z, r @ y)
    angle = (angle + np.pi) % (2 * np.pi) - np.pi
    return np.clip(angle, *JAW_LIMITS)


def eye_rotations(stream: FapStream, parts: FaceParts) -> np.ndarray:
    """``(T, 2, 3, 3)`` the left and right eyeballs' rotations (model axes) from FAPs 23-26 (a FAP
    absent from a frame keeps its last value): yaw about the face's +y (positive towards its left),
    then pitch about +x (positive down), each clipped to :data:`GAZE_LIMITS`."""
    from .decode import held

    table = fap_table()
    values = held(stream)
    out = np.zeros((len(stream), 2, 3, 3))
    for k, side in enumerate("lr"):
        yaw = np.clip(values[:, table.number(f"yaw_{side}_eyeball") - 1] * ANGLE_UNIT, -GAZE_LIMITS[0], GAZE_LIMITS[0])
        pitch = np.clip(values[:, table.number(f"pitch_{side}_eyeball") - 1] * ANGLE_UNIT,
                        -GAZE_LIMITS[1], GAZE_LIMITS[1])
        cy, sy, cp, sp = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch)
        Ry = np.zeros((len(stream), 3, 3))
        Ry[:, 0, 0], Ry[:, 0, 2], Ry[:, 1, 1], Ry[:, 2, 0], Ry[:, 2, 2] = cy, sy, 1.0, -sy, cy
        Rx = np.zeros((len(stream), 3, 3))
        Rx[:, 0, 0], Rx[:, 1, 1], Rx[:, 1, 2], Rx[:, 2, 1], Rx[:, 2, 2] = 1.0, cp, -sp, sp, cp
        out[:, k] = parts.axes.T @ (Ry @ Rx) @ parts.axes
    return out


class PartsDeformer:
    """Moves a target's vertices, part by part, from displacements of its control vertices.

    Parameters
    ----------
    target : Target
    parts : FaceParts
        Of the same target (:func:`faceanim.parts.face_parts`).
    control_vertices : (K,) int64
        Distinct vertex ids whose displacements will be given; those off the skin (an iris point on
        an eyeball) are ignored, since their parts move as wholes.

    Calling it with displacements ``(T, K, 3)``, jaw angles ``(T,)`` and optionally eye rotations
    ``(T, 2, 3, 3)`` gives positions ``(T, V, 3)``.
    """

    def __init__(self, target: Target, parts: FaceParts, control_vertices, *, falloff: float = 0.25):
        mesh = target.mesh
        ids = np.asarray(control_vertices, dtype=np.int64)
        skin = parts.mask("skin")
        self.on_skin = skin[ids]
        if not self.on_skin.any():
            raise InputError("no control point lies on the skin; label the target's parts with --parts PARTS.json")
        skin_ids = np.flatnonzero(skin)
        index = np.full(len(mesh.vertices), -1)
        index[skin_ids] = np.arange(len(skin_ids))
        tris = index[mesh.triangles]
        skin_mesh = Mesh(mesh.vertices[skin_ids], tris[(tris >= 0).all(axis=1)])
        self.rest = mesh.vertices
        self.parts = parts
        self.skin_ids = skin_ids
        self.controls = ids
        self.spread = SparseTransfer(skin_mesh, index[ids[self.on_skin]], falloff=falloff)
        r = mesh.vertices - parts.hinge
        axis = parts.axes[0]
        self._turn_sin = np.cross(axis, r)  # (R - I) r = sin(t) a x r + (1 - cos(t)) a x (a x r)
        self._turn_cos = np.cross(axis, self._turn_sin)
        self._riders = self._bind_riders(mesh, skin_mesh, target)

    def _bind_riders(self, mesh: Mesh, skin_mesh: Mesh, target: Target):
        """Lid layers and a separate mouth socket: the skin point each rides on (skin-local corner ids,
        barycentric weights) and how much it rides rather than following the jaw."""
        riders = np.flatnonzero(self.parts.mask("lid_layer", "mouth_socket"))
        if not len(riders):
            return None
        hit = project_points(skin_mesh, mesh.vertices[riders])
        ride = np.ones(len(riders))
        socket = self.parts.mask("mouth_socket")[riders]
        if socket.any():
            mouth = target.mesh.vertices[target.ids(["8.3", "8.4"])]
            reach = 0.15 * np.linalg.norm(mouth[0] - mouth[1])
            ride[socket] = np.exp(-(hit.distances[socket] / reach) ** 2)
        return riders, hit.corner_vertices, hit.barycentric, ride

    def jaw_turn(self, angles) -> np.ndarray:
        """``(T, V, 3)`` every vertex turned fully about the hinge by ``angles (T,)``."""
        angles = np.asarray(angles, dtype=np.float64)
        return (np.sin(angles)[:, None, None] * self._turn_sin
                + (1 - np.cos(angles))[:, None, None] * self._turn_cos)

    def fitted_jaw_weight(self, displacements, angles) -> np.ndarray:
        """``(V,)`` the parts' jaw weight with the skin's share adjusted to the motion: at each control
        point on the skin, the share of the jaw's turn that best explains its displacements over all
        frames (least squares, within [0, 1]); the differences from the parts' weights spread over the
        skin like the displacements (so far from the control points the parts' weights hold).

        Without this the residual after the turn is wherever the parts' weights guessed wrong, and
        between control points the skin falls back towards the guess: a crease at every control."""
        weight = self.parts.jaw_weight.copy()
        controls = self.controls[self.on_skin]
        turn = self.jaw_turn(angles)[:, controls]  # (T, K, 3)
        energy = (turn ** 2).sum(axis=(0, 2))
        seen = energy > 1e-12 * max(energy.max(), 1e-300)
        share = np.where(seen, (np.asarray(displacements)[:, self.on_skin] * turn).sum(axis=(0, 2))
                         / np.where(seen, energy, 1.0), weight[controls])
        change = np.clip(share, 0.0, 1.0) - weight[controls]
        weight[self.skin_ids] = np.clip(weight[self.skin_ids] + self.spread.operator @ change, 0.0, 1.0)
        return weight

    def __call__(self, displacements, angles, eyes=None, *, fit_weights: bool = True) -> np.ndarray:
        displacements = np.asarray(displacements, dtype=np.float64)
        T = len(displacements)
        weight = self.fitted_jaw_weight(displacements, angles) if fit_weights else self.parts.jaw_weight
        turned = self.jaw_turn(angles) * weight[None, :, None]  # (T, V, 3)
        controls = self.controls[self.on_skin]
        residual = displacements[:, self.on_skin] - turned[:, controls]
        moved = turned
        skin_field = turned[:, self.skin_ids] + self.spread(residual)
        moved[:, self.skin_ids] = skin_field
        if self._riders is not None:
            riders, corners, bary, ride = self._riders
            carried = np.einsum("nc,tncd->tnd", bary, skin_field[:, corners])
            moved[:, riders] = ride[None, :, None] * carried + (1 - ride)[None, :, None] * turned[:, riders]
        if eyes is not None:
            eyes = np.asarray(eyes, dtype=np.float64)
            for k, side in enumerate(("eye_left", "eye_right")):
                ball = np.flatnonzero(self.parts.mask(side))
                if len(ball):
                    r = self.rest[ball] - self.parts.eye_centres[k]
                    moved[:, ball] = np.einsum("tij,nj->tni", eyes[:, k], r) - r
        assert moved.shape == (T, len(self.rest), 3)
        return self.rest + moved


def deform_parts(target: Target, parts: FaceParts | None, control_vertices, displacements,
                 gaze: FapStream | None = None) -> np.ndarray:
    """``(T, V, 3)`` positions of ``target`` moved by its control vertices' ``displacements (T, K, 3)``,
    part by part: the jaw's turn read from the chin (feature point 2.1, when it is a control vertex),
    the eyeballs turned by ``gaze``'s FAPs when given. ``parts`` defaults to the target's own."""
    from ..parts import face_parts

    parts = face_parts(target) if parts is None else parts
    ids = np.asarray(control_vertices, dtype=np.int64)
    deformer = PartsDeformer(target, parts, ids)
    chin = np.flatnonzero(ids == target.points.get("2.1", -1))
    if len(chin):
        angles = jaw_angles(parts, target.mesh.vertices[ids[chin[0]]], displacements[:, chin[0]])
    else:
        angles = np.zeros(len(displacements))
    eyes = eye_rotations(gaze, parts) if gaze is not None else None
    return deformer(displacements, angles, eyes)
