"""From a `Track` to a `Motion`: head pose apart from expression, filtering, neutral, FAPU."""

from __future__ import annotations

import functools
import json
from importlib import resources

import numpy as np

from ..errors import InputError
from ..geometry.align import robust_depth_affine, robust_procrustes
from ..landmarks import FEATURE_POINT_LANDMARK, landmark_names
from ..motion import Motion
from ..mpeg4 import fapu_from_points
from .blinkcoupling import BlinkCoupling
from .blinkslide import BlinkSlide
from .browscores import BrowDrive
from .jaw import correct_jaw_depth
from .lidskin import follow_lid_skin
from .metric import canonical_face, metric_geometry_frames
from .neutral import relaxed_window
from .noisefloor import NoiseFloor
from .scores import scores_across_filled_frames
from .smoothing import OneEuro, OneEuroFilter
from .track import Track

__all__ = ["head_frame", "head_frame_into", "settle", "displacements_from", "mouth_gap", "track_to_motion",
           "restabilise", "rest_window", "brow_drive", "blink_slide", "score_drives", "unscored_drives",
           "view_features", "unview", "DEFAULT_SMOOTHING"]

DEFAULT_SMOOTHING = OneEuro()

# Of MediaPipe's Procrustes landmarks (metric.py), those that expressions move: 136/365 ride on the jaw,
# 147/376 and 205/425 on the cheeks a smile raises; the forehead's 10, 54/284 and 67/297, which a brow
# raise carries up 2-5 mm on ICT's own expressions (and MediaPipe's depth of them shifts by as much:
# benchmarks/results/skull_shifts.json); the cheeks under the eyes, 117/346 (a smile raises them 4 mm)
# and 143/372 (2 mm with a brow raise). Counted even at the robust fit's reduced weight, they tilted the
# head with brow raises and smiles. Round trip (the motion route) on the tuning seeds 3, 4, 6, 7, 8, 20,
# the view and blink tables made again for each set, median over seeds, with the first six only -> all
# fifteen (18 landmarks left in the fit): all 0.537 -> 0.518 (no seed worse; 3: 0.539 -> 0.496), brows
# 0.552 -> 0.531, blink 0.543 -> 0.536, smile 0.540 -> 0.541, jawOpen 0.401 -> 0.407. The forehead alone
# gave 0.526 (smile 0.550); also leaving out 119/348 and 132/361 (a smile moves them 2.5-3 mm) left too
# few: 0.539, brows 0.550. Over the 12 reporting pairs: median 0.57 -> 0.56 (no pair worse), blink 0.74
# -> 0.71, brows 0.61 -> 0.62 (benchmarks/results/roundtrip_pairs.md).
_MOVED_BY_EXPRESSION = (136, 365, 147, 376, 205, 425, 10, 54, 284, 67, 297, 117, 346, 143, 372)
_BLOCK = 256  # frames fitted at once: the fits' temporaries stay a few MB however long the video
# A skull landmark this far (cm) from its rest position counts half in the head fit (robust_procrustes).
# MediaPipe's depths of the eye corners and nose shift with blinks and smiles (and did of the forehead,
# since left out); fitted with full weights, the skull's landmarks pitched the head by 1.5-3.5 degrees on
# ICT renders of a still head, and the whole face seemed to move (benchmarks/roundtrip_ict.py).
_SKULL_SPREAD = 0.1
# The head's turn is filtered as the face's points are, a point this far (cm) from the axis standing for
# it: a rotation matrix's rows move at the turn's angular speed (rad/s), so its cut-off rises with
# speed by ``beta * _TURN_RADIUS``. A fixed cut-off (1.5 Hz) let the pose lag a real turn by 4 frames
# at 25 fps: 9 degrees behind a 20-degree yaw sweep on an ICT render (benchmarks/head_pose_ict.py).
_TURN_RADIUS = 10.0
# MediaPipe's depths breathe with expressions: on an ICT render of a still head the skull's landmarks'
# depths about their centre shrank by 2.6% through a blink and 3.6% through a brow raise (the truth:
# 0.01% and 0.2%), which moved the chin 0.2 cm back and the face's sides forward. A similarity's one
# scale cannot take that out; a stretch along the line of sight can, and the image does not see it
# (benchmarks/roundtrip_ict.py). The depths also tilt: through a smile on tuning seed 3 the skin that
# stays still came 1 mm forward and its depth rose 0.6 mm per cm of height, and an open jaw tilted it
# the other way; a similarity takes such a tilt as part turn, part shift, and leaves the rest on the
# face. So the last round's depth map is affine in the whole position (stretch, tilt and shift:
# robust_depth_affine), which the image does not see either. Only the last: fitted in turn with the
# similarity, the tilt trades against the head's pitch, which the image shows only faintly (a pitch moves
# points up or down in proportion to their depth): a forehead brought 3 mm forward turned the head 0.58
# degrees with the tilt in both rounds, 1.93 with 16 rounds, against 0.35 without it (measured while the
# forehead still counted in the fit; tests/test_headframe_pose.py now shifts the eyes' corners), so the
# pose stays the similarity's. Round trip (roundtrip_ict.run) on the tuning seeds 3, 4, 6, 7, 8, 9, 20, with
# the view table made again through it, median over seeds before -> after: 0.586 -> 0.560 (every seed
# better, seed 3 0.591 -> 0.531), jawOpen 0.44 -> 0.38, smile 0.56 -> 0.53 (worse on 8, 9, 20 by
# 0.02-0.04), blink 0.72 -> 0.72, brows 0.61 -> 0.55. The similarity and the depth's map are fitted in
# turn, this many times.
_FIT_ROUNDS = 2
# The depth map's robust scale (cm), half the similarity's: a few skull points an expression brings
# 3 mm forward pull the face's depth less (tests/test_headframe_pose.py's chin 0.63 -> 0.58 mm, measured
# while the forehead counted).
_DEPTH_SPREAD = 0.05


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
    temples and the cheeks beside the nose.
    """
    weights = (canonical_face().weights > 0).astype(np.float64)
    weights[list(_MOVED_BY_EXPRESSION)] = 0.0
    return weights


def restabilise(points: np.ndarray, pose: np.ndarray, rest: np.ndarray, usable: np.ndarray):
    """Each usable frame's head-frame ``points (T, L, 3)`` moved onto the face's own ``rest (L, 3)`` by
    the similarity over the skull's landmarks, then moved along the line of sight onto the rest's
    depths over the same landmarks (a stretch and shift of the depth, and in the last round a tilt too);
    ``pose (T, 4, 4)`` takes up the similarity's inverse, so camera-space positions are unchanged but
    along the line of sight (which the image does not see). Returns new ``(points, pose)``.

    The head frame from :func:`head_frame` is fitted to MediaPipe's canonical face, which is nobody's
    face at rest: a person's expression changes how it fits. Fitted to the person's own neutral, the
    skull's points stay put and only expression remains. The fit is robust (:func:`robust_procrustes`,
    :func:`~faceanim.geometry.align.robust_depth_affine`): skull points an expression carries off count
    less. The depth's map takes out the depth MediaPipe's reconstruction breathes and tilts with an
    expression (:data:`_FIT_ROUNDS`): a skull's depth does not change.
    """
    points, pose = np.array(points, dtype=np.float64), np.array(pose, dtype=np.float64)
    _restabilise_in_place(points, pose, rest, usable)
    return points, pose


def _usable_blocks(points, usable: np.ndarray):
    """``(start, stop, frames, block)`` for each block of :data:`_BLOCK` frames of ``points`` (an array or a
    store) holding a usable frame: ``frames`` the usable ones (video frame numbers), ``block``
    ``points[start:stop]`` (a view of an array, a copy from a store: the caller writes it back).
    Temporaries stay a block, however long the video."""
    for start in range(0, len(points), _BLOCK):
        stop = min(start + _BLOCK, len(points))
        frames = start + np.flatnonzero(usable[start:stop])
        if frames.size:
            yield start, stop, frames, points[start:stop]


def _restabilise_in_place(points, pose: np.ndarray, rest: np.ndarray, usable: np.ndarray) -> None:
    """:func:`restabilise`, writing into ``points`` (an array or a :class:`~faceanim.framestore.FrameStore`,
    read and rewritten a block at a time) and ``pose``."""
    weights = _skull_weights()
    for start, stop, frames, block in _usable_blocks(points, usable):
        moved = block[frames - start]
        to_frame = np.tile(np.eye(4), (len(frames), 1, 1))
        for round_ in range(_FIT_ROUNDS):  # the similarity and the depth's map, each fitted given the other
            fit = robust_procrustes(rest[:468], moved[:, :468], weights, scale=_SKULL_SPREAD)
            to_frame = to_frame @ fit
            moved = _apply(np.linalg.inv(fit), moved)
            sight = _towards_camera(pose[frames] @ to_frame)
            depth = robust_depth_affine(rest[:468], moved[:, :468], weights, sight, scale=_DEPTH_SPREAD,
                                        tilt=round_ == _FIT_ROUNDS - 1)
            moved = _apply(depth, moved)
        block[frames - start] = moved
        points[start:stop] = block
        pose[frames] = pose[frames] @ to_frame


def _apply(maps: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Affine ``maps (T, 4, 4)`` applied to ``points (T, L, 3)``."""
    return np.matmul(points, maps[:, :3, :3].transpose(0, 2, 1)) + maps[:, None, :3, 3]


def _towards_camera(pose: np.ndarray) -> np.ndarray:
    """``(T, 3)``: the unit direction from the head to the camera in the head frame, for each ``pose
    (T, 4, 4)`` (head frame to camera, the camera at the origin); the head's own forward axis (+z)
    where the pose puts the head at the camera (no translation: a pose not measured)."""
    linear = pose[:, :3, :3] / np.cbrt(np.linalg.det(pose[:, :3, :3]))[:, None, None]
    distance = np.linalg.norm(pose[:, :3, 3], axis=1)
    away = distance > 0
    seen = np.tile([0.0, 0.0, 1.0], (len(pose), 1))
    seen[away] = np.einsum("tji,tj->ti", linear[away], -pose[away, :3, 3] / distance[away, None])
    return seen


@functools.cache
def _view_table() -> np.ndarray:
    """``(5, L * 3)``: cm per unit of each of :func:`view_features`, per landmark and axis, from
    ``data/view_shifts.json`` (made by ``benchmarks/view_shifts.py``, which says how)."""
    with resources.files(__package__).joinpath("data", "view_shifts.json").open() as handle:
        return np.array(json.load(handle)["shift_cm_per_feature"], dtype=np.float64)


def view_features(pose: np.ndarray) -> np.ndarray:
    """``(T, 5)``: where the camera is seen from the head, for each ``pose (T, 4, 4)`` (head frame to
    camera): the unit direction from the head to the camera in the head frame, its x and y (about the
    sines of the yaw and the pitch the camera sees the face at), and their squares and product."""
    x, y = _towards_camera(pose)[:, :2].T
    return np.stack([x, y, x * x, y * y, x * y], axis=1)


def unview(points, pose: np.ndarray, usable: np.ndarray, at_rest=None) -> None:
    """Take out of head-frame ``points (T, L, 3)`` (an array or a store, rewritten a block at a time)
    what the angle the camera sees the face at adds to them, against the ``at_rest`` frames' angle
    (the median over the usable frames when None).

    MediaPipe's reconstruction of a face depends on the angle it is seen at: on ICT renders of a still
    face turned 20 degrees, the nose's base moved 2-3 mm in the head frame and the skull's landmarks
    up to 4 mm RMS, so that a real head turn left part of itself in the face's expression (issue 17:
    37% of a static point's motion on a speech clip followed the head angles). The shift is a
    quadratic in :func:`view_features`, learned on still ICT faces turned (``benchmarks/view_shifts.py``).
    """
    table = _view_table()
    features = np.full((len(pose), 5), np.nan)  # frames without a face have no pose to be seen from
    features[usable] = view_features(pose[usable])
    chosen = usable if at_rest is None else np.isin(np.arange(len(pose)), at_rest) & usable
    if not chosen.any():
        return
    calm = np.median(features[chosen], axis=0) if at_rest is None else features[chosen].mean(axis=0)
    landmarks = min(points.shape[1], table.shape[1] // 3)
    table = table.reshape(len(table), -1, 3)[:, :landmarks]
    for start, stop, frames, block in _usable_blocks(points, usable):
        block[frames - start, :landmarks] -= np.einsum("tf,flc->tlc", features[frames] - calm, table)
        points[start:stop] = block


def head_frame_into(landmarks, usable: np.ndarray, times: np.ndarray, width: int, height: int, points, pose,
                    smoothing: OneEuro | None = DEFAULT_SMOOTHING) -> None:
    """Fill ``points (T, L, 3)`` (an array or a :class:`~faceanim.framestore.FrameStore` of the same
    length) and ``pose (T, 4, 4)`` with :func:`head_frame` of the normalised ``landmarks`` (an array
    or a store), filtered by ``smoothing`` both ways, a block of frames at a time: what is held is a
    block, however long the video.

    The One Euro filter runs forward over the video, then backward, and the two are averaged: run one
    way, it lagged a blink's lid by 2 frames at 25 fps, and each way's lag cancels the other's (the
    capture is of a whole video, so the frames after each one are there to be read). The backward
    pass makes each block's head frame again (a third of a millisecond a frame) rather than keep the
    unfiltered points."""
    if smoothing is None:
        for start, stop, block, turned in _head_frame_blocks(landmarks, usable, width, height):
            points[start:stop], pose[start:stop] = block, turned
        return
    forward, backward = _HeadFilter(smoothing), _HeadFilter(smoothing)
    for start, stop, block, turned in _head_frame_blocks(landmarks, usable, width, height):
        forward(block, turned, usable[start:stop], times[start:stop])
        points[start:stop], pose[start:stop] = block, turned
    for start, stop, block, turned in _head_frame_blocks(landmarks, usable, width, height, backwards=True):
        back = slice(None, None, -1)  # the frames in reverse, their times negated: time runs forward for the filter
        backward(block[back], turned[back], usable[start:stop][back], -times[start:stop][back])
        points[start:stop] = 0.5 * (points[start:stop] + block)
        pose[start:stop] = 0.5 * (pose[start:stop] + turned)


def _head_frame_blocks(landmarks, usable: np.ndarray, width: int, height: int, *, backwards: bool = False):
    """``(start, stop, points, pose)`` of :func:`head_frame` a block of :data:`_BLOCK` frames at a time
    (NaN points and the identity pose on frames without a face), the last block first if ``backwards``."""
    starts = range(0, len(landmarks), _BLOCK)
    for start in reversed(starts) if backwards else starts:
        stop = min(start + _BLOCK, len(landmarks))
        raw, ok = landmarks[start:stop], usable[start:stop]
        block = np.full(raw.shape, np.nan)
        turned = np.tile(np.eye(4), (stop - start, 1, 1))
        if ok.any():
            block[ok], turned[ok] = metric_geometry_frames(raw[ok], width, height)
        yield start, stop, block, turned


class _HeadFilter:
    """The One Euro filters of the head-frame points and of the pose's move and turn, run over
    successive blocks of frames (their state carried across), each block filtered in place."""

    def __init__(self, smoothing: OneEuro):
        self._points, self._move = OneEuroFilter(smoothing), OneEuroFilter(smoothing)
        self._turn = OneEuroFilter(OneEuro(smoothing.min_cutoff, smoothing.beta * _TURN_RADIUS, smoothing.d_cutoff))

    def __call__(self, block: np.ndarray, turned: np.ndarray, ok: np.ndarray, when: np.ndarray) -> None:
        block[:] = self._points(block, when)
        # frames without a face restart the pose's filters as they do the points' (they hold the
        # identity, which the filters would otherwise take for a turn back to the camera's axes)
        translation = self._move(np.where(ok[:, None, None], turned[:, None, :3, 3], np.nan), when)[:, 0]
        linear = self._turn(np.where(ok[:, None, None], turned[:, :3, :3], np.nan), when)
        turned[ok, :3, 3] = translation[ok]
        turned[ok, :3, :3] = linear[ok]


def mouth_gap(points) -> np.ndarray:
    """``(T,)`` the inner lips' vertical gap (feature points 2.2 and 2.3) of head-frame ``points``
    (an array or a store, read a block at a time)."""
    top, bottom = FEATURE_POINT_LANDMARK["2.2"], FEATURE_POINT_LANDMARK["2.3"]
    gap = np.empty(len(points))
    for start in range(0, len(points), _BLOCK):
        block = points[start:start + _BLOCK]
        gap[start:start + len(block)] = np.abs(block[:, top, 1] - block[:, bottom, 1])
    return gap


def settle(points, pose: np.ndarray, usable: np.ndarray, fps: float, *, neutral=None, neutral_points=None):
    """Choose the face at rest and refit the head frame to it: ``points`` (head frame, an array or a
    store) and ``pose`` are rewritten in place (:func:`restabilise`, then :func:`unview` against the
    neutral frames); returns the rest ``(L, 3)`` and its FAPU. ``neutral``, ``(start, end)`` frames, is
    found by :func:`relaxed_window` when None; ``neutral_points`` measured elsewhere override it (and
    :func:`unview` is not made: the angle they were seen at is not known here).

    Raises
    ------
    InputError
        The neutral frames hold no tracked face, or the neutral gives no usable FAPU.
    """
    if neutral_points is not None:
        rest = np.asarray(neutral_points, dtype=np.float64)
    else:
        if neutral is None:
            neutral = relaxed_window(points, usable, fps, mouth=mouth_gap(points))
        start, end = neutral
        chosen = usable[start:end]
        if not chosen.any():
            raise InputError(f"the neutral frames {start}:{end} hold no tracked face")
        rest = points[start:end][chosen].mean(axis=0)
    _restabilise_in_place(points, pose, rest, usable)
    if neutral_points is None:  # a neutral measured elsewhere was seen from an angle not known here
        unview(points, pose, usable, start + np.flatnonzero(chosen))
    if neutral_points is None:
        rest = points[start:end][chosen].mean(axis=0)
    names = landmark_names(len(rest))
    try:
        fapu = fapu_from_points(dict(zip(names, rest, strict=True)))
    except ValueError as exc:
        raise InputError(f"the neutral face gives no usable FAPU ({exc})") from None
    return rest, fapu


def rest_window(points, usable: np.ndarray, fps: float, neutral=None, neutral_points=None):
    """The ``(start, end)`` frames the neutral is read from: ``neutral`` when given, else those
    :func:`relaxed_window` finds in head-frame ``points``; None when ``neutral_points`` give the
    neutral instead. What :func:`settle` takes as ``neutral``."""
    if neutral_points is not None:
        return None
    if neutral is not None:
        return neutral
    return relaxed_window(points, usable, fps, mouth=mouth_gap(points))


def brow_drive(blendshapes, names, times, fapu, usable: np.ndarray, window,
               smoothing: OneEuro | None = DEFAULT_SMOOTHING) -> BrowDrive | None:
    """The brow heights the tracker's scores call for (:class:`~.browscores.BrowDrive`), calibrated on
    the usable ones of the ``window`` frames at rest (on the whole video when None); None without brow
    scores."""
    at_rest = None if window is None else window[0] + np.flatnonzero(usable[window[0]:window[1]])
    return BrowDrive.of_scores(blendshapes, names, times, fapu.ens0, at_rest, smoothing=smoothing)


def blink_slide(blendshapes, names, times, rest: np.ndarray, fapu, usable: np.ndarray, window,
                smoothing: OneEuro | None = DEFAULT_SMOOTHING) -> BlinkSlide | None:
    """The sideways slide the tracker draws with each blink (:class:`~.blinkslide.BlinkSlide`), its
    scores calibrated as :func:`brow_drive`'s; None without blink scores."""
    at_rest = None if window is None else window[0] + np.flatnonzero(usable[window[0]:window[1]])
    return BlinkSlide.of_scores(blendshapes, names, times, rest, fapu.es0, at_rest, smoothing=smoothing)


def score_drives(blendshapes, names, times, rest: np.ndarray, fapu, usable: np.ndarray, window,
                 smoothing: OneEuro | None = DEFAULT_SMOOTHING) -> list:
    """What the tracker's blendshape scores change in the displacements, in the order applied: the
    brows' heights (:func:`brow_drive`), then the eyes' sideways slide in a blink (:func:`blink_slide`);
    each has ``apply(displacements, start)``. Empty without scores. Frames whose landmarks were filled
    across a short gap get scores filled the same way (:func:`~.scores.scores_across_filled_frames`)."""
    blendshapes = scores_across_filled_frames(blendshapes, usable)
    drives = (brow_drive(blendshapes, names, times, fapu, usable, window, smoothing),
              blink_slide(blendshapes, names, times, rest, fapu, usable, window, smoothing))
    return [drive for drive in drives if drive is not None]


def unscored_drives(rest: np.ndarray, fapu, *, floor: bool = True) -> list:
    """The drives that need no scores, applied after the scores' drives, in order: what the tracker moves
    with a blink that the face does not, taken out (:class:`~.blinkcoupling.BlinkCoupling`), then, with
    ``floor``, the motion under the tracker's noise floor dropped (:class:`~.noisefloor.NoiseFloor`); empty
    for a layout without MediaPipe's face mesh."""
    drives = (BlinkCoupling.of_face(rest, fapu), NoiseFloor.of_face(rest, fapu) if floor else None)
    return [drive for drive in drives if drive is not None]


def displacements_from(points: np.ndarray, rest: np.ndarray, usable: np.ndarray) -> np.ndarray:
    """Head-frame ``points (t, L, 3)`` (changed in place) as displacements from ``rest``: NaN on frames
    without a face, the jaw's points given the depth the chin's drop implies (:func:`.jaw.correct_jaw_depth`),
    the upper lids' skin brought down with their lash lines (:func:`.lidskin.follow_lid_skin`)."""
    points -= rest
    points[~usable] = np.nan
    return follow_lid_skin(correct_jaw_depth(rest, points, out=points))


def track_to_motion(track: Track, *, neutral=None, smoothing: OneEuro | None = DEFAULT_SMOOTHING,
                    neutral_points=None, scores: bool = True, floor: bool = True) -> Motion:
    """The tracked face's motion, held in memory (a long video streams through
    :func:`faceanim.capture.stream.captured` instead).

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
    scores : bool
        Brow heights from the tracker's blendshape scores where the track has them
        (:mod:`.browscores`), and the eyes' sideways slide in a blink taken out (:mod:`.blinkslide`);
        False keeps the tracked movement (the lid skin's and the jaw's corrections, the blink's
        coupling taken out, :mod:`.blinkcoupling`, and the noise floor, :mod:`.noisefloor`, need no
        scores and still apply).
    floor : bool
        Drop each point's motion under the tracker's noise floor (:mod:`.noisefloor`): for a motion that
        is shown, where a still face should stay still. Independent of ``smoothing`` here; the jobs
        (:mod:`faceanim.inputs`) turn it off with the filter (``--no-filter``) and in the speaker's
        commands, whose linear model, fitted over many frames, averages the noise away itself and was
        built without the floor (which is not linear in the motion).
    """
    usable = track.usable
    # One (T, L, 3) array, made here and then changed in place, step by step: a long video's
    # landmarks are held once here (and once in the track), not once per step.
    points = np.empty(track.landmarks.shape)
    pose = np.empty((len(track), 4, 4))
    head_frame_into(track.landmarks, usable, track.times, track.width, track.height, points, pose, smoothing)
    window = rest_window(points, usable, track.fps, neutral, neutral_points)
    rest, fapu = settle(points, pose, usable, track.fps, neutral=window, neutral_points=neutral_points)
    displacements = displacements_from(points, rest, usable)
    drives = score_drives(track.blendshapes, track.blendshape_names, track.times, rest, fapu, usable, window,
                          smoothing) if scores else []
    for drive in drives + unscored_drives(rest, fapu, floor=floor):
        drive.apply(displacements, 0)
    displacements.flags.writeable = False  # handed over: the Motion takes it uncopied
    return Motion(landmark_names(len(rest)), rest, displacements, pose, track.fps, fapu, valid=usable)
