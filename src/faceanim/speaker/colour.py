"""The lip/skin colour model: each pixel's RGB becomes its probability of being lip.

A linear discriminant (Fisher's) on RGB: the direction ``w = S^-1 (m_lip - m_skin)`` (``S`` the pooled
within-class covariance of lip and skin pixels) turns a colour into one number ``s = w . rgb``; lip and
skin are each a Gaussian along it (their projected means and the pooled spread), and a pixel's
probability of being lip is the posterior with equal priors, a logistic function of ``s``. The model
is learnt once from the key frames' lip pixels (inside the lip contour) and skin pixels around them,
applied once to the key textures, and re-estimated on a new video's first frame from its tracked lip
region (:meth:`ColourModel.adapted`), so that a change of lighting does not move the probabilities.

>>> import numpy as np
>>> lips = np.tile([[180, 60, 70]], (50, 1)) + np.arange(50)[:, None] % 7
>>> skin = np.tile([[200, 150, 120]], (50, 1)) + np.arange(50)[:, None] % 5
>>> model = ColourModel.fit(lips, skin)
>>> image = np.array([[[180, 60, 70], [200, 150, 120]]], dtype=np.uint8)
>>> np.round(model.probability(image), 3).tolist()
[[1.0, 0.0]]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from ..validation import as_array

__all__ = ["ColourModel", "lip_and_skin"]

# Spread added to every channel's variance (RGB units squared): a flat-coloured class (a synthetic image)
# still gives an invertible covariance, and 8-bit quantisation is a spread of 1/12 anyway.
_FLOOR = 1.0
_MIN_PIXELS = 10


@dataclass(frozen=True, eq=False)
class ColourModel:
    """Means ``lip_mean``, ``skin_mean`` (3,) and pooled covariance ``covariance (3, 3)`` of RGB (0-255);
    ``direction (3,)`` is Fisher's discriminant and ``spread`` the pooled standard deviation along it."""

    lip_mean: np.ndarray
    skin_mean: np.ndarray
    covariance: np.ndarray

    def __post_init__(self):
        object.__setattr__(self, "lip_mean", as_array(self.lip_mean, "lip_mean", shape=(3,), frozen=True))
        object.__setattr__(self, "skin_mean", as_array(self.skin_mean, "skin_mean", shape=(3,), frozen=True))
        covariance = as_array(self.covariance, "covariance", shape=(3, 3), frozen=True)
        if not np.allclose(covariance, covariance.T) or np.linalg.eigvalsh(covariance).min() <= 0:
            raise ValueError("covariance must be symmetric positive definite")
        object.__setattr__(self, "covariance", covariance)
        if np.allclose(self.lip_mean, self.skin_mean):
            raise ValueError("lip and skin have the same mean colour: nothing to discriminate")

    @classmethod
    def fit(cls, lip, skin) -> ColourModel:
        """The model of ``lip (n, 3)`` and ``skin (m, 3)`` RGB samples (0-255).

        Raises
        ------
        ValueError
            Fewer than 10 samples of either.
        """
        lip = as_array(np.asarray(lip).reshape(-1, 3), "lip", shape=("n", 3))
        skin = as_array(np.asarray(skin).reshape(-1, 3), "skin", shape=("m", 3))
        if len(lip) < _MIN_PIXELS or len(skin) < _MIN_PIXELS:
            raise ValueError(f"the colour model needs at least {_MIN_PIXELS} lip and skin pixels, "
                             f"got {len(lip)} and {len(skin)}")
        lm, sm = lip.mean(axis=0), skin.mean(axis=0)
        pooled = (((lip - lm).T @ (lip - lm)) + ((skin - sm).T @ (skin - sm))) / (len(lip) + len(skin) - 2)
        return cls(lm, sm, pooled + _FLOOR * np.eye(3))

    @property
    def direction(self) -> np.ndarray:
        """(3,) Fisher's direction, scaled so that lip and skin project one unit apart per pooled spread
        squared: ``w = S^-1 (m_lip - m_skin)``."""
        return np.linalg.solve(self.covariance, self.lip_mean - self.skin_mean)

    @property
    def spread(self) -> float:
        """The pooled standard deviation of the projected colours."""
        w = self.direction
        return float(np.sqrt(w @ self.covariance @ w))

    def logit(self, rgb) -> np.ndarray:
        """``(...)`` float32 log-odds of lip against skin of ``rgb (..., 3)``: ``w . (x - (m_l + m_s) / 2)``
        (the two Gaussians along ``w`` share the spread, so the log ratio is linear)."""
        x = np.asarray(rgb, dtype=np.float32)
        if x.shape[-1:] != (3,):
            raise ValueError(f"rgb must have shape (..., 3), got {x.shape}")
        w = self.direction.astype(np.float32)
        middle = float(w @ (0.5 * (self.lip_mean + self.skin_mean)))
        return x @ w - np.float32(middle)

    def probability(self, image) -> np.ndarray:
        """``(H, W)`` float32 probability of lip of each pixel of ``image (H, W, 3)`` (uint8 RGB)."""
        z = np.clip(self.logit(image), -60.0, 60.0)
        return (1.0 / (1.0 + np.exp(-z))).astype(np.float32)

    def adapted(self, image, lip_mask, skin_mask=None) -> ColourModel:
        """The model re-estimated on ``image (H, W, 3)``: its lip pixels (``lip_mask (H, W)``, the tracked
        lips) and skin pixels (``skin_mask``; by default a ring around the lips, see :func:`lip_and_skin`).
        Means and spread come from this image, so a change of lighting or camera follows.

        Raises
        ------
        ValueError
            Masks of the wrong shape, or fewer than 10 pixels of lip or skin in them.
        """
        image = np.asarray(image)
        if image.ndim != 3 or image.shape[2] != 3:
            raise ValueError(f"image must have shape (H, W, 3), got {image.shape}")
        lip_mask = np.asarray(lip_mask, dtype=bool)
        if lip_mask.shape != image.shape[:2]:
            raise ValueError(f"lip_mask must have shape {image.shape[:2]}, got {lip_mask.shape}")
        if skin_mask is None:
            lip_mask, skin_mask = lip_and_skin(lip_mask)
        skin_mask = np.asarray(skin_mask, dtype=bool)
        if skin_mask.shape != image.shape[:2]:
            raise ValueError(f"skin_mask must have shape {image.shape[:2]}, got {skin_mask.shape}")
        return ColourModel.fit(image[lip_mask], image[skin_mask])


def lip_and_skin(lip_mask, *, margin: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The pixels to learn from, given the lips' region ``lip_mask (H, W)``: the lips eroded by one
    pixel (away from the contour, where colours mix) and a ring of skin around them and the mouth's opening,
    from ``margin / 3`` to ``margin`` pixels out (``margin`` default: a third of the lips' width)."""
    lip_mask = np.asarray(lip_mask, dtype=bool)
    if margin is None:
        columns = np.flatnonzero(lip_mask.any(axis=0))
        margin = max(3, (columns[-1] - columns[0]) // 3 if len(columns) else 3)
    inner = ndimage.binary_erosion(lip_mask, iterations=1)
    mouth = ndimage.binary_fill_holes(lip_mask)  # the lips and the opening between them: not skin
    near = ndimage.binary_dilation(mouth, iterations=max(1, margin // 3))
    far = ndimage.binary_dilation(mouth, iterations=margin)
    return (inner if inner.sum() >= _MIN_PIXELS else lip_mask), far & ~near
