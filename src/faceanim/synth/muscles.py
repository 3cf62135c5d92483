"""Vector muscles (Waters 1987) and the other movers of a face: jaw, eyelids, eyes, cheek air.

Every mover is a small frozen description placed by feature points (``(("8.3", 1.0),)`` is the left
lip corner) with offsets in the face frame in ES0 units, written for the face's left side; the right
side is its mirror image. ``displacement(face, activation, side)`` turns it into a ``(V, 3)`` field of
model-space displacements on a :class:`~faceanim.synth.face.MuscleFace`.

* :class:`LinearMuscle`: Waters' linear muscle. A vertex ``p`` at distance ``D`` from the origin and
  at angle ``mu`` from the muscle's line moves toward the origin by
  ``strength * cos(mu / zone * pi/2) * R(D)``, with ``R`` rising as ``cos((1 - D/Rs) pi/2)`` up to the
  start radius ``Rs`` and falling as ``cos((D - Rs)/(Rf - Rs) pi/2)`` to the end radius ``Rf``.
* :class:`Sphincter`: Waters' sphincter, an ellipsoid around a centre (mouth, eye) whose inside is
  drawn toward the centre (gains per axis, a negative gain pushes away) and pushed out of the face.
* :class:`Rotator`: a part turning about an axis through a hinge, carried by a weight field: the jaw
  about the temporomandibular hinge, an eyelid about the eyeball's centre.
* :class:`Gaze`: the eyeballs turning, with the lids following part of the way.
* :class:`Translator`: the jaw sliding (thrust, sideways).
* :class:`Inflation`: skin pushed out along its normals (a cheek full of air), which no muscle does.

Strengths are in ES0 (the eye separation) per unit activation, so a muscle does the same on a small
and a large face.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .face import MuscleFace

__all__ = ["LinearMuscle", "Sphincter", "Rotator", "Gaze", "Translator", "Inflation", "Places"]

Places = tuple  # ((feature point, weight), ...)


def _cos_falloff(t: np.ndarray) -> np.ndarray:
    """1 at t <= 0, cos(t pi/2) on (0, 1), exactly 0 at t >= 1."""
    return np.where(t >= 1.0, 0.0, np.cos(np.clip(t, 0.0, 1.0) * np.pi / 2))


def _layer(face: MuscleFace, layer: str) -> np.ndarray:
    """Which lip a muscle may move: ``upper`` (what the jaw does not carry), ``lower`` or ``all``."""
    if layer == "all":
        return np.ones(len(face.skin_ids))
    return face.jaw_weight if layer == "lower" else 1.0 - face.jaw_weight


def _on_mesh(face: MuscleFace, skin_field: np.ndarray) -> np.ndarray:
    out = np.zeros((len(face.mesh.vertices), 3))
    out[face.skin_ids] = skin_field
    return out


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix by ``angle`` radians about unit ``axis`` (right-handed)."""
    x, y, z = axis
    K = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


@dataclass(frozen=True)
class LinearMuscle:
    """Waters' linear muscle from a bony ``origin`` to a skin ``insertion``.

    ``zone`` is the half-angle of the influence cone in degrees; ``start`` and ``end`` are the radii
    ``Rs`` and ``Rf`` as multiples of the origin-insertion length; ``layer`` limits it to one lip;
    ``lift`` adds a push out of the face (ES0 per unit activation) over the same zone.
    """

    origin: Places
    insertion: Places
    strength: float
    origin_offset: tuple = (0.0, 0.0, 0.0)
    insertion_offset: tuple = (0.0, 0.0, 0.0)
    zone: float = 40.0
    start: float = 1.0
    end: float = 1.6
    layer: str = "all"
    lift: float = 0.0

    def points(self, face: MuscleFace, side: str) -> tuple[np.ndarray, np.ndarray]:
        return (face.place(self.origin, self.origin_offset, side),
                face.place(self.insertion, self.insertion_offset, side))

    def displacement(self, face: MuscleFace, activation: float, side: str) -> np.ndarray:
        origin, insertion = self.points(face, side)
        line = insertion - origin
        length = np.linalg.norm(line)
        v = face.skin_vertices - origin
        D = np.maximum(np.linalg.norm(v, axis=1), 1e-12)
        mu = np.arccos(np.clip(v @ line / (D * length), -1.0, 1.0))
        angular = _cos_falloff(mu / np.radians(self.zone))
        Rs, Rf = self.start * length, self.end * length
        radial = np.where(D <= Rs, np.cos((1.0 - D / Rs) * np.pi / 2), _cos_falloff((D - Rs) / (Rf - Rs)))
        w = activation * angular * radial * _layer(face, self.layer)
        toward_origin = -v / D[:, None]
        field = (self.strength * face.unit) * w[:, None] * toward_origin
        if self.lift:
            field += (self.lift * face.unit) * w[:, None] * face.axes[2]
        return _on_mesh(face, field)


@dataclass(frozen=True)
class Sphincter:
    """An elliptical sphincter around ``centre`` (orbicularis oris, orbicularis oculi).

    The ellipsoid has half-axes ``radii`` (ES0, face frame); inside ``inner`` (as a fraction of the
    ellipsoid) the skin moves fully, fading to nothing at ``outer``. A vertex at face-frame offset
    ``(x, y, z)`` from the centre moves by ``(-gain_x x, -gain_y y, push)`` (gains are fractions of its
    offset; ``push`` in ES0), times the fall-off and, below and above the centre, ``below`` and ``above``.
    """

    centre: Places
    radii: tuple
    gain_x: float = 0.0
    gain_y: float = 0.0
    push: float = 0.0
    centre_offset: tuple = (0.0, 0.0, 0.0)
    inner: float = 0.6
    outer: float = 1.0
    below: float = 1.0
    above: float = 1.0
    ring: float = 0.0

    def displacement(self, face: MuscleFace, activation: float, side: str) -> np.ndarray:
        centre = face.place(self.centre, self.centre_offset, side)
        q = face.local(face.skin_vertices - centre)
        rho = np.linalg.norm(q / (np.asarray(self.radii) * face.unit), axis=1)
        w = _cos_falloff((rho - self.inner) / (self.outer - self.inner))
        if self.ring:  # the orbital part: nothing on the lids themselves, most on the ring around them
            w = w * (1.0 - _cos_falloff(rho / self.ring))
        w = w * np.where(q[:, 1] < 0, self.below, self.above) * activation
        local = np.stack([-self.gain_x * q[:, 0], -self.gain_y * q[:, 1],
                          np.full(len(q), self.push * face.unit)], axis=1) * w[:, None]
        return _on_mesh(face, local @ face.axes)


@dataclass(frozen=True)
class Rotator:
    """A part turning by ``degrees`` per unit activation about a face-frame ``axis`` through a hinge
    (moved by ``hinge_offset``, ES0).

    ``part`` picks the weight field and the hinge: ``"jaw"`` (hinge level with the bottom of the nose
    and 0.55 ES0 behind the lip corners, the temporomandibular joint), ``"upper_lid"`` or
    ``"lower_lid"`` (the eyeball's centre). For a lid, ``degrees=None`` means "all the way to the other
    lid": one unit of activation closes the eye.
    """

    part: str
    degrees: float | None
    axis: tuple = (1.0, 0.0, 0.0)
    hinge_offset: tuple = (0.0, 0.0, 0.0)

    def hinge(self, face: MuscleFace, side: str) -> np.ndarray:
        if self.part == "jaw":
            corners = 0.5 * (face.point("8.3") + face.point("8.4"))
            below_nose = face.point("9.15")
            hinge = corners + face.vector((0.0, 0.0, -0.55))
            hinge = hinge + face.axes[1] * (face.axes[1] @ (below_nose - hinge))
            return hinge + face.vector(self.hinge_offset)
        return face.eye_centre(side) + face.vector(self.hinge_offset, side)

    def angle(self, face: MuscleFace, activation: float, side: str) -> float:
        if self.degrees is not None:
            return np.radians(self.degrees) * activation
        centre = self.hinge(face, side)
        upper, lower = (face.local(face.point(n, side) - centre) for n in ("3.1", "3.3"))
        closure = np.arctan2(upper[1], upper[2]) - np.arctan2(lower[1], lower[2])
        return closure * activation * (1.0 if self.part == "upper_lid" else -1.0)

    def weight(self, face: MuscleFace, side: str) -> np.ndarray:
        if self.part == "jaw":
            return face.jaw_weight
        return face.lid_weight(side, "upper" if self.part == "upper_lid" else "lower")

    def displacement(self, face: MuscleFace, activation: float, side: str) -> np.ndarray:
        axis = np.asarray(self.axis, dtype=np.float64)
        if side == "R":  # an axis of rotation is a pseudovector: its mirror image keeps x, flips y and z
            axis = axis * np.array([1.0, -1.0, -1.0])
        axis = axis @ face.axes
        axis /= np.linalg.norm(axis)
        angle = self.angle(face, activation, side)
        hinge = self.hinge(face, side)
        r = face.skin_vertices - hinge
        turned = r @ _rotation(axis, angle).T
        return _on_mesh(face, self.weight(face, side)[:, None] * (turned - r))


@dataclass(frozen=True)
class Translator:
    """The jaw sliding by ``shift`` (ES0 per unit activation, face frame), carried by the jaw weight."""

    shift: tuple

    def displacement(self, face: MuscleFace, activation: float, side: str) -> np.ndarray:
        return _on_mesh(face, face.jaw_weight[:, None] * face.vector(self.shift, side) * activation)


@dataclass(frozen=True)
class Gaze:
    """Both eyeballs turning ``degrees`` per unit activation about a face-frame ``axis`` (through each
    eye's centre); the upper lids follow by ``lid_follow`` of the angle, as they do in life."""

    degrees: float
    axis: tuple
    lid_follow: float = 0.5

    def displacement(self, face: MuscleFace, activation: float, side: str) -> np.ndarray:
        axis = face.axes.T @ np.asarray(self.axis, dtype=np.float64)  # no mirroring: the eyes turn together
        angle = np.radians(self.degrees) * activation
        centre = face.eye_centre(side)
        out = np.zeros((len(face.mesh.vertices), 3))
        ball = face.eyeball_vertices(side)
        if len(ball):
            r = face.mesh.vertices[ball] - centre
            out[ball] = r @ _rotation(axis, angle).T - r
        r = face.skin_vertices - centre
        lid = face.lid_weight(side, "upper") + 0.5 * face.lid_weight(side, "lower")
        turned = r @ _rotation(axis, self.lid_follow * angle).T
        out[face.skin_ids] = np.clip(lid, 0.0, 1.0)[:, None] * (turned - r)
        return out


@dataclass(frozen=True)
class Inflation:
    """Skin pushed out along its normals by ``strength`` (ES0) with a Gaussian fall-off of width
    ``radius`` (ES0) around ``centre``."""

    centre: Places
    radius: float
    strength: float
    centre_offset: tuple = (0.0, 0.0, 0.0)

    def displacement(self, face: MuscleFace, activation: float, side: str) -> np.ndarray:
        centre = face.place(self.centre, self.centre_offset, side)
        d2 = ((face.skin_vertices - centre) ** 2).sum(axis=1) / (self.radius * face.unit) ** 2
        w = np.exp(-0.5 * d2) * activation * (self.strength * face.unit)
        return _on_mesh(face, w[:, None] * face.skin_normals)
