"""A Motion onto a target directly: every control point the two share moves the target, in 3D.

The FAP route (:mod:`.decode`) keeps what MPEG-4 can say: one or two axes per feature point, each in
its own FAPU. A tracked Motion knows more: the full 3D motion of all its points (MediaPipe's 478), and
a target placed automatically carries the same named points. Following the Motion directly keeps the
lip corners' backward pull, the cheeks and the lids' shape, which FAPs drop (on ICT-FaceKit,
``benchmarks/roundtrip_ict.py`` compares the two).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..geometry.align import weighted_procrustes
from ..geometry.animation import Animation
from ..motion import Motion, relative_head_rotations
from ..mpeg4.fapstream import FapStream
from ..parts import FaceParts
from ..target import Target
from .decode import turn_head
from .deform import parts_frames
from .lids import LidOpenings

__all__ = ["animate_motion", "shared_points", "MINIMUM_SHARED_POINTS"]

MINIMUM_SHARED_POINTS = 8  # fewer cannot say where the jaw, the lips and the lids go

# Pupils and iris rims move with the eyeball, not the skin; on the skin they would drag the lids.
_EYEBALL_POINTS = frozenset({"3.5", "3.6", *(f"mp{i}" for i in range(468, 478))})


def shared_points(motion: Motion, target: Target) -> tuple[str, ...]:
    """Names of the motion's points that the target also carries, less the eyeballs' points."""
    return tuple(n for n in motion.names if n in target.points and n not in _EYEBALL_POINTS)


def animate_motion(motion: Motion, target: Target, *, head_motion: bool = False, pivot=None,
                   minimum_points: int = MINIMUM_SHARED_POINTS, parts: FaceParts | None = None,
                   gaze: FapStream | None = None) -> Animation:
    """The target moved by ``motion``, streamed (its frames are made as they are read).

    Displacements are carried from the motion's head frame into the target's by the similarity that
    best maps the motion's neutral points onto the target's (rotation and one scale, over all shared
    points, so no single distance's placement error sets the size), the lids' closing as a share of
    each eye's opening (:mod:`.lids`, as MPEG-4's eyelid FAPs carry it), then spread over the mesh by
    the head part by part (:class:`~.deform.PartsDeformer`: the jaw turned about its hinge with the
    skin, the residual spread on top by surface-aware interpolation, rigid teeth, lid layers riding
    on the skin; the eyeballs turned by ``gaze``'s FAPs 23-26 when given). ``parts`` defaults to
    :func:`~faceanim.parts.face_parts` of the target. Frames without a face hold the last face
    seen (rest before the first). With ``head_motion`` the mesh also turns as the head did, about
    ``pivot`` (default: the centre of the shared points).

    Raises
    ------
    InputError
        The motion and the target share fewer than ``minimum_points`` control points.
    """
    names = shared_points(motion, target)
    if len(names) < minimum_points:
        raise InputError(f"the motion and the target share {len(names)} control points; at least "
                         f"{minimum_points} are needed (give the target MediaPipe's points or MPEG-4 feature points)")
    ids = target.ids(names)
    ids, first = np.unique(ids, return_index=True)  # two names on one vertex: keep the first
    names = [names[i] for i in first]
    source = motion.neutral[motion.index(names)]
    carry = weighted_procrustes(source, target.mesh.vertices[ids])[:3, :3]
    lids = LidOpenings.of(names, source, target.mesh.vertices[ids], carry)
    displacements = _CarriedControls(motion, names, carry, lids)
    animation = Animation.streamed(target.mesh, parts_frames(target, parts, ids, displacements, gaze), len(motion),
                                   motion.fps)
    if head_motion:
        centre = target.mesh.vertices[ids].mean(axis=0) if pivot is None else pivot
        turn = carry / np.cbrt(np.linalg.det(carry))  # the carry's rotation: the head turns in the target's axes
        rotations = turn @ relative_head_rotations(motion) @ turn.T
        animation = animation.map(lambda a, b, positions: turn_head(positions, rotations[a:b], centre))
    return animation


class _CarriedControls:
    """The shared points' displacements ``(T, K, 3)`` carried into the target's axes, read from the
    motion a run of frames at a time (``controls[a:b]``): a streamed capture's motion is never held
    whole. A frame without a face holds the last face seen (zeros, the rest, before the first)."""

    def __init__(self, motion: Motion, names, carry: np.ndarray, lids: LidOpenings):
        self._motion, self._at, self._carry = motion, motion.index(names), carry
        self._lids = lids  # the lids' motion as a share of the eye's opening
        seen = np.where(motion.valid, np.arange(len(motion)), -1)
        self._shown = np.maximum.accumulate(seen)  # the frame whose face each frame shows; -1: the rest

    def __len__(self) -> int:
        return len(self._motion)

    def __getitem__(self, key: slice) -> np.ndarray:
        start, stop, _ = key.indices(len(self))
        stop = max(start, stop)
        shown = self._shown[start:stop]
        out = np.zeros((stop - start, len(self._at), 3))
        frames = np.unique(shown[shown >= 0])
        if frames.size:  # frames in the run, and at most one before it (the last face before a gap)
            read = np.empty((len(frames), len(self._at), 3))
            inside = frames >= start
            if (~inside).any():
                first = int(frames[0])
                read[0] = self._motion.chunk(first, first + 1)[0, self._at]
            if inside.any():
                lo, hi = int(frames[inside][0]), int(frames[inside][-1]) + 1
                read[inside] = self._motion.chunk(lo, hi)[frames[inside] - lo][:, self._at]
            has = shown >= 0
            out[has] = read[np.searchsorted(frames, shown[has])]
        return self._lids(out @ self._carry.T)
