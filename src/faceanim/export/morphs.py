"""An animation as few morph targets with weights in [0, 1], found in two streaming passes.

A performance is ``T`` frames of ``V`` vertices; clients play it as ``K`` shapes added to the rest
mesh with a weight per shape and frame. The shapes are the displacements' principal directions
(a truncated SVD), found without ever holding the ``(T, 3V)`` matrix of displacements:

1. the first pass keeps a running truncated SVD (sequential Karhunen-Loeve: the kept rows
   ``sigma_i v_i`` stacked with the next chunk of frames, and the stack's strongest directions
   kept, through its small Gram matrix) of rank ``max_modes`` plus a margin;
2. the second pass projects every frame on those directions (the weights, ``T x K`` numbers) and
   measures, exactly, the worst per-vertex error of every candidate count of shapes.

Memory is the kept basis and one chunk (about 130 MB on a 26,000-vertex head), whatever the length.
Each frame is read twice: a deformer's animation is best spilled first
(:func:`~faceanim.geometry.animation.spilled`), so that it is deformed once.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import solve_triangular

from ..geometry.animation import Animation
from ..validation import as_array

__all__ = ["MorphSet", "morphs_from_animation"]

_WEIGHT_SLACK = 1e-9  # weights this far outside [0, 1] are rounding, and are clipped
_MARGIN = 16  # directions kept beyond max_modes in the running SVD, so truncating it costs the kept ones little
_CHUNK = 96  # frames taken at once by each pass (near the running SVD's cheapest per frame)
# Counts of shapes tried: each costs arithmetic over every frame, so they are spaced by about 1.5x.
_COUNTS = (1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128)
_ROUNDING = 1e-9  # a weight this small against its mode's strength is rounding (a frame at rest): zero


@dataclass(frozen=True, eq=False)
class MorphSet:
    """Morph targets of a mesh and, optionally, their weights over time.

    ``targets (K, V, 3)`` displacements (model units), ``names`` (K,), ``weights (T, K)`` within
    [0, 1] or None (a still mesh with sliders), ``fps`` for the weights, ``default_weights (K,)``
    within [0, 1], the weights a viewer shows without animation (zeros when not given: the rest
    shape). Weights outside [0, 1] are refused: glTF clients clamp them (Blender's importer to the
    slider range [0, 1]), so they would not play as written.
    """

    targets: np.ndarray
    names: tuple[str, ...]
    weights: np.ndarray | None = None
    fps: float = 25.0
    max_error: float = field(default=0.0)
    default_weights: np.ndarray | None = None

    def __post_init__(self):
        targets = as_array(self.targets, "targets", shape=("K", "V", 3))
        names = tuple(self.names)
        if len(names) != len(targets):
            raise ValueError(f"names must give one name per target ({len(targets)}), got {len(names)}")
        if self.weights is not None:
            weights = as_array(self.weights, "weights", shape=("T", len(targets)), min_length=1)
            object.__setattr__(self, "weights", _unit_interval(weights, "weights", names))
        if self.default_weights is not None:
            weights = as_array(self.default_weights, "default_weights", shape=(len(targets),))
            object.__setattr__(self, "default_weights", _unit_interval(weights, "default_weights", names))
        object.__setattr__(self, "targets", targets)
        object.__setattr__(self, "names", names)


def _unit_interval(weights: np.ndarray, name: str, names: tuple[str, ...]) -> np.ndarray:
    """``weights`` clipped to [0, 1] when they are outside it by rounding only; else a ValueError that
    names the first weight outside."""
    outside = (weights < -_WEIGHT_SLACK) | (weights > 1 + _WEIGHT_SLACK)
    if outside.any():
        at = np.argwhere(outside)[0]
        where = f"frame {at[0]}, target {names[at[-1]]!r}" if weights.ndim == 2 else f"target {names[at[0]]!r}"
        raise ValueError(f"{name} must lie within [0, 1] (glTF clients clamp morph weights), got "
                         f"{weights[tuple(at)]:g} at {where}; split a signed shape into two (see "
                         "morphs_from_animation)")
    return np.clip(weights, 0.0, 1.0)


def morphs_from_animation(animation: Animation, *, max_modes: int = 64, tolerance: float = 1e-4) -> MorphSet:
    """Few morph targets, with weights in [0, 1], that replay ``animation`` (its mesh's vertices are the rest).

    The shapes are the displacements' principal directions, strongest first, found in two passes over
    the frames (see the module's notes): the animation may be streamed, and nothing of the size of all
    its frames is held. The number of modes ``k`` (at most ``max_modes``) is the smallest candidate
    (1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, ..., and ``max_modes``) whose worst per-vertex error over
    all frames, measured exactly, is within ``tolerance`` times the mesh's size (the largest side of
    its bounding box); or the largest when none is. Each mode is written as up to two targets, its positive part
    and its negated negative part (``shape03+``, ``shape03-``), with weights ``max(w, 0)`` and
    ``max(-w, 0)`` scaled to peak at 1; a mode whose weights never change sign gives one.

    Returns
    -------
    MorphSet
        ``targets`` in model units, ``weights (T, K)`` within [0, 1]; ``max_error`` is the worst
        distance (model units), over every frame and vertex, between the animation and what these
        targets replay (in float64; the file's float32 adds about 1e-7 of the mesh's size).

    Examples
    --------
    >>> from faceanim.geometry import Mesh
    >>> mesh = Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    >>> lift = np.sin(np.arange(20) / 3)[:, None, None] * [[0, 0, 0], [0, 0, 0], [0, 0, 0.5]]
    >>> morphs = morphs_from_animation(Animation(mesh, mesh.vertices + lift, 25.0))
    >>> morphs.names, float(morphs.weights.min()), float(morphs.weights.max())
    (('shape00+', 'shape00-'), 0.0, 1.0)
    """
    if int(max_modes) != max_modes or max_modes < 1:
        raise ValueError(f"max_modes must be a whole number of at least 1, got {max_modes}")
    if not np.isfinite(tolerance) or tolerance < 0:
        raise ValueError(f"tolerance must be a non-negative number, got {tolerance}")
    rest = animation.mesh.vertices.ravel()
    size = np.ptp(animation.mesh.vertices, axis=0).max() or 1.0
    shapes, strength = _principal_shapes(animation, rest, int(max_modes) + _MARGIN)
    shapes, strength = shapes[:int(max_modes)], strength[:int(max_modes)]
    if not len(shapes):
        return MorphSet(np.zeros((0, len(rest) // 3, 3)), (), np.zeros((len(animation), 0)), animation.fps)
    counts = np.array(sorted({c for c in _COUNTS if c < len(shapes)} | {len(shapes)}), dtype=np.int64)
    curves, errors = _weights_and_errors(animation, rest, shapes, strength, counts, tolerance * size)
    passing = np.flatnonzero(errors <= tolerance * size)
    at = passing[0] if len(passing) else len(counts) - 1
    k = int(counts[at])
    targets, weights, names = [], [], []
    for j in range(k):
        for sign, suffix in ((1.0, "+"), (-1.0, "-")):
            part = np.maximum(sign * curves[:, j], 0.0)
            peak = part.max()
            if peak > 0:
                targets.append(sign * peak * shapes[j])
                weights.append(part / peak)
                names.append(f"shape{j:02d}{suffix}")
    return MorphSet(np.reshape(targets, (len(targets), -1, 3)), tuple(names), np.transpose(weights), animation.fps,
                    float(errors[at]))


def _principal_shapes(animation: Animation, rest: np.ndarray, rank: int) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal shapes ``(K, 3V)`` and strengths ``(K,)`` (singular values), strongest first, of
    the displacements ``frames - rest``: a running truncated SVD of rank ``rank``. Shapes of
    numerically zero strength are left out.

    Each step stacks the kept rows ``sigma_i v_i`` on the next chunk and keeps the stack's strongest
    directions, from the eigenvectors of its small Gram matrix; exact when the displacements have
    rank ``rank`` or less, the truncated SVD's best approximation otherwise up to what truncating
    at each step loses (the margin over ``max_modes`` keeps that to the weak directions)."""
    kept, power = np.zeros((0, len(rest))), np.zeros(0)
    for chunk in animation.chunks(_CHUNK):
        fresh = chunk.reshape(len(chunk), -1) - rest
        cross = kept @ fresh.T
        # The stack's Gram matrix; the kept rows are orthogonal, so their block is their powers.
        gram = np.block([[np.diag(power), cross], [cross.T, fresh @ fresh.T]])
        power, mix = np.linalg.eigh(gram)
        order = np.argsort(power)[::-1][:rank]
        power, mix = power[order], np.ascontiguousarray(mix[:, order].T)  # BLAS needs it contiguous
        kept = mix[:, :len(kept)] @ kept + mix[:, len(kept):] @ fresh  # rows sigma_i v_i
        kept, power = kept[power > 0], power[power > 0]
    strength = np.linalg.norm(kept, axis=1)
    if not len(strength):
        return kept, strength
    # The Gram matrix resolves powers (squared strengths) to about eps of the strongest, so directions
    # weaker than sqrt(eps) of it are rounding, not motion.
    significant = strength > strength[0] * np.sqrt(max(len(animation), len(rest)) * np.finfo(float).eps)
    kept, strength = kept[significant], strength[significant]
    # Gram-based rows are orthogonal to about eps * (sigma_0 / sigma_i)^2; made orthonormal again
    # (Cholesky QR: the normalised rows are nearly orthonormal, so their Gram matrix is well
    # conditioned), in the same order, a frame's weights are its plain projection.
    unit = kept / strength[:, None]
    lower = np.linalg.cholesky(unit @ unit.T)
    return np.ascontiguousarray(solve_triangular(lower, unit, lower=True)), strength


def _weights_and_errors(animation: Animation, rest: np.ndarray, shapes: np.ndarray, strength: np.ndarray,
                        counts: np.ndarray, limit: float) -> tuple[np.ndarray, np.ndarray]:
    """Weights ``(T, K)`` of every frame on ``shapes`` (projections; rounding-level ones zeroed) and,
    for each count in ``counts``, the worst per-vertex distance over all frames between the
    animation and what the first ``count`` shapes replay. A count found over ``limit`` is measured no
    further (its error is then a lower bound, already over the limit); the largest always is."""
    curves = np.empty((len(animation), len(shapes)))
    worst = np.zeros(len(counts))
    squared_limit = limit * limit
    start = 0
    for chunk in animation.chunks(_CHUNK):
        displacements = chunk.reshape(len(chunk), -1) - rest
        weights = displacements @ shapes.T
        weights[np.abs(weights) <= _ROUNDING * strength] = 0.0
        curves[start:start + len(chunk)] = weights
        start += len(chunk)
        measured = worst <= squared_limit
        measured[-1] = True
        for columns in _column_blocks(displacements.shape[1]):  # a block stays in cache through every count
            residual = displacements[:, columns]
            done = 0
            for i in np.flatnonzero(measured):
                count = counts[i]
                residual -= weights[:, done:count] @ shapes[done:count, columns]
                done = count
                squared = residual * residual
                worst[i] = max(worst[i], float((squared[:, 0::3] + squared[:, 1::3] + squared[:, 2::3]).max()))
    return curves, np.sqrt(worst)


def _column_blocks(n: int, size: int = 3 * 256):
    return (slice(start, min(start + size, n)) for start in range(0, n, size))
