"""Image warping by radial basis functions (Arad, Dyn, Reisfeld and Yeshurun 1994, "Image warping by
radial basis functions: applications to facial expressions"): points of an image move, an RBF through
their displacements moves every pixel, the image follows.

The RBF is fitted at the points' rest positions, so its operator onto a pixel grid is computed once and
each frame costs one matrix product. That gives the forward map (where each rest pixel goes); an image
is resampled with the backward map (where each output pixel comes from), which is found by a few
fixed-point steps ``x = y - d(x)``, convergent while the warp does not fold (its displacement gradient
stays below one).
"""

from __future__ import annotations

import numpy as np

from ..validation import as_array
from .rbf import RbfWarp

__all__ = ["ImageWarp"]


class ImageWarp:
    """A fitted warp of ``width`` x ``height`` images driven by ``points (K, 2)`` (pixels, x right, y down).

    The image border and, when given, ``fixed (M, 2)`` points (a ring around a face, say) stay still.
    ``warp(image, displacements (K, 2))`` returns the image with each point moved by its displacement.

    Parameters
    ----------
    points : (K, 2) float64
    width, height : int
    fixed : (M, 2) float64, optional
    kernel : str
        An :class:`RbfWarp` kernel; thin-plate by default, the smoothest bending of a plane.
    step : int
        Spacing in pixels of the grid the RBF is evaluated on; pixels between are interpolated bilinearly.

    Examples
    --------
    >>> warp = ImageWarp([[20.0, 20.0]], 40, 40, step=4)
    >>> image = np.zeros((40, 40, 3), np.uint8); image[18:23, 18:23] = 255
    >>> moved = warp(image, [[4.0, 0.0]])
    >>> np.flatnonzero(moved[20, :, 0] > 127).tolist()  # the square (columns 18-22) moved 4 pixels right
    [22, 23, 24, 25, 26]
    """

    def __init__(self, points, width: int, height: int, *, fixed=None, kernel: str = "thin_plate", step: int = 8):
        points = as_array(points, "points", shape=("K", 2), min_length=1)
        if int(width) < 2 or int(height) < 2:
            raise ValueError(f"image size must be at least 2 x 2, got {width} x {height}")
        if int(step) < 1:
            raise ValueError(f"step must be a positive number of pixels, got {step}")
        self.width, self.height, self.count = int(width), int(height), len(points)
        border = _border(self.width, self.height, spacing=2.0 * step)
        still = border if fixed is None else np.vstack([border, as_array(fixed, "fixed", shape=("M", 2))])
        centres = np.vstack([points, still])
        self._gx = np.unique(np.append(np.arange(0, self.width, step), self.width - 1)).astype(np.float64)
        self._gy = np.unique(np.append(np.arange(0, self.height, step), self.height - 1)).astype(np.float64)
        grid = np.stack(np.meshgrid(self._gx, self._gy), axis=-1).reshape(-1, 2)
        operator = RbfWarp(centres, np.zeros_like(centres), kernel=kernel).operator(grid)
        self._operator = operator[:, :len(points)]  # the still centres carry zero displacement

    def __call__(self, image, displacements, *, iterations: int = 5) -> np.ndarray:
        from scipy.ndimage import map_coordinates

        image = np.asarray(image)
        if image.shape[:2] != (self.height, self.width):
            raise ValueError(f"image must be {self.height} x {self.width} pixels, got {image.shape[:2]}")
        d = as_array(displacements, "displacements", shape=(self.count, 2))
        shape = (len(self._gy), len(self._gx))
        forward = (self._operator @ d).T.reshape(2, *shape)
        # The backward map is solved on the grid, where it is as smooth as the forward one, then spread
        # to every pixel: the cost of a frame is then one resampling of the image.
        gy, gx = np.meshgrid(self._gy, self._gx, indexing="ij")
        source = np.stack([gx, gy])
        for _ in range(iterations):
            at = [_grid_index(source[1], self._gy), _grid_index(source[0], self._gx)]
            source = np.stack([gx, gy]) - np.stack([map_coordinates(f, at, order=1, mode="nearest") for f in forward])
        backward = source - np.stack([gx, gy])
        rows, columns = np.mgrid[0:self.height, 0:self.width].astype(np.float64)
        at = np.stack(np.meshgrid(_grid_index(np.arange(self.height), self._gy),
                                  _grid_index(np.arange(self.width), self._gx), indexing="ij"))
        source_x = columns + map_coordinates(backward[0], at, order=1, mode="nearest")
        source_y = rows + map_coordinates(backward[1], at, order=1, mode="nearest")
        channels = image[..., None] if image.ndim == 2 else image
        out = np.stack([map_coordinates(channels[..., c], [source_y, source_x], order=1, mode="nearest",
                                        output=np.float64) for c in range(channels.shape[2])], axis=-1)
        out = np.clip(np.rint(out), 0, 255).astype(image.dtype) if image.dtype == np.uint8 else out
        return out.reshape(image.shape)


def _border(width: int, height: int, *, spacing: float) -> np.ndarray:
    """Points around the image's edge, ``spacing`` apart."""
    xs = np.linspace(0, width - 1, max(2, int(np.ceil((width - 1) / spacing)) + 1))
    ys = np.linspace(0, height - 1, max(2, int(np.ceil((height - 1) / spacing)) + 1))[1:-1]
    return np.vstack([np.column_stack([xs, np.zeros_like(xs)]), np.column_stack([xs, np.full_like(xs, height - 1)]),
                      np.column_stack([np.zeros_like(ys), ys]), np.column_stack([np.full_like(ys, width - 1), ys])])


def _grid_index(coordinate: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Fractional index of pixel coordinates into a sorted grid axis."""
    i = np.clip(np.searchsorted(axis, coordinate) - 1, 0, len(axis) - 2)
    return i + (coordinate - axis[i]) / (axis[i + 1] - axis[i])
