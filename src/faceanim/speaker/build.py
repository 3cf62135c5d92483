"""Building a speaker's articulatory model from the motion of a speech video.

Two constructions of the displacement vectors, both with parameters of unit variance over the frames
used (so a parameter reads in standard deviations, and the interpretation's ridge is one prior for all):

* ``"pca"``: the principal components of the mobile points' positions.
* ``"guided"``, as the ICP models were built: the jaw's parameter first, from the chin alone, then
  the lips' parameters one after another, each from the residual that the previous ones leave
  (protrusion and rounding, opening, upper lip, lower lip, corners). Each parameter is the first
  principal component of the residual on its own few coordinates (the chin's height and depth, the
  lips' depth and width, ...); its displacement vector is the regression of every point's residual
  on it, so the jaw's vector carries the lips the jaw carries. Parameters beyond these six are the
  principal components of what is left.

``benchmarks/speaker_model.py`` measures both on frames held out of the fit (6 contiguous blocks of
each shared speech clip, one held out at a time; 10 reporting draws). With 6 parameters they explain
about as much of the held-out lips' and jaw's variance (medians 84.5% guided, 82.2% PCA about the
block's own mean; 92.8% and 92.0% about the model's rest), but the guided model decodes the
held-out frames' tracked FAPs closer in 9 and 7 draws of 10 (from all 34 FAPs and from the 8 of the ICP
figure): its parameters are read from the feature points the FAPs measure, where PCA's also serve
the jaw line and cheeks. Guided is the default.

Each model also measures how its parameters persist from one frame to the next over the frames it
was built on (:func:`persistence`), the temporal prior of its interpretation.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay

from ..motion import Motion
from .model import DEFAULT_RIDGE, SpeakerModel

__all__ = ["build_model", "mobile_names", "GUIDED", "METHODS"]

METHODS = ("guided", "pca")
CHEEKS = ("5.1", "5.2", "5.3", "5.4")
NOSE = ("9.1", "9.2", "9.3")  # the nostrils and the tip: FAPs 61-64, which the upper lip and cheeks pull

_X, _Y, _Z = 0, 1, 2
_UPPER_LIP = ("8.1", "8.5", "8.6", "2.2", "2.6", "2.7")
_LOWER_LIP = ("8.2", "8.7", "8.8", "2.3", "2.8", "2.9")
_CORNERS = ("2.4", "2.5", "8.3", "8.4")
_LIPS = _UPPER_LIP + _LOWER_LIP + _CORNERS

# The guided parameters, in the order they are taken out: (name, coordinates it is read from, each
# (point, axis, sign)). The sign orients the parameter: positive moves those coordinates that way (0: no
# say). A parameter whose points the motion lacks is replaced by the next principal component.
GUIDED: tuple[tuple[str, tuple[tuple[str, int, int], ...]], ...] = (
    ("jaw", tuple((p, a, s) for p in ("2.1", "2.10", "2.11", "2.12") for a, s in ((_Y, -1), (_Z, 0)))),
    ("protrusion", tuple((p, _Z, 1) for p in _LIPS) + (("2.4", _X, -1), ("2.5", _X, 1), ("8.3", _X, -1),
                                                        ("8.4", _X, 1))),
    ("opening", tuple((p, _Y, 1) for p in ("2.2", "2.6", "2.7")) + tuple((p, _Y, -1) for p in ("2.3", "2.8", "2.9"))),
    ("upper_lip", tuple((p, _Y, 1) for p in _UPPER_LIP)),
    ("lower_lip", tuple((p, a, s) for p in _LOWER_LIP for a, s in ((_Y, 1), (_Z, 0)))),
    ("corners", (("2.4", _X, 1), ("2.5", _X, -1), ("8.3", _X, 1), ("8.4", _X, -1))
     + tuple((p, _Y, 1) for p in _CORNERS)),
)


def mobile_names(motion: Motion) -> tuple[str, ...]:
    """The points a speaker's model moves: every point of ``motion`` below the bottom of the nose (9.15)
    at rest (lips, chin, jaw line, lower cheeks), the cheek feature points 5.1-5.4 and the nose's
    9.1-9.3 (nostrils and tip)."""
    if "9.15" not in motion.names:
        raise ValueError("the motion needs the bottom of the nose (feature point 9.15) to tell the mobile points")
    below = motion.neutral[:, 1] < motion.neutral[motion.names.index("9.15"), 1]
    return tuple(n for n, low in zip(motion.names, below, strict=True) if low or n in CHEEKS or n in NOSE)


def _pca(residual: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit-variance scores ``(N, count)`` and vectors ``(count, D)`` of the first principal components
    of the centred ``residual (N, D)``."""
    U, S, Vt = np.linalg.svd(residual, full_matrices=False)
    N = len(residual)
    return U[:, :count] * np.sqrt(N), Vt[:count] * (S[:count, None] / np.sqrt(N))


def _guided(X: np.ndarray, names: tuple[str, ...], count: int) -> tuple[np.ndarray, tuple[str, ...]]:
    """Guided displacement vectors ``(count, 3P)`` of centred positions ``X (N, P, 3)`` and their names."""
    N = len(X)
    residual = X.reshape(N, -1).copy()
    lookup = {n: i for i, n in enumerate(names)}
    vectors, labels = [], []
    for label, coordinates in GUIDED[:count]:
        usable = [(lookup[p] * 3 + axis, sign) for p, axis, sign in coordinates if p in lookup]
        if not usable:
            continue
        columns = np.array([c for c, _ in usable])
        signs = np.array([s for _, s in usable], dtype=np.float64)
        _, _, Vt = np.linalg.svd(residual[:, columns], full_matrices=False)
        score = residual[:, columns] @ Vt[0]
        score *= -1.0 if Vt[0] @ signs < 0 else 1.0
        spread = score.std()
        if spread <= 1e-12:
            continue
        a = score / spread
        vector = residual.T @ a / N  # the regression of every coordinate on the unit-variance parameter
        residual -= np.outer(a, vector)
        vectors.append(vector)
        labels.append(label)
    if len(vectors) < count:
        _, rest = _pca(residual, count - len(vectors))
        vectors += list(rest)
        labels += [f"residual{k + 1}" for k in range(count - len(labels))]
    return np.array(vectors), tuple(labels)


def build_model(motion: Motion, *, parameters: int = 6, frames=None, method: str = "guided",
                ridge: float = DEFAULT_RIDGE) -> SpeakerModel:
    """A speaker's model from ``motion`` (a speech video's capture, cm).

    Parameters
    ----------
    motion : Motion
        With MPEG-4 feature points named (a tracked video's).
    parameters : int
        ``K``, the number of articulatory parameters (6 for speech: jaw and lips).
    frames : (T,) bool or int indices, optional
        The frames to build from (default: all); frames without a face are left out.
    method : {"guided", "pca"}
        See the module's docstring.
    ridge : float
        The interpretation's ridge (cm^2), kept in the model.

    Raises
    ------
    ValueError
        Fewer usable frames than ``parameters + 1``, a bad ``method`` or ``parameters``.
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    if isinstance(parameters, bool) or not isinstance(parameters, (int, np.integer)) or parameters < 1:
        raise ValueError(f"parameters must be a whole number from 1, got {parameters!r}")
    chosen = np.zeros(len(motion), dtype=bool)
    chosen[np.arange(len(motion)) if frames is None else frames] = True
    chosen &= motion.valid
    if chosen.sum() <= parameters:
        raise ValueError(f"{int(chosen.sum())} frames with a face are too few for {parameters} parameters "
                         f"(at least {parameters + 1})")
    names = mobile_names(motion)
    index = motion.index(names)
    neutral = motion.neutral[index]
    positions = neutral + motion.displacements[np.flatnonzero(chosen)][:, index]
    rest = positions.mean(axis=0)
    X = positions - rest
    count = min(parameters, X.size)
    if method == "pca":
        _, vectors = _pca(X.reshape(len(X), -1), count)
        labels = tuple(f"pc{k + 1}" for k in range(count))
    else:
        vectors, labels = _guided(X, names, count)
    static = tuple(n for n in motion.names if n not in set(names))
    static_points = motion.neutral[motion.index(static)] if static else np.zeros((0, 3))
    everything = np.vstack([rest, static_points])
    triangles = Delaunay(everything[:, :2]).simplices.astype(np.int64)
    model = SpeakerModel(names, neutral, rest, vectors.reshape(count, len(names), 3), labels, static, static_points,
                         triangles, motion.fapu, np.zeros((count, 2)), motion.fps, method=method, ridge=ridge)
    seen = model.fit_points(positions - neutral)
    return SpeakerModel(names, neutral, rest, model.basis, labels, static, static_points, triangles, motion.fapu,
                        np.stack([seen.min(axis=0), seen.max(axis=0)], axis=1), motion.fps, method=method,
                        ridge=ridge, persistence=persistence(seen, np.flatnonzero(chosen)))


def persistence(parameters: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """(K,) each unit-variance parameter's correlation with itself one frame earlier, ``1 - E[(a_t -
    a_(t-1))^2] / 2`` over the pairs of consecutive frames among ``frames`` (the frame numbers of
    ``parameters (N, K)``' rows), kept within 0 and 0.999; 0 where no two frames follow each other."""
    follows = np.flatnonzero(np.diff(frames) == 1)
    if not len(follows):
        return np.zeros(parameters.shape[1])
    change = parameters[follows + 1] - parameters[follows]
    return np.clip(1 - (change**2).mean(axis=0) / 2, 0.0, 0.999)


def reconstruction_error(model: SpeakerModel, motion: Motion, frames=None) -> np.ndarray:
    """(N, P, 3) what the model misses of the mobile points on ``frames`` of ``motion`` (default all
    frames with a face): their positions less the model's nearest shape (cm)."""
    chosen = np.zeros(len(motion), dtype=bool)
    chosen[np.arange(len(motion)) if frames is None else frames] = True
    chosen &= motion.valid
    d = motion.displacements[np.flatnonzero(chosen)][:, motion.index(model.names)]
    return model.neutral + d - model.points(model.fit_points(d))
