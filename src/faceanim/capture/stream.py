"""A video's capture streamed through disk: memory that does not grow with the video's length.

:func:`captured` runs the same steps as :func:`~faceanim.capture.track.track_video` then
:func:`~faceanim.capture.headframe.track_to_motion` (track, fill short gaps, head frame and filter,
the neutral, the refit to it, displacements), with every per-frame landmark array kept in a
:class:`~faceanim.framestore.FrameStore` instead of memory, and hands out a streamed
:class:`~faceanim.motion.Motion` that reads its frames back from there. What stays in memory per
frame is the pose, the flags and the times (about 150 bytes; 1 MB for ten minutes at 30 fps), plus
the blendshape scores when the tracker gives them.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..framestore import FrameStore
from ..landmarks import landmark_names
from ..motion import Motion
from .headframe import (
    DEFAULT_SMOOTHING,
    displacements_from,
    head_frame_into,
    rest_window,
    score_drives,
    settle,
    unscored_drives,
)
from .smoothing import OneEuro
from .track import FrameFacts, Track, _Rows, fill_short_gaps, track_frames

__all__ = ["Capture", "captured"]


@dataclass(frozen=True, eq=False)
class Capture(FrameFacts):
    """A streamed capture: the motion and what the tracker saw, with the landmarks on disk.

    It answers what a :class:`~faceanim.capture.track.Track` answers for the frames' facts
    (``valid``, ``filled``, ``usable``, ``times``, ``fps``, ``width``, ``height``, ``source``,
    ``gaps()``, ``len``); its ``landmarks`` are a :class:`~faceanim.framestore.FrameStore` of the
    normalised landmarks (read by frame or run of frames), valid only inside :func:`captured`.
    """

    motion: Motion
    landmarks: FrameStore
    valid: np.ndarray
    filled: np.ndarray
    times: np.ndarray
    fps: float
    width: int
    height: int
    source: str
    blendshapes: np.ndarray | None = None
    blendshape_names: tuple[str, ...] = ()



class _StoreRows:
    """The tracker's rows appended to a :class:`FrameStore` made at the first face (the landmark count
    is known only then); the frames before it become rows of NaN."""

    def __init__(self, folder):
        self._folder, self._waiting, self.store = folder, 0, None

    def expect(self, count) -> None:  # a store grows on disk as it goes: nothing to reserve
        pass

    def append(self, row) -> None:
        if self.store is None:
            if row is None:
                self._waiting += 1
                return
            self.store = FrameStore(np.shape(row), folder=self._folder)
            for _ in range(self._waiting):
                self.store.append(None)
        self.store.append(row)


def captured(source, *, neutral=None, smoothing: OneEuro | None = DEFAULT_SMOOTHING, neutral_points=None,
             progress=None, folder=None, model=None, max_gap: float = 0.2, scores: bool = True,
             floor: bool = True) -> Capture:
    """The :class:`Capture` of a video (or of a :class:`~faceanim.capture.track.Track` already made),
    its landmarks and head-frame points in temporary files in ``folder`` (the system's temporary
    folder by default). The files have no name in any folder; their space is freed when the capture
    and everything that reads its motion (a streamed animation) are let go.

    ``neutral``, ``smoothing``, ``neutral_points``, ``scores`` and ``floor`` as for
    :func:`~faceanim.capture.headframe.track_to_motion`; ``progress`` and ``model`` as for
    :func:`~faceanim.capture.track.track_video`. The motion's frames are the ones
    ``track_to_motion(track_video(source))`` gives, to the float32 precision of the head-frame
    points kept on disk (1e-6 cm on a face).

    Raises
    ------
    InputError
        As ``track_video`` and ``track_to_motion`` do, and a ``neutral`` window outside the video.
    """
    if isinstance(source, Track):
        raw = FrameStore(source.landmarks.shape[1:], folder=folder)
        for start in range(0, len(source), 1024):
            raw.append(source.landmarks[start:start + 1024])
        valid, filled, times = source.valid, source.filled, source.times
        fps, width, height, name = source.fps, source.width, source.height, source.source
        blendshapes, names = source.blendshapes, source.blendshape_names
    else:
        rows, shapes = _StoreRows(folder), _Rows()
        seen = track_frames(source, rows, shapes, progress=progress, model=model)
        raw, valid, times = rows.store, seen.valid, seen.times
        fps, width, height, name = seen.fps, seen.width, seen.height, str(Path(source))
        blendshapes = shapes.array() if seen.blendshape_names else None
        names = seen.blendshape_names
        filled = fill_short_gaps(raw, valid, fps, max_gap)
    usable = valid | filled
    if not usable.any():  # a saved track can hold no face at all (a video that does is refused when tracked)
        raise InputError(f"the track of {name or 'a video'} holds no frame with a face ({len(usable)} frames)")
    if neutral is not None and not 0 <= neutral[0] < neutral[1] <= len(usable):
        raise InputError(f"--neutral {neutral[0]}:{neutral[1]}: frames must lie in [0, {len(usable)}) "
                         "with START < END")
    points = FrameStore(raw.frame_shape, folder=folder)
    for start in range(0, len(raw), 1024):  # room for every frame, rewritten block by block below
        points.append(np.zeros((min(1024, len(raw) - start), *raw.frame_shape)))
    pose = np.empty((len(raw), 4, 4))
    head_frame_into(raw, usable, times, width, height, points, pose, smoothing)
    window = rest_window(points, usable, fps, neutral, neutral_points)
    rest, fapu = settle(points, pose, usable, fps, neutral=window, neutral_points=neutral_points)
    drives = score_drives(blendshapes, names, times, rest, fapu, usable, window, smoothing) if scores else []
    drives += unscored_drives(rest, fapu, floor=floor)

    def frames(start: int, stop: int) -> np.ndarray:
        moved = displacements_from(points[start:stop], rest, usable[start:stop])
        for drive in drives:
            drive.apply(moved, start)
        return moved

    motion = Motion.streamed(landmark_names(len(rest)), rest, frames, pose, fps, fapu, valid=usable)
    return Capture(motion, raw, valid, filled, times, fps, width, height, name, blendshapes, names)
