"""`Track`: what the face tracker saw in a video, frame by frame, and how it is made."""

from __future__ import annotations

import sys
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..atomic import atomic_output
from ..errors import FileFormatError, InputError
from .tracker import FaceTracker, TrackerOptions
from .video import open_frames

__all__ = ["Track", "track_video", "fill_gaps"]


@dataclass(frozen=True, eq=False)
class Track:
    """Raw tracker output for a video.

    Attributes
    ----------
    landmarks : (T, L, 3) float64
        MediaPipe's normalised landmarks per frame (x, y in [0, 1] from the top left, z in width
        units); NaN where no face was found and the gap was not filled.
    valid : (T,) bool
        A face was found in this frame.
    filled : (T,) bool
        Not found, but filled by interpolation across a short gap.
    times : (T,) float64
        Frame timestamps in seconds.
    fps : float
    width, height : int
        Frame size in pixels.
    source : str
        The video it came from.
    """

    landmarks: np.ndarray
    valid: np.ndarray
    filled: np.ndarray
    times: np.ndarray
    fps: float
    width: int
    height: int
    source: str = ""

    def __len__(self) -> int:
        return len(self.valid)

    @property
    def usable(self) -> np.ndarray:
        """(T,) bool: frames with landmarks, found or filled."""
        return self.valid | self.filled

    def gaps(self) -> list[tuple[int, int]]:
        """``(first, last)`` frame of every run of frames left without landmarks."""
        missing = np.r_[False, ~self.usable, False].astype(np.int8)
        edges = np.flatnonzero(np.diff(missing))
        return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2], strict=True)]

    def pixels(self) -> np.ndarray:
        """(T, L, 2) landmark positions in pixels."""
        return self.landmarks[..., :2] * [self.width, self.height]

    def save(self, path) -> None:
        """Write as ``.npz``, complete or not at all."""
        with atomic_output(path, suffix=".npz") as tmp:
            np.savez_compressed(tmp, landmarks=self.landmarks, valid=self.valid, filled=self.filled,
                                times=self.times, fps=self.fps, width=self.width, height=self.height,
                                source=self.source)

    @classmethod
    def load(cls, path) -> Track:
        path = Path(path)
        if not path.is_file():
            raise InputError(f"{path}: no such file")
        try:
            with np.load(path) as data:
                return cls(data["landmarks"], data["valid"], data["filled"], data["times"], float(data["fps"]),
                           int(data["width"]), int(data["height"]), str(data["source"]))
        except (KeyError, ValueError, OSError) as exc:
            raise FileFormatError(path, f"is not a faceanim track ({exc})") from None


def fill_gaps(track: Track, max_gap: float = 0.2) -> Track:
    """Fill runs of missing frames no longer than ``max_gap`` seconds by linear interpolation between
    the frames around them; those frames are flagged in ``filled``. Longer gaps and gaps at the ends
    stay missing (see :meth:`Track.gaps`)."""
    landmarks = track.landmarks.copy()
    filled = track.filled.copy()
    longest = max(1, int(round(max_gap * track.fps)))
    for first, last in track.gaps():
        if first == 0 or last == len(track) - 1 or last - first + 1 > longest:
            continue
        before, after = landmarks[first - 1], landmarks[last + 1]
        for k, frame in enumerate(range(first, last + 1), 1):
            s = k / (last - first + 2)
            landmarks[frame] = (1 - s) * before + s * after
        filled[first:last + 1] = True
    return replace(track, landmarks=landmarks, filled=filled)


def track_video(path, *, options: TrackerOptions | None = None, max_gap: float = 0.2,
                progress: bool | None = None) -> Track:
    """Track the face through a video, an image or an image folder.

    Raises
    ------
    InputError
        The file cannot be read as video, or no frame has a face.
    """
    from tqdm import tqdm

    options = options or TrackerOptions()
    show = sys.stderr.isatty() if progress is None else progress
    frames, valid, times = [], [], []
    with open_frames(path) as source, FaceTracker(options) as tracker:
        for index, (time, rgb) in enumerate(tqdm(source, total=source.frame_count, disable=not show,
                                                 unit="frame", desc="tracking")):
            face = tracker(rgb)
            valid.append(face is not None)
            frames.append(face)
            times.append(time if time is not None else index / source.fps)
        fps, width, height = source.fps, source.width, source.height
    if not frames:
        raise InputError(f"{path}: holds no frames")
    if not any(valid):
        raise InputError(f"{path}: no face was found in any of its {len(frames)} frames")
    count = next(f for f in frames if f is not None).shape[0]
    landmarks = np.full((len(frames), count, 3), np.nan)
    for i, face in enumerate(frames):
        if face is not None:
            landmarks[i] = face
    track = Track(landmarks, np.array(valid), np.zeros(len(frames), bool), np.array(times, dtype=np.float64),
                  fps, width, height, str(path))
    return fill_gaps(track, max_gap)
