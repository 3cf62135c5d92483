"""Overlay frames: the source frames with the control points and the head's axes drawn on them.

Writing them to a file is the pipeline's job (``faceanim.render.video``); capture only draws."""

from __future__ import annotations

import numpy as np

from ..landmarks import FEATURE_POINT_LANDMARK
from .metric import Camera
from .track import Track
from .video import open_frames

__all__ = ["overlay_frames"]

_FEATURE_INDICES = np.array(sorted(set(FEATURE_POINT_LANDMARK.values())))


def _axes_pixels(pose: np.ndarray, width: int, height: int, length: float, camera: Camera):
    """Pixels of the head origin and its X (red), Y (green), Z (blue) axis tips, through the pose's camera."""
    ends = np.array([[0, 0, 0], [length, 0, 0], [0, length, 0], [0, 0, length]], dtype=np.float64)
    cam = ends @ pose[:3, :3].T + pose[:3, 3]
    f = 0.5 * height / np.tan(0.5 * np.radians(camera.vertical_fov))
    x = width / 2 + f * cam[:, 0] / -cam[:, 2]
    y = height / 2 - f * cam[:, 1] / -cam[:, 2]
    return np.stack([x, y], axis=1)


def overlay_frames(track: Track, pose: np.ndarray, *, camera: Camera | None = None):
    """Yield every source frame (RGB) with all landmarks (small, grey), the MPEG-4 feature points (larger,
    yellow) and the head axes drawn; frames without a face say so. ``track``: a Track, or a streamed
    :class:`~faceanim.capture.stream.Capture` (its landmarks are read a frame at a time)."""
    from PIL import Image, ImageDraw

    camera = camera or Camera()
    with open_frames(track.source) as source:
        for t, (_, rgb) in enumerate(source):
            if t >= len(track):
                break
            image = Image.fromarray(rgb)
            draw = ImageDraw.Draw(image)
            if track.usable[t]:
                pixels = track.landmarks[t][:, :2] * [track.width, track.height]
                for x, y in pixels:
                    draw.point((x, y), fill=(200, 200, 200))
                for x, y in pixels[_FEATURE_INDICES]:
                    draw.ellipse((x - 2, y - 2, x + 2, y + 2), fill=(255, 220, 0))
                o, *tips = _axes_pixels(pose[t], source.width, source.height, 6.0, camera)
                for tip, colour in zip(tips, ((255, 0, 0), (0, 200, 0), (0, 80, 255)), strict=True):
                    draw.line((*o, *tip), fill=colour, width=2)
                if track.filled[t]:
                    draw.text((8, 8), "filled", fill=(255, 128, 0))
            else:
                draw.text((8, 8), "no face", fill=(255, 0, 0))
            yield np.asarray(image)
