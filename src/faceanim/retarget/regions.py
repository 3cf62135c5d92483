"""Face regions (lips, eyes, brows, nose, cheeks, jaw) from the 68-point landmark layout."""

from __future__ import annotations

import numpy as np

from ..validation import as_array

__all__ = ["REGIONS", "label_regions", "region_mask"]

REGIONS = ("lips", "eyes", "brows", "nose", "cheeks", "jaw")
_GROUP_OF_LANDMARK = np.empty(68, dtype=np.int64)
_GROUP_OF_LANDMARK[48:68] = 0   # lips
_GROUP_OF_LANDMARK[36:48] = 1   # eyes
_GROUP_OF_LANDMARK[17:27] = 2   # brows
_GROUP_OF_LANDMARK[27:36] = 3   # nose
_GROUP_OF_LANDMARK[0:17] = 5    # jaw line


def label_regions(points, landmarks) -> np.ndarray:
    """Region of each point (index into :data:`REGIONS`) by its nearest landmark.

    Parameters
    ----------
    points : (N, 3) float64
    landmarks : (68, 3) float64
        The 68-point iBUG / Multi-PIE layout on the same face, +Y up.

    Points nearest a jaw-line landmark count as cheeks above the outer lip corners, jaw below.

    >>> lm = np.zeros((68, 3)); lm[:, 0] = np.arange(68)
    >>> [REGIONS[i] for i in label_regions([[50.2, 0, 0], [40, 0, 0]], lm)]
    ['lips', 'eyes']
    """
    points = as_array(points, "points", shape=("N", 3))
    landmarks = as_array(landmarks, "landmarks", shape=(68, 3))
    nearest = np.argmin(((points[:, None] - landmarks[None]) ** 2).sum(-1), axis=1)
    label = _GROUP_OF_LANDMARK[nearest]
    corner_height = landmarks[[48, 54], 1].mean()
    label[(label == 5) & (points[:, 1] > corner_height)] = 4
    return label


def region_mask(points, landmarks, regions) -> np.ndarray:
    """Boolean mask of the points in any of the named ``regions``."""
    unknown = [r for r in regions if r not in REGIONS]
    if unknown:
        raise ValueError(f"unknown region {unknown[0]!r}; regions are {', '.join(REGIONS)}")
    return np.isin(label_regions(points, landmarks), [REGIONS.index(r) for r in regions])
