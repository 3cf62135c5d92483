"""Frames in: any video FFmpeg reads (through PyAV), a single image, or a folder of images.

Frames stream one at a time, so memory is bounded by a frame, not by the video's length.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError

__all__ = ["FrameSource", "open_frames", "IMAGE_SUFFIXES"]

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp")


@dataclass
class FrameSource:
    """An open source of RGB frames; use as a context manager and iterate.

    Attributes
    ----------
    path : Path
    fps : float
        Nominal frame rate (images: the rate given when opening).
    width, height : int
    frame_count : int or None
        The container's frame count when it states one (used for progress only).

    Iterating yields ``(timestamp_seconds, rgb (H, W, 3) uint8)``.
    """

    path: Path
    fps: float
    width: int
    height: int
    frame_count: int | None
    _container: object = None
    _images: list | None = None

    def __iter__(self):
        if self._images is not None:
            for i, image_path in enumerate(self._images):
                yield i / self.fps, _read_image(image_path)
            return
        import av

        stream = self._container.streams.video[0]
        try:
            for frame in self._container.decode(stream):
                time = float(frame.pts * stream.time_base) if frame.pts is not None else None
                yield time, frame.to_ndarray(format="rgb24")
        except av.error.FFmpegError as exc:  # a truncated or corrupt file, found while decoding
            raise InputError(f"{self.path}: the video cannot be decoded ({exc})") from None

    def close(self):
        if self._container is not None:
            self._container.close()
            self._container = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _read_image(path: Path) -> np.ndarray:
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(path) as image:
            return np.asarray(image.convert("RGB"))
    except (UnidentifiedImageError, OSError) as exc:
        raise InputError(f"{path}: not a readable image ({exc})") from None


def open_frames(path, *, image_fps: float = 25.0) -> FrameSource:
    """Open a video file, an image or a folder of images (sorted by name).

    Raises
    ------
    InputError
        Missing path, an empty file or folder, or a file that is not a video or image; the message
        names the path.
    """
    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: no such file or folder")
    if path.is_dir():
        images = sorted(p for p in path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
        if not images:
            raise InputError(f"{path}: the folder holds no images ({', '.join(IMAGE_SUFFIXES)})")
        first = _read_image(images[0])
        return FrameSource(path, image_fps, first.shape[1], first.shape[0], len(images), _images=images)
    if path.stat().st_size == 0:
        raise InputError(f"{path}: the file is empty")
    if path.suffix.lower() in IMAGE_SUFFIXES:
        image = _read_image(path)
        return FrameSource(path, image_fps, image.shape[1], image.shape[0], 1, _images=[path])
    try:
        import av
    except ImportError:
        raise ImportError("reading video needs PyAV: pip install 'faceanim[capture]'") from None
    try:
        container = av.open(str(path))
    except (av.error.FFmpegError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: not a video FFmpeg can read ({exc})") from None
    if not container.streams.video:
        container.close()
        raise InputError(f"{path}: holds no video stream")
    stream = container.streams.video[0]
    stream.thread_type = "AUTO"
    rate = stream.average_rate or stream.guessed_rate
    fps = float(rate) if rate else 25.0
    return FrameSource(path, fps, stream.codec_context.width, stream.codec_context.height,
                       stream.frames or None, _container=container)
