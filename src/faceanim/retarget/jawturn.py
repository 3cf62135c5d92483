"""Where a motion's jaw turns: a turning centre and a turn per frame fitted to the chin's control points.

The parts' centre (:func:`faceanim.parts.face_parts`) is read off the target's shape, low on the ramus,
because a real jaw's condyles slide forward as it opens. How far they slide differs between faces and
rigs: ICT-FaceKit's jawOpen turns its teeth about a centre near the condyles, 2 cm higher and 1.7 cm
further back than that guess, and its chin swings back 3.5 cm as it drops 2. Turned about the guess by
the chin's angle, the lower teeth fell 1 cm short of going back with the lower lip, and came through it
at the widest frames.

So the motion says where its jaw turns: the control points on the chin (below the lower lip, where the
jaw carries all the skin) are taken as one body turning about the axis across the face, and their
displacements over the widest openings give the centre, shared by every frame, and each frame's turn
about it. The chin's skin is not bone (on ICT's jawOpen it turns about 15 degrees about a centre far
behind, where the teeth turn 27 about the condyles), so the centre is kept in a box above and behind the
guess, towards the condyles (:data:`_UP_AND_BACK` of the mouth's width up, and as much back). On the
tuning pairs of ``benchmarks/roundtrip_ict.py`` the lower teeth on the jawOpen frames came 0.83 cm from
the truth (median over pairs; 1.24 turned about the guess), and 0.54 with the exact motion (1.07).

Where the chin's control points cannot give a centre, :func:`jaw_angles` reads the turn about the parts'
own hinge off the chin's angle alone. Both keep to :data:`JAW_LIMITS`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ..parts import FaceParts

__all__ = ["JawTurns", "fitted_jaw_turns", "jaw_angles", "CHIN_WEIGHT", "JAW_LIMITS"]

JAW_LIMITS = (-0.05, 0.6)  # radians: a little closing past rest, about 34 degrees open

CHIN_WEIGHT = 0.9  # control points whose skin follows this much of the jaw's turn are taken as on the jaw
_FITTED_FRAMES = 256  # the widest openings the centre is fitted on (frames read, not the whole motion)
_LEAST_OPENING = 0.05  # of the mouth's width: a chin moving less says nothing of where it turns
_STILL = 1e-6  # of the mouth's width: a point moving no further on any frame is pinned, not followed
_NOISE = 0.01  # of the mouth's width: how far a tracked chin point strays from a rigid turn
# Of the mouth's width: how far the parts' centre may be from the fitted one. It decides only where the
# chin's motion leaves the centre open (points that all move one way say nothing of how far off it is).
_PRIOR = 0.5
# Of the mouth's width: how far the centre may move from the parts' (low on the ramus) up and back, towards
# the condyles, and down or forward, where no jaw turns. Unbounded, the chin's skin (which stretches as it
# turns) put the centre 3.5 cm in front of the guess on a round-trip pair and swung the teeth out 2 cm; on
# the tuning pairs (seeds 3, 4, 6, 7, 8, 9, 20) these bounds gave the lower teeth 0.83 cm off (median over
# pairs, worst 1.35), against 1.17 (1.59) unbounded, 1.07 (1.34) at twice as wide, and 1.24 (1.45) before.
_UP_AND_BACK, _DOWN_OR_FORWARD = 0.6, 0.1


@dataclass(frozen=True, eq=False)
class JawTurns:
    """A turning centre ``(3,)`` (model units) and the turn ``(T,)`` per frame about it (radians,
    opening positive)."""

    centre: np.ndarray
    angles: np.ndarray


def _plane(parts: FaceParts, points: np.ndarray) -> np.ndarray:
    """``(..., 2)`` the points' (y, z) in the face's axes: the plane the jaw turns in."""
    return np.asarray(points, dtype=np.float64) @ parts.axes[1:].T


def _turns_about(centre: np.ndarray, rest: np.ndarray, moved: np.ndarray) -> np.ndarray:
    """``(T,)`` the in-plane turn about ``centre (2,)`` that best takes ``rest (K, 2)`` to each frame of
    ``moved (T, K, 2)`` (least squares: the angle of the summed cross and dot products). In the face's
    (y, z) plane with x across, opening (the chin going down and back) is a positive turn."""
    r = rest - centre
    m = moved - centre
    cross = (r[None, :, 0] * m[..., 1] - r[None, :, 1] * m[..., 0]).sum(axis=1)
    dot = (r[None] * m).sum(axis=(1, 2))
    return np.arctan2(cross, dot)


def _turned(centre: np.ndarray, rest: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """``(T, K, 2)``: ``rest (K, 2)`` turned about ``centre (2,)`` by each of ``angles (T,)``."""
    r = rest - centre
    c, s = np.cos(angles)[:, None], np.sin(angles)[:, None]
    y = c * r[None, :, 0] - s * r[None, :, 1]
    z = s * r[None, :, 0] + c * r[None, :, 1]
    return np.stack([y, z], axis=-1) + centre


def fitted_jaw_turns(parts: FaceParts, rest: np.ndarray, control_vertices, displacements, *,
                     mouth_width: float, below=None, limits=(-np.inf, np.inf)) -> JawTurns | None:
    """The jaw's turning centre and turns fitted to the motion, or None where the motion does not say.

    Parameters
    ----------
    parts : FaceParts
    rest : (V, 3) float64
        The target's vertices.
    control_vertices : (K,) int64
    displacements : (T, K, 3)
        Or any object read by runs of frames (see :func:`~faceanim.retarget.deform.as_frames`).
    mouth_width : float
        Model units; the scale of what counts as a move, of a chin point's noise and of the prior.
    below : (3,) float64, optional
        A point on the lower lip (8.2): control points above it (on the lips, which move on their
        own) are left out.
    limits : (2,) float
        The turns are clipped to these.

    Uses the control points on the skin whose jaw weight is at least :data:`CHIN_WEIGHT`. The centre
    is fitted, with the parts' centre as its prior and within :data:`_UP_AND_BACK` of the mouth's width
    above and behind it (:data:`_DOWN_OR_FORWARD` below or in front), on the :data:`_FITTED_FRAMES`
    frames where those points move most; then every frame's turn is the rigid turn about it that fits them best. None
    where there are fewer than 3 such points or they never move :data:`_LEAST_OPENING` of the mouth's
    width. Points held still on every frame (pinned, not followed) are not counted; frames with NaN are not
    fitted on, and their turns are NaN.
    """
    ids = np.asarray(control_vertices, dtype=np.int64)
    on_jaw = parts.mask("skin")[ids] & (parts.jaw_weight[ids] >= CHIN_WEIGHT)
    if below is not None:
        on_jaw &= (rest[ids] - np.asarray(below, dtype=np.float64)) @ parts.axes[1] < 0.0
    chin = np.flatnonzero(on_jaw)
    if len(chin) < 3 or not len(displacements):
        return None
    chunks = range(0, len(displacements), _CHUNK)
    # Points held still on every frame are not followed but pinned (a FAP stream pins the feature points no
    # FAP moves): taken as on the jaw, they would hold its turn back.
    farthest = np.max([np.nanmax(np.linalg.norm(_run(displacements, a)[:, chin], axis=2), axis=0, initial=0.0)
                       for a in chunks], axis=0)
    chin = chin[farthest > _STILL * mouth_width]
    if len(chin) < 3:
        return None
    size = np.concatenate([np.linalg.norm(_run(displacements, a)[:, chin], axis=2).mean(axis=1) for a in chunks])
    size[~np.isfinite(size)] = -np.inf  # a frame without a face (NaN) is never among the widest
    if size.max() < _LEAST_OPENING * mouth_width:
        return None
    widest = np.sort(np.argsort(size)[-_FITTED_FRAMES:])
    widest = widest[np.isfinite(size[widest])]
    p = _plane(parts, rest[ids[chin]])
    moved = p + _plane(parts, _rows(displacements, widest)[:, chin])
    prior = _plane(parts, parts.hinge)

    def residuals(shift):  # each frame's turn is the best about the centre tried (variable projection)
        centre = prior + shift
        miss = _turned(centre, p, _turns_about(centre, p, moved)) - moved
        return np.r_[miss.ravel() / (_NOISE * mouth_width), shift / (_PRIOR * mouth_width)]

    reach = np.array([[-_DOWN_OR_FORWARD, -_UP_AND_BACK], [_UP_AND_BACK, _DOWN_OR_FORWARD]]) * mouth_width
    fit = least_squares(residuals, np.zeros(2), x_scale=mouth_width, bounds=reach)
    centre_2d = prior + fit.x
    centre = parts.hinge + fit.x @ parts.axes[1:]
    angles = np.concatenate([_turns_about(centre_2d, p, p + _plane(parts, _run(displacements, a)[:, chin]))
                             for a in chunks])
    return JawTurns(centre, np.clip(angles, *limits))


def _rows(displacements, frames: np.ndarray) -> np.ndarray:
    """``displacements[frames]`` (``frames`` sorted), read a run of :data:`_CHUNK` frames at a time."""
    if isinstance(displacements, np.ndarray):
        return displacements[frames]
    rows = []
    for start in range(0, len(displacements), _CHUNK):
        wanted = frames[(frames >= start) & (frames < start + _CHUNK)]
        if len(wanted):
            rows.append(_run(displacements, start)[wanted - start])
    return np.concatenate(rows)


def _run(displacements, start: int) -> np.ndarray:
    """The run of :data:`_CHUNK` frames from ``start``."""
    return np.asarray(displacements[start:start + _CHUNK], dtype=np.float64)


_CHUNK = 1024  # frames of the motion read at once


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
