"""`FrameStore`: per-frame arrays of one shape kept on disk, so a long video costs disk, not memory.

A capture reads every frame's landmarks several times (head frame, filter, the neutral's search,
the refit to that neutral, the deformation); held in memory they grow with the video (12 KB a frame
for MediaPipe's 478 landmarks, 66 MB a minute with the copies the steps make). A store keeps them in
a temporary file with no name in any folder (unlinked as it is made: nothing is left behind however
the process ends) and hands back the rows asked for, so what a step holds is the block it works on.
Rows are float32 on disk (MediaPipe's own precision; 1e-7 of a face's size in the head frame) and
float64 when read.
"""

from __future__ import annotations

import os
import tempfile

import numpy as np

__all__ = ["FrameStore"]


class FrameStore:
    """Rows of shape ``frame_shape``, appended in order, then read and rewritten by frame index.

    Indexing takes a frame number, a slice (step 1) or an array of frame numbers and returns a new
    float64 array (``store[a:b]`` is ``(b - a, *frame_shape)``), as a NumPy array would; assigning
    to a slice rewrites those rows. So code written for a ``(T, ...)`` array that reads and writes
    by blocks runs on a store unchanged. ``None`` appended is a row of NaN (a frame without data).
    ``folder``: where the file goes (the jobs pass their output's folder); the system's temporary
    folder by default. The file is closed (and its space freed) by :meth:`close`, at the end of a
    ``with`` block, or when the store is let go.

    >>> with FrameStore((2, 3)) as store:
    ...     store.append(np.ones((2, 3)))
    ...     store.append(None)
    ...     store[1:2] = np.zeros((1, 2, 3))
    ...     len(store), store.shape, float(store[0].sum()), float(store[np.array([1])].sum())
    (2, (2, 2, 3), 6.0, 0.0)
    """

    def __init__(self, frame_shape: tuple[int, ...], *, folder=None):
        self.frame_shape = tuple(int(n) for n in frame_shape)
        if any(n < 1 for n in self.frame_shape):
            raise ValueError(f"frame_shape must hold positive sizes, got {frame_shape}")
        self._row = int(np.prod(self.frame_shape))
        self._bytes = self._row * 4
        self._file = tempfile.TemporaryFile(prefix=".faceanim-frames-", dir=folder)
        self._fd = self._file.fileno()
        self._length = 0

    def __enter__(self) -> FrameStore:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Let the file go (its space is freed at once: it has no name)."""
        self._file.close()

    def __len__(self) -> int:
        return self._length

    @property
    def shape(self) -> tuple[int, ...]:
        return (self._length, *self.frame_shape)

    def reserve(self, length: int) -> None:
        """Hold ``length`` rows from now on, for writers that fill them out of order (by slice
        assignment); rows not yet written read as zeros."""
        if int(length) != length or length < self._length:
            raise ValueError(f"length must be a whole number of at least the {self._length} rows held, got {length}")
        os.ftruncate(self._fd, int(length) * self._bytes)
        self._length = int(length)

    def append(self, rows) -> None:
        """Add one frame (``frame_shape``, or None for a row of NaN) or a block ``(n, *frame_shape)``."""
        if rows is None:
            block = np.full((1, self._row), np.nan, dtype=np.float32)
        else:
            block = np.asarray(rows, dtype=np.float32)
            if block.shape == self.frame_shape:
                block = block[None]
            if block.shape[1:] != self.frame_shape:
                raise ValueError(f"rows must have shape {self.frame_shape} or (n, *{self.frame_shape}), "
                                 f"got {block.shape}")
        os.pwrite(self._fd, np.ascontiguousarray(block).tobytes(), self._length * self._bytes)
        self._length += len(block)

    def _read(self, start: int, stop: int) -> np.ndarray:
        size = (stop - start) * self._bytes
        raw = os.pread(self._fd, size, start * self._bytes)
        if len(raw) != size:
            raise OSError(f"the frame store's file was cut short (read {len(raw)} of {size} bytes)")
        return np.frombuffer(raw, dtype=np.float32).astype(np.float64).reshape(stop - start, *self.frame_shape)

    def _range(self, key: slice) -> tuple[int, int]:
        start, stop, step = key.indices(self._length)
        if step != 1:
            raise IndexError("a frame store reads runs of frames: slices take no step")
        return start, max(start, stop)

    def __getitem__(self, key) -> np.ndarray:
        if isinstance(key, slice):
            start, stop = self._range(key)
            return self._read(start, stop)
        if isinstance(key, (int, np.integer)):
            index = int(key) + (self._length if key < 0 else 0)
            if not 0 <= index < self._length:
                raise IndexError(f"frame {key} is outside the store's {self._length} frames")
            return self._read(index, index + 1)[0]
        frames = np.asarray(key)
        if frames.dtype.kind not in "iu" or frames.ndim != 1:
            raise IndexError(f"a frame store is indexed by a frame, a slice or a 1-D array of frames, got {key!r}")
        frames = np.where(frames < 0, frames + self._length, frames)
        if frames.size and not (0 <= frames.min() and frames.max() < self._length):
            raise IndexError(f"frames outside the store's {self._length} frames")
        out = np.empty((len(frames), *self.frame_shape))
        # One read per run of consecutive frames: a sorted selection spread over a long video costs
        # as many reads as runs, never the frames between them.
        order = np.argsort(frames, kind="stable")
        ranked = frames[order]
        breaks = np.flatnonzero(np.diff(ranked) != 1) + 1
        for run in np.split(np.arange(len(ranked)), breaks):
            if run.size:
                first = int(ranked[run[0]])
                block = self._read(first, int(ranked[run[-1]]) + 1)
                out[order[run]] = block[ranked[run] - first]
        return out

    def __setitem__(self, key, value) -> None:
        if not isinstance(key, slice):
            raise IndexError("a frame store rewrites runs of frames: assign to a slice")
        start, stop = self._range(key)
        block = np.broadcast_to(np.asarray(value, dtype=np.float32), (stop - start, *self.frame_shape))
        os.pwrite(self._fd, np.ascontiguousarray(block).tobytes(), start * self._bytes)
