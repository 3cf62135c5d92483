"""Writing frames to a video file (H.264 in MP4, through PyAV), complete or not at all."""

from __future__ import annotations

import contextlib

import numpy as np

from ..atomic import atomic_output

__all__ = ["video_writer"]


@contextlib.contextmanager
def video_writer(path, fps: float, width: int, height: int):
    """Yield ``write(rgb)`` for ``(height, width, 3)`` uint8 frames; the file appears only when the block
    ends without error. Odd sizes are cropped to even (H.264 needs even sizes)."""
    try:
        import av
    except ImportError:
        raise ImportError("writing video needs PyAV: pip install 'faceanim[capture]'") from None
    even_w, even_h = width - width % 2, height - height % 2
    with atomic_output(path, suffix=".mp4") as tmp:
        container = av.open(str(tmp), mode="w")
        try:
            stream = container.add_stream("libx264", rate=max(1, round(fps)))
            stream.width, stream.height, stream.pix_fmt = even_w, even_h, "yuv420p"

            def write(rgb: np.ndarray) -> None:
                frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(rgb[:even_h, :even_w]), format="rgb24")
                for packet in stream.encode(frame):
                    container.mux(packet)

            yield write
            for packet in stream.encode():
                container.mux(packet)
        finally:
            container.close()
