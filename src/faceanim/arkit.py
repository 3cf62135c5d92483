"""``faceanim blendshapes``: a video's ARKit-52 take, written as a Live Link Face CSV.

The Face Landmarker scores 51 of ARKit's 52 shapes on every frame (not ``tongueOut``, written as 0);
the head's rotation comes from the capture's head pose (MediaPipe's metric face geometry) and each
eye's from its pupil in the head frame, as FAPs 23-26 measure them. The capture is streamed
(:func:`~faceanim.inputs.captured_source`): memory holds a few numbers per frame, not the landmarks.
See :mod:`faceanim.rig.livelink` for the columns, the units and the timecode.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .errors import InputError
from .inputs import captured_source, neutral_window
from .outputs import check_outputs

__all__ = ["blendshapes", "take_of_capture"]


def take_of_capture(capture, *, neutral: tuple[int, int] | None = None):
    """The :class:`~faceanim.rig.livelink.Take` of a streamed capture: one row per frame with a face
    (found, or filled across a short gap: its scores interpolated), weights in [0, 1], and with
    ``neutral`` (a ``(start, end)`` frame window) the window's mean scores taken off every frame
    (clipped at 0).

    Raises
    ------
    InputError
        The capture has no blendshape scores (a track saved before faceanim tracked with the Face
        Landmarker), or no frame of the ``neutral`` window has a face.
    """
    from .capture.scores import scores_across_filled_frames
    from .motion import gaze_angles, head_angles, rotation_part
    from .rig.livelink import Take, arkit_weights

    if capture.blendshapes is None:
        raise InputError(f"{capture.source}: holds no blendshape scores (a track saved by an older faceanim); "
                         "track the video again")
    usable = capture.usable
    # across short gaps, as the landmarks are
    weights = arkit_weights(scores_across_filled_frames(capture.blendshapes, usable), capture.blendshape_names)
    if neutral is not None:
        start, end = neutral
        if not 0 <= start < end <= len(usable):
            raise InputError(f"--neutral {start}:{end}: frames must lie in [0, {len(usable)}) with START < END")
        at = np.arange(start, end)[usable[start:end]]
        if not len(at):
            raise InputError(f"--neutral {start}:{end}: no frame of the window has a face")
        weights = np.clip(weights - weights[at].mean(axis=0), 0.0, 1.0)
    motion = capture.motion
    pose = np.zeros((len(usable), 9))
    pitch_yaw_roll = head_angles(rotation_part(motion.pose))
    pose[:, :3] = pitch_yaw_roll[:, [1, 0, 2]]
    pupils = motion.points_over_time(["3.5", "3.6"])
    for eye in range(2):  # left (3.5), right (3.6): yaw towards the face's left, pitch down, as FAPs 23-26
        pose[:, 3 + 3 * eye:5 + 3 * eye] = gaze_angles(pupils[:, eye], motion.fapu)
    keep = usable & np.isfinite(pose).all(axis=1)
    times = np.asarray(capture.times)[keep]
    return Take(times - min(float(times[0]), 0.0), weights[keep], pose[keep], capture.fps)


def blendshapes(video, output, *, neutral=None, smoothing: bool = True, progress=None, capture=None):
    """``faceanim blendshapes``: the ARKit-52 take of ``video`` (or of a saved ``.npz`` track made
    by the Face Landmarker) written to ``output`` as a Live Link Face CSV; returns ``(take,
    summary)``, the summary as ``faceanim fap-info`` prints one.

    ``neutral``: ``FRAME`` or ``START:END``; that window's scores are taken off every frame (clipped
    at 0), and it is the capture's rest (the eyes' zero). ``smoothing``: the One Euro filter on the
    landmarks (the head and eye angles; the scores are MediaPipe's own). ``capture``: the streamed
    :class:`~faceanim.capture.stream.Capture` of ``video`` already made, instead of tracking again.

    Raises
    ------
    InputError
        A bad output path or ``--neutral``, a video with no face, a track without blendshape scores.
    """
    from .rig.livelink import take_summary, write_livelink_csv

    output = Path(output)
    check_outputs({"-o": (output, ".csv")}, inputs={"VIDEO": video})
    window = neutral_window(neutral, "blendshapes")
    if capture is None:
        capture = captured_source(video, neutral=neutral, smoothing=smoothing, progress=progress,
                                  folder=output.parent)
    if capture.blendshapes is None:  # named as the user gave it (a track's own source is its video)
        raise InputError(f"{video}: holds no blendshape scores (a track saved by an older faceanim); track the "
                         "video again")
    take = take_of_capture(capture, neutral=window)
    write_livelink_csv(output, take)
    skipped = len(capture.valid) - len(take)
    note = (f"; neutral frames {window[0]}:{window[1]} removed" if window else "") + (
        f"; {skipped} frames without a face left out" if skipped else "")
    return take, take_summary(take, output, note=note)
