"""`Motion`, the narrow waist of faceanim, and its conversion to MPEG-4 FAPs.

Every producer (a tracked video, a FAP file, a synthesised expression) makes a Motion; every
consumer (retargeting, FAP encoding, export) takes one. Control points are named: MPEG-4 feature
points by their number (``"8.3"``), other points by their producer's name (``"mp61"`` for MediaPipe
vertex 61). Positions are in the head frame with MPEG-4's axes (+X the face's left, +Y up, +Z out of
the face), rigid head motion removed and kept apart as a pose per frame.
"""

from __future__ import annotations

import numbers
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from .mpeg4 import ANGLE_UNIT, FAP_COUNT, Fapu, fap_table
from .mpeg4.fapstream import FapStream, fap_ranges
from .mpeg4.fapu import HUMAN_ES0
from .mpeg4.jaw import JAW_CARRIED, jaw_hinge, jaw_swing
from .validation import as_array

__all__ = ["Motion", "motion_to_faps", "clip_to_range", "head_angles", "relative_head_rotations", "rotation_part",
           "gaze_angles", "EYEBALL_RADIUS_ES0"]

# An adult eyeball's radius (1.2 cm) over a typical eye separation (HUMAN_ES0, 6.3 cm): the eyeball in
# the face's own yardstick, so iris shifts turn into the same gaze angles whatever the face's unit.
EYEBALL_RADIUS_ES0 = 0.012 / HUMAN_ES0


FrameSource = Callable[[int, int], np.ndarray]
"""``frames(start, stop)`` -> displacements ``(stop - start, K, 3)`` of frames ``start .. stop - 1``."""

CHUNK = 512  # frames read at once from a streamed motion: a few MB with MediaPipe's 478 points


class Motion:
    """Named control points moving over time; immutable (read-only arrays) and checked on construction.

    Parameters
    ----------
    names : tuple of str, (K,)
    neutral : (K, 3) float64
        Rest positions in the head frame.
    displacements : (T, K, 3) float64
        Per-frame displacement from ``neutral`` in the head frame; NaN on frames without data.
    pose : (T, 4, 4) float64
        Head frame to camera space, per frame (identity when unknown).
    fps : float
    fapu : Fapu
        Measured on ``neutral``.
    valid : (T,) bool, optional
        Frames with data; all by default.

    Positions and displacements are in the model units of the face they were measured on (the unit
    of ``fapu``; centimetres for a tracked video).

    ``Motion(...)`` holds the displacements given (read-only); :meth:`streamed` reads them on demand
    from a :data:`FrameSource` (a capture's frames kept on disk), so that a long video's motion
    costs one chunk of memory. Consumers read them with :meth:`chunk` or :meth:`chunks`;
    :attr:`displacements` makes them all at once (``T x K x 24`` bytes).

    Raises
    ------
    ValueError
        Repeated names, an array of the wrong shape, non-finite displacements on a valid frame or a
        non-positive fps (the field is named).
    TypeError
        A name that is not a string, or ``fapu`` not a Fapu.
    """

    __slots__ = ("names", "neutral", "pose", "fps", "fapu", "valid", "_held", "_source")

    def __init__(self, names, neutral, displacements, pose, fps, fapu, valid=None):
        names = tuple(names)
        d = as_array(displacements, "displacements", shape=("T", len(names), 3), finite=False, frozen=True)
        valid = np.ones(len(d), bool) if valid is None else valid
        self._init(names, neutral, pose, fps, fapu, valid, d, None)
        for start in range(0, len(d), 1024):  # by blocks: d[valid] would copy a long video's motion
            broken = self.valid[start:start + 1024] & ~np.isfinite(d[start:start + 1024]).all(axis=(1, 2))
            if broken.any():
                raise ValueError(f"displacements must be finite on valid frames, got NaN or infinity on frame "
                                 f"{start + int(np.argmax(broken))}")

    @classmethod
    def streamed(cls, names, neutral, frames: FrameSource, pose, fps, fapu, valid=None) -> Motion:
        """A motion whose displacements ``frames(start, stop)`` makes when read; its length is the pose's.
        (Each chunk is checked as it is read: finite on valid frames, of the right shape.)"""
        if not callable(frames):
            raise TypeError(f"frames must be a function (start, stop) -> displacements, got {type(frames).__name__}")
        motion = cls.__new__(cls)
        length = len(np.asarray(pose))
        motion._init(tuple(names), neutral, pose, fps, fapu, np.ones(length, bool) if valid is None else valid,
                     None, frames)
        return motion

    def _init(self, names, neutral, pose, fps, fapu, valid, held, source) -> None:
        if not all(isinstance(n, str) for n in names):
            raise TypeError(f"names must be strings, got {next(n for n in names if not isinstance(n, str))!r}")
        if len(set(names)) != len(names):
            raise ValueError("control point names must be distinct")
        if not isinstance(fapu, Fapu):
            raise TypeError(f"fapu must be a Fapu, got {type(fapu).__name__}")
        neutral = as_array(neutral, "neutral", shape=(len(names), 3), frozen=True)
        pose = as_array(pose, "pose", shape=("T" if held is None else len(held), 4, 4), frozen=True)
        if not len(pose):
            raise ValueError("a motion needs at least one frame")
        valid = as_array(valid, "valid", shape=(len(pose),), dtype=bool, frozen=True)
        if isinstance(fps, bool) or not isinstance(fps, numbers.Real) or not (np.isfinite(fps) and fps > 0):
            raise ValueError(f"fps must be a positive number, got {fps!r}")
        for field, value in (("names", names), ("neutral", neutral), ("pose", pose), ("fps", float(fps)),
                             ("fapu", fapu), ("valid", valid), ("_held", held), ("_source", source)):
            object.__setattr__(self, field, value)

    def __setattr__(self, name, value):
        raise AttributeError(f"a Motion is immutable; {name} cannot be set")

    def __reduce__(self):
        if self._held is None:
            raise TypeError("a streamed Motion reads its frames from an open file and cannot be pickled; "
                            "pickle Motion(m.names, m.neutral, m.displacements, ...) instead")
        return (Motion, (self.names, self.neutral, self._held, self.pose, self.fps, self.fapu, self.valid))

    def __repr__(self) -> str:
        kind = "streamed" if self._held is None else "held"
        return f"Motion({len(self)} frames, {len(self.names)} points, {self.fps:g} fps, {kind})"

    def __len__(self) -> int:
        return len(self.pose)

    @property
    def is_streamed(self) -> bool:
        """True when the displacements are read on demand rather than held."""
        return self._held is None

    def chunk(self, start: int, stop: int) -> np.ndarray:
        """Displacements ``(stop - start, K, 3)`` of frames ``start .. stop - 1`` (read-only when held)."""
        if not 0 <= start < stop <= len(self):
            raise IndexError(f"frames {start}:{stop} are outside the motion's 0:{len(self)}")
        if self._held is not None:
            return self._held[start:stop]
        made = np.asarray(self._source(start, stop), dtype=np.float64)
        if made.shape != (stop - start, len(self.names), 3):
            raise ValueError(f"the frame source made shape {made.shape} for frames {start}:{stop}, expected "
                             f"{(stop - start, len(self.names), 3)}")
        broken = self.valid[start:stop] & ~np.isfinite(made).all(axis=(1, 2))
        if broken.any():
            raise ValueError(f"displacements must be finite on valid frames, got NaN or infinity on frame "
                             f"{start + int(np.argmax(broken))}")
        return made

    def chunks(self, size: int = CHUNK):
        """``(start, displacements)`` in runs of ``size`` frames (the last may be shorter), first to last."""
        for start in range(0, len(self), int(size)):
            yield start, self.chunk(start, min(start + int(size), len(self)))

    @property
    def displacements(self) -> np.ndarray:
        """All displacements ``(T, K, 3)``, read-only; a streamed motion reads them all, every time asked."""
        if self._held is not None:
            return self._held
        whole = np.concatenate([d for _, d in self.chunks()])
        whole.flags.writeable = False
        return whole

    def points_over_time(self, names) -> np.ndarray:
        """Displacements ``(T, k, 3)`` of the named points only, read chunk by chunk (what a consumer
        of a few points of a long streamed motion holds)."""
        at = self.index(names)
        if self._held is not None:
            return self._held[:, at]
        out = np.empty((len(self), len(at), 3))
        for start, d in self.chunks():
            out[start:start + len(d)] = d[:, at]
        return out

    def index(self, names) -> np.ndarray:
        """Positions of the named points; a missing name raises ``KeyError`` naming it."""
        lookup = {n: i for i, n in enumerate(self.names)}
        missing = [n for n in names if n not in lookup]
        if missing:
            raise KeyError(f"motion has no control point {', '.join(missing)}")
        return np.array([lookup[n] for n in names], dtype=np.int64)


def head_angles(rotations) -> np.ndarray:
    """(T, 3) pitch, yaw, roll in radians of head rotations ``(T, 3, 3)`` (MPEG-4 axes and signs).

    MPEG-4 words, turned into right-handed angles about the head's own axes: pitch about +X
    (positive turns the face down), yaw about +Y (positive turns it toward its own left), roll about
    +Z (positive tilts it toward its own right). ``R = R_y(yaw) R_x(pitch) R_z(roll)``.

    >>> c, s = np.cos(0.1), np.sin(0.1)
    >>> yaw = np.array([[[c, 0, s], [0, 1, 0], [-s, 0, c]]])
    >>> [round(float(a), 6) + 0.0 for a in head_angles(yaw)[0]]  # + 0.0 turns -0.0 into 0.0
    [0.0, 0.1, 0.0]
    """
    R = np.asarray(rotations, dtype=np.float64)
    pitch = np.arcsin(np.clip(-R[:, 1, 2], -1, 1))
    yaw = np.arctan2(R[:, 0, 2], R[:, 2, 2])
    roll = np.arctan2(R[:, 1, 0], R[:, 1, 1])
    return np.stack([pitch, yaw, roll], axis=1)


def rotation_part(pose: np.ndarray) -> np.ndarray:
    """Rotations of similarity transforms ``(T, 4, 4)``, scale divided out."""
    A = pose[:, :3, :3]
    return A / np.cbrt(np.linalg.det(A))[:, None, None]


def gaze_angles(pupil_displacements, fapu: Fapu) -> np.ndarray:
    """``(T, 2)`` an eye's yaw (towards the face's left) and pitch (down), radians, from its pupil's
    displacement ``(T, 3)`` in the head frame: the shift over an eyeball of radius
    :data:`EYEBALL_RADIUS_ES0` times the face's ES0, so the angle does not depend on the unit.

    >>> from faceanim.mpeg4 import Fapu
    >>> fapu = Fapu(irisd0=1.0, es0=6.3, ens0=4.0, mns0=3.0, mw0=5.0)
    >>> [round(float(a), 6) + 0.0 for a in gaze_angles([[0.0, -1.2 / 2, 0.0]], fapu)[0]]  # pupil 6 mm down
    [0.0, 0.523599]
    """
    shift = np.asarray(pupil_displacements, dtype=np.float64) / (EYEBALL_RADIUS_ES0 * fapu.es0)
    return np.stack([np.arcsin(np.clip(shift[:, 0], -1, 1)), -np.arcsin(np.clip(shift[:, 1], -1, 1))], axis=1)


def relative_head_rotations(motion: Motion) -> np.ndarray:
    """(T, 3, 3) head rotations since the first valid frame, in the head frame (the identity on invalid
    frames and where no frame is valid)."""
    R = np.tile(np.eye(3), (len(motion), 1, 1))
    valid = motion.valid
    if valid.any():
        turned = rotation_part(motion.pose[valid])
        R[valid] = np.einsum("ji,tjk->tik", turned[0], turned)
    return R


def motion_to_faps(motion: Motion, *, name: str = "faceanim") -> FapStream:
    """The FAPs a motion's control points observe, frame by frame.

    A translational FAP is its feature point's displacement along the FAP's direction, in its FAPU
    (``shared/mpeg4/faps.csv``). The jaw is measured as a player will play it: ``open_jaw`` is the
    chin's drop, and ``thrust_jaw`` and the FAPs of the points the jaw carries (:data:`JAW_CARRIED`)
    are what is left after the swing that drop implies (:mod:`.mpeg4.jaw`). Eyeball yaw and pitch
    (23-26) come from the pupils' shift in the head frame over an eyeball of radius
    :data:`EYEBALL_RADIUS_ES0` times the face's ES0, so the neutral gaze is the zero and the angle
    does not depend on the motion's unit (a face in metres and in millimetres look the same way);
    head pitch, yaw and roll (48-50) from
    the pose relative to the first valid frame's. FAPs whose points the motion lacks are absent (mask
    False); invalid frames carry no FAPs.
    """
    table = fap_table()
    T = len(motion)
    values = np.zeros((T, FAP_COUNT))
    mask = np.zeros((T, FAP_COUNT), dtype=bool)
    units = motion.fapu.scale()
    lookup = {n: i for i, n in enumerate(motion.names)}
    opening = table.number("open_jaw") - 1
    measured = [j for j in range(2, FAP_COUNT) if len(table.feature_points[j]) == 1
                and table.feature_points[j][0] in lookup and table.direction[j].any()]
    # Only the points a FAP reads, chunk by chunk: a streamed capture's other points stay on disk.
    wanted = sorted({table.feature_points[j][0] for j in measured} | ({"2.1", "3.5", "3.6"} & lookup.keys()))
    seen = dict(zip(wanted, np.moveaxis(motion.points_over_time(wanted), 1, 0), strict=True))
    swing = _jaw_swing_seen(motion, seen["2.1"], table.direction[opening]) if "2.1" in lookup else None
    for j in measured:
        points = table.feature_points[j]
        d = seen[points[0]]
        if swing is not None and (points[0] in JAW_CARRIED or (points[0] == "2.1" and j != opening)):
            d = d - swing(motion.neutral[lookup[points[0]]])  # a player swings these with open_jaw first
        values[:, j] = d @ table.direction[j] / units[j]
        mask[:, j] = True
    eyes = {"3.5": ("yaw_l_eyeball", "pitch_l_eyeball"), "3.6": ("yaw_r_eyeball", "pitch_r_eyeball")}
    for pupil, names in eyes.items():
        if pupil in lookup:
            for fap, angle in zip(names, gaze_angles(seen[pupil], motion.fapu).T, strict=True):
                j = table.number(fap) - 1
                values[:, j] = angle / ANGLE_UNIT
                mask[:, j] = True
    valid = motion.valid
    if valid.any():
        angles = head_angles(relative_head_rotations(motion))
        for k, fap in enumerate(("head_pitch", "head_yaw", "head_roll")):
            j = table.number(fap) - 1
            values[:, j] = angles[:, k] / ANGLE_UNIT
            mask[:, j] = True
    mask &= valid[:, None]
    values = np.where(mask, np.nan_to_num(values), 0.0)
    return FapStream(values, mask, motion.fps, name=name)


def _jaw_swing_seen(motion: Motion, chin: np.ndarray, down: np.ndarray):
    """The jaw swing (:func:`.mpeg4.jaw.jaw_swing`) a player makes for the chin's drop along ``down`` on
    each frame (``chin (T, 3)``, the displacements of point 2.1), about the hinge of the motion's own
    neutral face. open_jaw cannot be negative, so a chin above rest makes no swing."""
    at = dict(zip(motion.names, motion.neutral, strict=True))
    drop = np.maximum(np.nan_to_num(chin @ down), 0.0)
    return jaw_swing(jaw_hinge(at, motion.fapu), at["2.1"], drop)


def clip_to_range(stream: FapStream) -> tuple[FapStream, int]:
    """``stream`` with values outside the MPEG-4 I-frame ranges clipped to them, and how many were.

    Measured motion leaves the legal range when the face does what the standard cannot say: a jaw
    closing past rest (unidirectional ``open_jaw`` below 0), a chin pulled back as the jaw rotates, a
    squint closing a lid past its neutral opening.
    """
    low, high = fap_ranges()
    clipped = np.clip(stream.values, low, high)
    count = int((stream.mask & (clipped != stream.values)).sum())
    return replace(stream, values=clipped), count
