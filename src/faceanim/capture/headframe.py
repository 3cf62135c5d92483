"""From a `Track` to a `Motion`: head pose apart from expression, filtering, neutral, FAPU."""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..geometry.align import batch_procrustes
from ..motion import Motion
from ..mpeg4 import fapu_from_points
from .jaw import correct_jaw_depth
from .landmarks import FEATURE_POINT_LANDMARK
from .metric import canonical_face, metric_geometry_frames
from .neutral import relaxed_window
from .smoothing import OneEuro, one_euro
from .track import Track

__all__ = ["head_frame", "track_to_motion", "landmark_names", "restabilise", "DEFAULT_SMOOTHING"]

DEFAULT_SMOOTHING = OneEuro()

# Of MediaPipe's Procrustes landmarks (metric.py), those that expressions move: 136/365 ride on the jaw,
# 147/376 and 205/425 on the cheeks a smile raises.
_MOVED_BY_EXPRESSION = (136, 365, 147, 376, 205, 425)
_BLOCK = 256  # frames fitted at once: the fits' temporaries stay a few MB however long the video


def landmark_names(count: int) -> tuple[str, ...]:
    """Names of MediaPipe's landmarks: the MPEG-4 feature point where one sits, else ``mp<i>``."""
    names = [f"mp{i}" for i in range(count)]
    for point, index in FEATURE_POINT_LANDMARK.items():
        if index < count:
            names[index] = point
    return tuple(names)


def head_frame(track: Track):
    """Landmarks in the head frame (cm, MPEG-4 axes) and the head pose, per frame.

    Returns ``points (T, L, 3)`` and ``pose (T, 4, 4)``; frames without landmarks hold NaN and the
    identity.
    """
    T, L, _ = track.landmarks.shape
    points = np.full((T, L, 3), np.nan)
    pose = np.tile(np.eye(4), (T, 1, 1))
    usable = np.flatnonzero(track.usable)
    for start in range(0, len(usable), _BLOCK):  # the fit's temporaries bounded by a block, not the video
        at = usable[start:start + _BLOCK]
        points[at], pose[at] = metric_geometry_frames(track.landmarks[at], track.width, track.height)
    return points, pose


def _skull_weights() -> np.ndarray:
    """``(468,)`` equal weights on the landmarks that stay with the skull, zero elsewhere.

    MediaPipe's own weights favour the nostrils (a quarter of the total) and include the jaw and
    cheeks, so a smile or an open jaw tilts and lifts the fitted head, and every other point seems to
    move the other way. Equal weights over the rest spread the fit over the nose ridge, eye corners,
    forehead and temples.
    """
    weights = (canonical_face().weights > 0).astype(np.float64)
    weights[list(_MOVED_BY_EXPRESSION)] = 0.0
    return weights


def restabilise(points: np.ndarray, pose: np.ndarray, rest: np.ndarray, usable: np.ndarray):
    """Each usable frame's head-frame ``points (T, L, 3)`` moved onto the face's own ``rest (L, 3)`` by
    the similarity over the skull's landmarks; ``pose (T, 4, 4)`` takes up the inverse, so camera-space
    positions are unchanged. Returns new ``(points, pose)``.

    The head frame from :func:`head_frame` is fitted to MediaPipe's canonical face, which is nobody's
    face at rest: a person's expression changes how it fits. Fitted to the person's own neutral, the
    skull's points stay put and only expression remains.
    """
    return _restabilise_in_place(points.copy(), pose.copy(), rest, usable)


def _restabilise_in_place(points: np.ndarray, pose: np.ndarray, rest: np.ndarray, usable: np.ndarray):
    """:func:`restabilise`, writing into ``points`` and ``pose`` (a capture's own arrays, so that a long
    video's landmarks are not held twice)."""
    usable_frames = np.flatnonzero(usable)
    weights = _skull_weights()
    for start in range(0, len(usable_frames), _BLOCK):  # temporaries bounded by a block, not the video
        frames = usable_frames[start:start + _BLOCK]
        to_frame = batch_procrustes(rest[:468], points[frames, :468], weights)
        back = np.linalg.inv(to_frame)
        points[frames] = np.einsum("tij,tlj->tli", back[:, :3, :3], points[frames]) + back[:, None, :3, 3]
        pose[frames] = pose[frames] @ to_frame
    return points, pose


def track_to_motion(track: Track, *, neutral=None, smoothing: OneEuro | None = DEFAULT_SMOOTHING,
                    neutral_points=None) -> Motion:
    """The tracked face's motion.

    The head frame is refitted to the face's own neutral (:func:`restabilise`), and the depth of the
    points the jaw carries follows the chin's drop (:func:`.jaw.correct_jaw_depth`).

    Parameters
    ----------
    track : Track
    neutral : (start, end) frames, optional
        Where the face is at rest; chosen automatically (:func:`relaxed_window`) when None.
    smoothing : OneEuro or None
        Temporal filter on head-frame landmarks and pose; None turns it off.
    neutral_points : (L, 3) float64, optional
        A neutral measured elsewhere (for example from a separate image), in the head frame;
        overrides ``neutral``.
    """
    # One (T, L, 3) array, made by head_frame and then changed in place, step by step: a long video's
    # landmarks are held once here (and once in the track), not once per step.
    points, pose = head_frame(track)
    usable = track.usable
    if smoothing is not None:
        one_euro(points, track.times, smoothing, out=points)
        translation = one_euro(pose[:, :3, 3][:, None], track.times, smoothing)[:, 0]
        linear = one_euro(pose[:, :3, :3], track.times, OneEuro(smoothing.min_cutoff, 0.0, smoothing.d_cutoff))
        pose = pose.copy()
        pose[usable, :3, 3] = translation[usable]
        pose[usable, :3, :3] = linear[usable]
    if neutral_points is not None:
        rest = np.asarray(neutral_points, dtype=np.float64)
    else:
        if neutral is None:
            mouth = np.abs(points[:, FEATURE_POINT_LANDMARK["2.2"], 1] - points[:, FEATURE_POINT_LANDMARK["2.3"], 1])
            neutral = relaxed_window(points, usable, track.fps, mouth=mouth)
        start, end = neutral
        chosen = usable[start:end]
        if not chosen.any():
            raise InputError(f"the neutral frames {start}:{end} hold no tracked face")
        rest = points[start:end][chosen].mean(axis=0)
    points, pose = _restabilise_in_place(points, pose.copy(), rest, usable)
    if neutral_points is None:
        rest = points[start:end][chosen].mean(axis=0)
    names = landmark_names(points.shape[1])
    lookup = {n: rest[i] for i, n in enumerate(names)}
    try:
        fapu = fapu_from_points(lookup)
    except ValueError as exc:
        raise InputError(f"the neutral face gives no usable FAPU ({exc})") from None
    displacements = points
    displacements -= rest
    displacements[~usable] = np.nan
    correct_jaw_depth(rest, displacements, out=displacements)
    displacements.flags.writeable = False  # handed over: the Motion takes it uncopied
    return Motion(names, rest, displacements, pose, track.fps, fapu, valid=usable)
