"""`Track`: what the face tracker saw in a video, frame by frame, and how it is made."""

from __future__ import annotations

import numbers
import sys
from dataclasses import dataclass, replace
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..atomic import atomic_output
from ..errors import FileFormatError, InputError
from ..validation import as_array, restore_frozen
from .tracker import TrackerOptions, open_tracker
from .video import open_frames

__all__ = ["Track", "TrackedFrames", "track_video", "track_frames", "fill_gaps", "fill_short_gaps", "gaps_of"]

_MAX_SIZE = 1 << 20  # pixels along a frame's side: far beyond any video, well inside int32


class FrameFacts:
    """What a Track and a streamed :class:`~faceanim.capture.stream.Capture` both answer from their
    ``valid`` and ``filled`` flags."""

    valid: np.ndarray
    filled: np.ndarray

    def __len__(self) -> int:
        return len(self.valid)

    @property
    def usable(self) -> np.ndarray:
        """(T,) bool: frames with landmarks, found or filled."""
        return self.valid | self.filled

    def gaps(self) -> list[tuple[int, int]]:
        """``(first, last)`` frame of every run of frames left without landmarks."""
        return gaps_of(self.usable)


@dataclass(frozen=True, eq=False)
class Track(FrameFacts):
    """Raw tracker output for a video; immutable (read-only arrays) and checked on construction.

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
    blendshapes : (T, 52) float64, optional
        MediaPipe's blendshape scores per frame (NaN where no face); None in tracks saved before the
        Face Landmarker was faceanim's tracker.
    blendshape_names : tuple of str

    Raises
    ------
    ValueError
        An array of the wrong shape, frame counts that disagree, a frame both found and filled, NaN
        landmarks on a frame with a face, or a non-positive fps or frame size (the field is named).
    TypeError
        A field of the wrong type.
    """

    landmarks: np.ndarray
    valid: np.ndarray
    filled: np.ndarray
    times: np.ndarray
    fps: float
    width: int
    height: int
    source: str = ""
    blendshapes: np.ndarray | None = None
    blendshape_names: tuple[str, ...] = ()

    def __post_init__(self):
        landmarks = as_array(self.landmarks, "landmarks", shape=("T", "L", 3), finite=False, min_length=1,
                             frozen=True)
        T = len(landmarks)
        if landmarks.shape[1] == 0:
            raise ValueError("landmarks must have at least 1 landmark per frame, got shape (T, 0, 3)")
        valid = as_array(self.valid, "valid", shape=(T,), dtype=bool, frozen=True)
        filled = as_array(self.filled, "filled", shape=(T,), dtype=bool, frozen=True)
        both = np.flatnonzero(valid & filled)
        if both.size:
            raise ValueError(f"filled must mark only frames without a face, got frame {both[0]} both valid and filled")
        usable = valid | filled
        missing = np.flatnonzero(usable & ~np.isfinite(landmarks).all(axis=(1, 2)))
        if missing.size:
            raise ValueError(f"landmarks must be finite on frames with a face (valid or filled), got NaN or "
                             f"infinity on frame {missing[0]}")
        times = as_array(self.times, "times", shape=(T,), frozen=True)
        if isinstance(self.fps, bool) or not isinstance(self.fps, numbers.Real) or not (
                np.isfinite(self.fps) and self.fps > 0):
            raise ValueError(f"fps must be a positive number, got {self.fps!r}")
        for name in ("width", "height"):
            value = getattr(self, name)
            whole = isinstance(value, numbers.Integral) or (
                isinstance(value, numbers.Real) and float(value).is_integer())
            if isinstance(value, bool) or not whole or not 1 <= value <= _MAX_SIZE:
                raise ValueError(f"{name} must be a whole number of pixels from 1 to {_MAX_SIZE}, got {value!r}")
            object.__setattr__(self, name, int(value))
        if not isinstance(self.source, str):
            raise TypeError(f"source must be a str, got {type(self.source).__name__}")
        names = tuple(self.blendshape_names)
        if not all(isinstance(n, str) for n in names):
            raise TypeError("blendshape_names must be strings")
        if self.blendshapes is not None:
            shapes = as_array(self.blendshapes, "blendshapes", shape=(T, len(names)), finite=False, frozen=True)
            object.__setattr__(self, "blendshapes", shapes)
        for name, value in (("landmarks", landmarks), ("valid", valid), ("filled", filled), ("times", times),
                            ("fps", float(self.fps)), ("blendshape_names", names)):
            object.__setattr__(self, name, value)

    def __setstate__(self, state):
        restore_frozen(self, state)

    def pixels(self) -> np.ndarray:
        """(T, L, 2) landmark positions in pixels."""
        return self.landmarks[..., :2] * [self.width, self.height]

    def save(self, path) -> None:
        """Write as ``.npz``, complete or not at all."""
        with atomic_output(path, suffix=".npz") as tmp:
            extra = {} if self.blendshapes is None else {
                "blendshapes": self.blendshapes, "blendshape_names": np.array(self.blendshape_names)}
            np.savez_compressed(tmp, landmarks=self.landmarks, valid=self.valid, filled=self.filled,
                                times=self.times, fps=self.fps, width=self.width, height=self.height,
                                source=self.source, **extra)

    @classmethod
    def load(cls, path) -> Track:
        """Read a track written by :meth:`save`.

        Raises
        ------
        InputError
            The file is missing or cannot be read.
        FileFormatError
            The file is not a ``.npz`` archive (empty, a single ``.npy`` array, a pickle, a broken or
            cut-short zip), lacks one of the track's arrays, or holds one of the wrong kind or shape
            (as :class:`Track` checks its fields); the message names the file.
        """
        path = Path(path)
        if not path.is_file():
            raise InputError(f"{path}: no such file")
        fields = _read_npz(path)
        try:
            track = cls(**fields)
        except (TypeError, ValueError) as exc:  # the Track's own checks of what the file holds
            raise FileFormatError(path, f"is not a faceanim track ({exc})") from None
        if not track.usable.any():
            raise FileFormatError(path, f"holds no frame with a face ({len(track)} frames)")
        flat = _first_flat_frame(track)
        if flat is not None:  # the tracker never makes one; a head frame cannot be fitted to it
            raise FileFormatError(path, f"frame {flat}'s landmarks do not span the image (all on a point or a "
                                        "line); it is not a tracked face")
        return track


def _first_flat_frame(track: Track, block: int = 4096) -> int | None:
    """The first frame with a face whose landmarks span no area in the image (all on one point or a
    line), or None."""
    usable = np.flatnonzero(track.usable)
    for start in range(0, len(usable), block):
        frames = usable[start:start + block]
        xy = track.landmarks[frames, :, :2]
        centred = xy - xy.mean(axis=1, keepdims=True)
        # the smaller singular value of each frame's 2-D spread, against its size
        cov = np.einsum("tli,tlj->tij", centred, centred)
        smallest = np.linalg.eigvalsh(cov)[:, 0]
        flat = smallest <= 1e-12 * np.maximum(np.trace(cov, axis1=1, axis2=2), 1e-300)
        if flat.any():
            return int(frames[np.argmax(flat)])
    return None


_NUMBERS = "iuf"  # numpy kinds of real numbers (not bool, complex, strings, dates)


def _read_npz(path: Path) -> dict:
    """:class:`Track`'s fields from the ``.npz`` at ``path``: each array of the kind :meth:`Track.save`
    writes (shapes are left to the Track), or a FileFormatError naming the file."""
    import tokenize
    import zipfile
    import zlib

    def refuse(why: str):
        return FileFormatError(path, f"is not a faceanim track ({why})")

    try:
        with open(path, "rb") as handle:
            magic = handle.read(6)
    except OSError as exc:
        raise InputError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    if not magic:
        raise FileFormatError(path, "is empty")
    if magic == b"\x93NUMPY":
        raise FileFormatError(path, "is a single .npy array, not a faceanim track (.npz)")
    if not magic.startswith(b"PK"):
        raise refuse("not a .npz file: it does not start with the zip signature")
    arrays = {}
    try:
        with np.load(path, allow_pickle=False) as data:
            for key in ("landmarks", "valid", "filled", "times", "fps", "width", "height", "source", "blendshapes",
                        "blendshape_names"):
                if key in data.files:
                    arrays[key] = data[key]
                    arrays[key].flags.writeable = False  # fresh and ours: the Track takes it uncopied
    except (OSError, EOFError, ValueError, zipfile.BadZipFile, zlib.error, tokenize.TokenError,
            NotImplementedError) as exc:
        # a broken zip, a cut-short or corrupt member, a compression method zipfile lacks, a bad .npy
        # header or object arrays
        raise refuse(f"{type(exc).__name__}: {exc}") from None
    except RuntimeError as exc:  # zipfile: "File ... is encrypted, password required for extraction"
        if isinstance(exc, RecursionError):
            raise
        raise refuse(f"{type(exc).__name__}: {exc}") from None
    except MemoryError:
        raise refuse("an array's header declares more data than fits in memory") from None
    missing = [k for k in ("landmarks", "valid", "filled", "times", "fps", "width", "height", "source")
               if k not in arrays]
    if missing:
        raise refuse(f"it lacks {', '.join(missing)}")

    def kind(key: str, kinds: str, what: str, *, ndim: int | None = None):
        value = arrays[key]
        if value.dtype.kind not in kinds or (ndim is not None and value.ndim != ndim):
            raise refuse(f"{key} must be {what}, got {value.dtype} of shape {value.shape}")
        return value.item() if ndim == 0 else value

    fields = {key: kind(key, _NUMBERS, "an array of numbers") for key in ("landmarks", "times")}
    fields |= {key: kind(key, "b", "an array of booleans") for key in ("valid", "filled")}
    fields["fps"] = kind("fps", _NUMBERS, "a number", ndim=0)
    fields |= {key: kind(key, _NUMBERS, "a whole number", ndim=0) for key in ("width", "height")}
    fields["source"] = kind("source", "U", "a string", ndim=0)
    if "blendshapes" in arrays:
        fields["blendshapes"] = kind("blendshapes", _NUMBERS, "an array of numbers")
    if "blendshape_names" in arrays:
        fields["blendshape_names"] = tuple(str(n) for n in kind("blendshape_names", "U", "a list of names", ndim=1))
    return fields


def gaps_of(usable: np.ndarray) -> list[tuple[int, int]]:
    """``(first, last)`` frame of every run of frames that ``usable (T,)`` marks False."""
    missing = np.r_[False, ~np.asarray(usable, dtype=bool), False].astype(np.int8)
    edges = np.flatnonzero(np.diff(missing))
    return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def fill_gaps(track: Track, max_gap: float = 0.2) -> Track:
    """Fill runs of missing frames no longer than ``max_gap`` seconds by linear interpolation between
    the frames around them; those frames are flagged in ``filled``. Longer gaps and gaps at the ends
    stay missing (see :meth:`Track.gaps`)."""
    landmarks = track.landmarks.copy()
    filled = fill_short_gaps(landmarks, track.usable, track.fps, max_gap) | track.filled
    landmarks.flags.writeable = filled.flags.writeable = False  # handed over: the Track takes them uncopied
    return replace(track, landmarks=landmarks, filled=filled)


def fill_short_gaps(landmarks, usable: np.ndarray, fps: float, max_gap: float = 0.2) -> np.ndarray:
    """Interpolate, in place, the runs of frames ``usable`` lacks that last at most ``max_gap`` seconds
    and have a face on both sides, in ``landmarks (T, L, 3)`` (an array or a
    :class:`~faceanim.framestore.FrameStore`); returns ``(T,)`` the frames filled."""
    filled = np.zeros(len(usable), dtype=bool)
    longest = max(1, int(round(max_gap * fps)))
    for first, last in gaps_of(usable):
        if first == 0 or last == len(usable) - 1 or last - first + 1 > longest:
            continue
        before, after = landmarks[first - 1], landmarks[last + 1]
        s = (np.arange(first, last + 1) - first + 1)[:, None, None] / (last - first + 2)
        landmarks[first:last + 1] = (1 - s) * before + s * after
        filled[first:last + 1] = True
    return filled


class _Rows:
    """One row a frame (an array of one shape, or None: a row of NaN), kept in one float64 array made
    for the ``expected`` number of frames (a container's frame count) and grown by a quarter when
    there are more. A video's many small per-frame arrays, held between its large frame buffers,
    fragment the heap: tracking a 60 s video kept about five times the landmarks' size."""

    def __init__(self, expected: int | None = None):
        self._data, self._count, self._expected = None, 0, expected or 0

    def expect(self, count: int | None) -> None:
        """The number of rows to make room for at the first (a container's frame count; may be wrong)."""
        self._expected = count or 0

    def append(self, row) -> None:
        if row is None and self._data is None:
            self._count += 1
            return
        if self._data is None:
            self._data = np.full((max(64, self._expected, 2 * (self._count + 1)), *np.shape(row)), np.nan)
        elif self._count == len(self._data):  # more frames than the container said: a quarter more at a time
            grown = np.full((len(self._data) + max(64, len(self._data) // 4), *self._data.shape[1:]), np.nan)
            grown[:self._count] = self._data
            self._data = grown
        if row is not None:
            self._data[self._count] = row
        self._count += 1

    def array(self) -> np.ndarray | None:
        """The rows ``(T, ...)``, read-only and owned (a Track takes it uncopied); None when every row was None."""
        if self._data is None:
            return None
        self._data.resize((self._count, *self._data.shape[1:]), refcheck=False)  # shrinks in place
        self._data.flags.writeable = False
        return self._data


class TrackedFrames(NamedTuple):
    """What a pass of the tracker over a video leaves besides the landmarks: per frame whether a face
    was found and when, the video's rate and size, and the blendshape names."""

    valid: np.ndarray
    times: np.ndarray
    fps: float
    width: int
    height: int
    blendshape_names: tuple[str, ...]


def track_frames(path, faces, shapes, *, options: TrackerOptions | None = None, progress=None,
                 model=None) -> TrackedFrames:
    """Run the tracker over every frame of ``path``, appending each frame's landmarks (or None) to
    ``faces`` and its blendshape scores (or None) to ``shapes`` (anything with ``append``: rows in
    memory, or a :class:`~faceanim.framestore.FrameStore`'s rows on disk).

    Raises
    ------
    InputError
        The file cannot be read as video, holds no frames, or no frame has a face.
    """
    from ..progress import Progress, as_progress

    options = options or TrackerOptions()
    shown = Progress() if progress is None and sys.stderr.isatty() else as_progress(progress)
    valid, times = [], []
    names = ()
    with open_frames(path) as source, open_tracker(options, model) as tracker:
        if hasattr(faces, "expect"):
            faces.expect(source.frame_count)
            shapes.expect(source.frame_count)
        for index, (time, rgb) in enumerate(shown.bar(source, total=source.frame_count, desc="tracking")):
            time = time if time is not None else index / source.fps
            face = tracker(rgb, time)
            valid.append(face is not None)
            faces.append(face)
            times.append(time)
            shapes.append(tracker.blendshapes)
            names = names or getattr(tracker, "blendshape_names", ())
        fps, width, height = source.fps, source.width, source.height
    if not valid:
        raise InputError(f"{path}: holds no frames")
    if not any(valid):
        raise InputError(f"{path}: no face was found in any of its {len(valid)} frames")
    return TrackedFrames(np.array(valid), np.array(times, dtype=np.float64), fps, width, height, tuple(names))


def track_video(path, *, options: TrackerOptions | None = None, max_gap: float = 0.2,
                progress=None, model=None) -> Track:
    """Track the face through a video, an image or an image folder with MediaPipe's Face Landmarker
    (landmarks and 52 blendshape scores per frame), from faceanim's own model bundle or ``model`` (a
    ``face_landmarker.task`` file).
    ``progress``: a :class:`~faceanim.progress.Progress` or a bool; None shows a bar when stderr is
    a terminal.

    Raises
    ------
    InputError
        The file cannot be read as video, or no frame has a face.
    """
    faces, shapes = _Rows(), _Rows()
    seen = track_frames(path, faces, shapes, options=options, progress=progress, model=model)
    blendshapes = shapes.array() if seen.blendshape_names else None
    track = Track(faces.array(), seen.valid, np.zeros(len(seen.valid), bool), seen.times, seen.fps, seen.width,
                  seen.height, str(path), blendshapes, seen.blendshape_names)
    return fill_gaps(track, max_gap)
