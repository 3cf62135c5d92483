"""``faceanim speaker track``: a video's articulatory parameters by analysis by synthesis with the
speaker's clone (:mod:`faceanim.speaker.analysis`), with the FAPs they give and a wireframe overlay.

The video is tracked first (the streamed capture: landmarks on disk), for three things only: the
head's rigid motion per frame (the capture's pose registered to the frame's landmarks of the model's
static points through the camera, :func:`faceanim.speaker.camera.register_rigid`; with ``rigid`` the
simplex corrects it), the video's camera (fitted on up to 60 of its frames,
:func:`faceanim.speaker.camera.fit_video_camera`) and
the first frame's starting point (the landmark-based analysis, ``SpeakerModel.fit_points``; each later
frame starts from the previous frame's answer, and the first after a stretch without a face from its
own landmarks); each frame's answer is pulled toward the frame's landmark-based reading and the previous
frame's answer where the image is flat (``CloneAnalyser``'s ``anchor`` and ``continuity``). Frames
where the capture finds no face are not analysed: they are marked invalid and hold the last analysed
frame's parameters. The colour model is adapted to the video's lighting on
its first 3 frames. Frames are then decoded one at a time; memory does not grow with the video.
"""

from __future__ import annotations

import contextlib
import csv
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .atomic import atomic_output, output_group
from .errors import InputError
from .outputs import check_outputs

__all__ = ["track_speaker", "TrackedSpeech", "FIELDS", "frame_ranges"]

FIELDS = ("top", "bottom")
_ADAPT_FRAMES = 3
_CAMERA_FRAMES = 60


@dataclass(frozen=True, eq=False)
class TrackedSpeech:
    """What :func:`track_speaker` found: ``parameters (T, K)``, ``rigid (T, 6)`` (the head's rotation
    vector in radians and translation in cm, :mod:`faceanim.speaker.camera`), ``evaluations (T,)``,
    ``cost (T,)``, the landmark-based ``landmark_parameters (T, K)`` (``fit_points`` of the capture),
    the seconds the analysis took (decoding and the capture not counted), the FAP stream, and the
    video's ``camera (3, 4)`` and ``mouth_width`` (pixels) the analysis used; ``valid (T,)`` bool: the
    frames analysed (False: no face found there; those frames hold the last analysed frame's
    parameters, with 0 evaluations and a nan cost)."""

    parameters: np.ndarray
    rigid: np.ndarray
    evaluations: np.ndarray
    cost: np.ndarray
    landmark_parameters: np.ndarray
    seconds: float
    stream: object
    camera: np.ndarray
    mouth_width: float
    valid: np.ndarray | None = None


def frame_ranges(frames) -> str:
    """Frame numbers as runs: ``[3, 4, 5, 9] -> "3-5, 9"``.

    >>> frame_ranges([3, 4, 5, 9, 11, 12])
    '3-5, 9, 11-12'
    """
    frames = sorted(int(f) for f in frames)
    runs, start = [], None
    for i, f in enumerate(frames):
        if start is None:
            start = f
        if i + 1 == len(frames) or frames[i + 1] != f + 1:
            runs.append(f"{start}" if start == f else f"{start}-{f}")
            start = None
    return ", ".join(runs)


def _field_rows(image: np.ndarray, field) -> np.ndarray:
    """One field's rows of an interlaced frame (top: 0, 2, ...; bottom: 1, 3, ...), or the frame."""
    if field is None:
        return image
    return np.ascontiguousarray(image[(0 if field == "top" else 1)::2])


def _draw(image, xy, triangles, colour) -> None:
    import cv2

    edges = np.unique(np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]),
                              axis=1), axis=0)
    lines = np.round(xy[edges] * 4).astype(np.int32)  # 2 bits of sub-pixel precision
    cv2.polylines(image, list(lines), False, colour, 1, cv2.LINE_AA, shift=2)


def track_speaker(video, output, *, model, fap=None, overlay=None, motion_out=None, max_evals: int = 150,
                  rigid: bool = False,
                  field=None, raster: str | None = None, neutral=None, smoothing: bool = True,
                  progress=None, supersample: bool = False) -> TrackedSpeech:
    """``faceanim speaker track``: the articulatory parameters of every frame of ``video`` (written
    to ``output``, ``.csv``: ``frame, timestamp, <parameter names>`` as ``faceanim speaker analyse
    --params-csv`` writes), the FAPs they give through the model (``fap``, ``.fap``), the analysed
    clone's wireframe over the frames (``overlay``, ``.mp4``: the model's mesh in green, the analysis
    mesh in yellow) and the head's rigid motion per frame (``motion_out``, ``.csv``: ``frame, rx, ry,
    rz`` (rotation vector, radians), ``tx, ty, tz`` (cm), as ``faceanim speaker render --motion``
    reads it; analysed with ``rigid``, else the capture's).

    ``model``: a speaker file with an appearance (``faceanim speaker textures``); ``max_evals``: the
    cap on evaluations per frame; ``field``: ``"top"`` or ``"bottom"`` analyses one field of
    interlaced footage (its rows only: the overlay has half the rows); ``raster``: ``"gl"``,
    ``"numpy"`` or None (GL where it can run, else numpy; :mod:`faceanim.speaker.lipraster`);
    ``supersample``: the mean of every frame pixel under each of the comparison's box pixels compared
    with the clone read at each, not the middle one alone (:class:`~faceanim.speaker.analysis.CloneAnalyser`'s
    ``supersample``: not closer on the clone's own frames since the middle one is read exactly, 0.079
    against 0.063 of a parameter's spread, at 45-70% of the speed).

    Raises
    ------
    InputError
        A model without textures; a bad ``max_evals`` or ``field``; a video in which the mouth leaves
        the frame, naming the frames, or with no face at all. Nothing is written then. (Frames without a
        face are not an error: they are marked in ``TrackedSpeech.valid`` and hold the last answer.)
    """
    from .capture.video import open_frames
    from .inputs import captured_source
    from .mpeg4.fapfile import write_fap
    from .progress import as_progress
    from .speaker import read_speaker
    from .speaker.analysis import CloneAnalyser
    from .speaker.appearance import read_appearance
    from .speaker.camera import fit_video_camera, pose_matrix, register_rigid, rigid_of_pose, to_rigid
    from .speaker.mouthmesh import analysis_mesh

    output = Path(output)
    check_outputs({"-o": (output, ".csv"), "--fap": (fap, ".fap"), "--overlay": (overlay, ".mp4"),
                   "--motion-out": (motion_out, ".csv")},
                  inputs={"VIDEO": video, "--model": model, "--neutral": neutral})
    if not isinstance(supersample, (bool, np.bool_)):
        raise InputError(f"supersample must be True or False, got {supersample!r}")
    if isinstance(max_evals, bool) or not isinstance(max_evals, (int, np.integer)) or not 1 <= max_evals <= 100000:
        raise InputError(f"--max-evals {max_evals}: give a whole number of evaluations, at most 100000")
    if field is not None and field not in FIELDS:
        raise InputError(f"--field {field}: choose top or bottom")
    speaker = read_speaker(model)
    vertices = speaker.parameter_count + 1 + (6 if rigid else 0)  # the simplex's first vertices
    if max_evals < vertices:
        raise InputError(f"--max-evals {max_evals}: the simplex over {vertices - 1} parameters"
                         f"{' (with --rigid)' if rigid else ''} needs at least {vertices} evaluations")
    appearance = read_appearance(model)
    if appearance is None:
        raise InputError(f"{model}: the speaker model has no textures; add them first with faceanim speaker "
                         f"textures VIDEO --model {model} -o {model}")
    if len(appearance.uv) != len(speaker.names) + len(speaker.static_names):
        raise InputError(f"{model}: its appearance has {len(appearance.uv)} points but the model "
                         f"{len(speaker.names) + len(speaker.static_names)}; make the textures again")
    mesh = analysis_mesh(speaker)
    shown = as_progress(progress)

    # Without the noise floor, as the model was built (speaker build): its parameters start from the points.
    capture = captured_source(video, neutral=neutral, smoothing=smoothing, progress=shown, folder=output.parent,
                              floor=False)
    motion = capture.motion
    missing = [n for n in speaker.names if n not in set(motion.names)]
    if missing:
        raise InputError(f"{model}: the model moves points the capture of {video} lacks ({', '.join(missing[:5])})")
    T = len(motion)
    usable = np.asarray(motion.valid, dtype=bool)  # a frame without a face is marked, not analysed
    if not usable.any():
        raise InputError(f"{video}: no face is found on any of its {T} frames")
    head = np.zeros((T, 6))
    head[usable] = rigid_of_pose(motion.pose[usable])
    columns = motion.index(speaker.names)
    start = np.full((T, speaker.parameter_count), np.nan)
    chosen = np.flatnonzero(usable)[np.linspace(0, usable.sum() - 1, min(_CAMERA_FRAMES, usable.sum())).astype(int)]
    names = tuple(motion.names)
    points = np.full((len(chosen), len(names), 3), np.nan)
    for begin, d in motion.chunks():
        start[begin:begin + len(d)] = speaker.fit_points(d[:, columns])
        at = (chosen >= begin) & (chosen < begin + len(d))
        points[at] = motion.neutral + d[chosen[at] - begin]
    landmarks = np.stack([np.asarray(capture.landmarks[int(t)])[:len(names), :2] for t in chosen])
    camera = fit_video_camera(points, landmarks, motion.pose[chosen], np.ones(len(chosen), bool), capture.width,
                              capture.height).camera
    static = motion.index(speaker.static_names)  # the head registered on the face less what speech moves
    for begin, d in motion.chunks():
        at = np.flatnonzero(usable[begin:begin + len(d)])
        if len(at):
            seen = np.asarray(capture.landmarks[begin:begin + len(d)])[at][:, static, :2]
            head[begin + at] = register_rigid(camera, motion.neutral[static] + d[at][:, static], seen, head[begin + at])
    height = capture.height if field is None else len(range(0 if field == "top" else 1, capture.height, 2))
    poses = pose_matrix(head)

    lips = np.vstack([speaker.rest, speaker.static_points])[mesh.points[mesh.outer]]
    first = int(np.flatnonzero(usable)[0])
    from .speaker.camera import project_posed

    xy = project_posed(camera, poses[first], lips) * capture.width
    mouth_width = float(np.ptp(xy[:, 0]))
    with CloneAnalyser(speaker, appearance, width=capture.width, height=height, mouth_width=mouth_width,
                       max_evals=int(max_evals), rigid=rigid, raster=raster, field=field, camera=camera,
                       supersample=supersample) as analyser:
        outside = [t for t in np.flatnonzero(usable)
                   if not analyser.box_inside(analyser.box_origin(start[t], poses[t]))]
        if outside:
            raise InputError(f"{video}: the mouth leaves the frame on frames "
                             f"{frame_ranges(outside)} of {T}; track a video where it stays in view")
        K = speaker.parameter_count
        found = np.full((T, K), np.nan)
        rigid_found = head.copy()
        evaluations, cost = np.zeros(T, np.int64), np.full(T, np.nan)
        seconds = 0.0
        with contextlib.ExitStack() as stack:
            stack.enter_context(output_group())  # the CSV, the overlay and the FAPs all appear, or none
            tmp = stack.enter_context(atomic_output(output))
            handle = stack.enter_context(open(tmp, "w", newline="", encoding="utf-8"))
            writer = csv.writer(handle)
            writer.writerow(["frame", "timestamp", *speaker.parameter_names])
            draw = None
            if overlay is not None:
                from .render.video import video_writer

                draw = stack.enter_context(video_writer(overlay, capture.fps, capture.width, height))
            source = stack.enter_context(open_frames(video))
            frames = iter(source)
            waiting = []
            for _ in range(min(_ADAPT_FRAMES, T)):
                waiting.append(_field_rows(next(frames)[1], field))
            seen = [t for t in range(len(waiting)) if usable[t]]
            if seen:
                analyser.adapt([waiting[t] for t in seen], start[seen], poses[seen])
            previous, correction = start[first], np.zeros(6)

            def frames_in_order():
                yield from waiting
                for _, image in frames:
                    yield _field_rows(image, field)

            for t, image in enumerate(shown.bar(frames_in_order(), total=T, desc="analysing by synthesis")):
                if t >= T:
                    break
                if not usable[t]:  # no face: the last analysed frame's answer held, the frame marked
                    found[t], rigid_found[t] = previous, rigid_found[t - 1] if t > first else head[first]
                    writer.writerow([t, f"{t / capture.fps:.6g}", *(f"{v:.6g}" for v in previous)])
                    if draw is not None:
                        draw(np.ascontiguousarray(image))
                    continue
                restart = t == first or not usable[t - 1]  # after a stretch without a face: the landmarks
                clock = time.perf_counter()
                answer = analyser.analyse(image, start[t] if restart else previous, poses[t],
                                          np.zeros(6) if restart else correction, reading=start[t],
                                          previous=None if restart else previous)
                seconds += time.perf_counter() - clock
                previous, correction = answer.parameters, answer.correction
                found[t], evaluations[t], cost[t] = answer.parameters, answer.evaluations, answer.cost
                rigid_found[t] = to_rigid(answer.pose[:3, :3], answer.pose[:3, 3])
                writer.writerow([t, f"{t / capture.fps:.6g}", *(f"{v:.6g}" for v in answer.parameters)])
                if draw is not None:
                    picture = np.ascontiguousarray(image).copy()
                    full = analyser.full_points(answer.parameters)
                    xy = analyser.pixels(full, answer.pose)
                    triangles = speaker.triangles if appearance.triangles is None else appearance.triangles
                    _draw(picture, xy, triangles, (60, 200, 60))
                    _draw(picture, xy[analyser.mesh.points], analyser.mesh.triangles, (250, 220, 40))
                    draw(picture)
            if np.isnan(found).any():
                raise InputError(f"{video}: decoding gave fewer frames than tracking "
                                 f"({int(np.isfinite(found[:, 0]).sum())} of {T})")
            stream = speaker.to_faps(found, fps=capture.fps, name=output.stem.replace(" ", "_") or "speaker")
            if fap is not None:
                write_fap(fap, stream)
            if motion_out is not None:
                from .speakerclone import write_motion_csv

                write_motion_csv(motion_out, rigid_found)
    return TrackedSpeech(found, rigid_found, evaluations, cost, start, seconds, stream, camera, mouth_width, usable)
