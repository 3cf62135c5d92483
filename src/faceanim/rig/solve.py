"""Per-frame weights of a rig's shapes: bounded least squares against the motion at control points.

Frame by frame, the weights ``w`` in [0, 1] minimise

    ||A w - d_t||^2 / s  +  sum_j n_j (ridge w_j^2 + temporal (w_j - w_{t-1,j})^2)  +  sum_j p_j (w_j - q_tj)^2

where ``A (3K, S)`` holds the shapes' displacements at the ``K`` control points, ``d_t`` the points'
motion in frame ``t``, ``s`` the shapes' mean squared size at the points and ``n_j`` shape ``j``'s own
over ``s`` (so ridge and temporal read as fractions of each shape's own size, whatever the unit and
however many points it moves), and ``q_tj`` a prior weight (the tracker's blendshape score)
that pulls shape ``j`` with strength ``p_j`` (the eyes and brows, which the geometry reads poorly). All
terms are quadratic, so a frame is a box-constrained quadratic program in ``S`` unknowns with a
Hessian fixed for the whole take: :func:`box_qp` solves it by a primal active set started from the
previous frame's solution (few steps a frame; the result is the exact optimum, the same
``scipy.optimize.lsq_linear`` finds). The temporal term is causal and small: the capture's One Euro
filter already smooths the motion, and a key per frame stays editable.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from ..validation import as_array

__all__ = ["RigSolver", "box_qp", "RIDGE", "TEMPORAL", "PRIOR", "SPARSITY"]

RIDGE = 1e-3      # against shapes that (nearly) repeat each other at the points
TEMPORAL = 0.002  # pull towards the previous frame's weights
PRIOR = 4.0       # strength of a blendshape score on the shapes it leads (eyes and brows)
SPARSITY = 0.0    # a linear cost on each weight (an L1 term, as weights are >= 0): fewer shapes on
_FLOOR = 1e-3     # the least size a shape's own ridge is measured in (fraction of the mean)


def box_qp(H: np.ndarray, g: np.ndarray, start: np.ndarray | None = None, *, max_steps: int | None = None
           ) -> np.ndarray:
    """``argmin 0.5 w'Hw - g'w`` over ``w`` in [0, 1]^S, ``H (S, S)`` symmetric positive definite.

    A primal active set: from ``start`` (clipped into the box; zeros when None), the free weights
    take the unconstrained optimum with the bounded ones held, stepping only as far as the box
    allows (the weight that meets a bound is held there); a held weight whose gradient points into
    the box is freed. Each step lowers the objective, so it ends at the optimum; ``max_steps``
    (default ``10 S``) only guards against rounding loops.

    >>> H = np.array([[2.0, 0.0], [0.0, 2.0]]); g = np.array([4.0, -1.0])
    >>> box_qp(H, g).tolist()
    [1.0, 0.0]
    """
    S = len(g)
    w = np.zeros(S) if start is None else np.clip(np.asarray(start, dtype=np.float64), 0.0, 1.0)
    low, high = w <= 0.0, w >= 1.0
    w[low], w[high] = 0.0, 1.0
    held = low | high
    for _ in range(max_steps or 10 * S + 10):
        free = ~held
        if free.any():
            f = np.flatnonzero(free)
            rhs = g[f] - H[np.ix_(f, np.flatnonzero(held))] @ w[held]
            target = np.linalg.solve(H[np.ix_(f, f)], rhs)
            step = target - w[f]
            over = np.where(step > 0, (1.0 - w[f]) / np.where(step > 0, step, 1.0),
                            np.where(step < 0, -w[f] / np.where(step < 0, step, -1.0), np.inf))
            alpha = float(over.min(initial=np.inf))
            if alpha < 1.0:  # a bound is met first: hold the weight that met it, there
                w[f] += alpha * step
                k = f[int(np.argmin(over))]
                w[k] = 1.0 if step[int(np.argmin(over))] > 0 else 0.0
                held[k] = True
                continue
            w[f] = target
        gradient = H @ w - g
        wrong = held & (((w <= 0.0) & (gradient < -1e-12)) | ((w >= 1.0) & (gradient > 1e-12)))
        if not wrong.any():
            return np.clip(w, 0.0, 1.0)
        k = int(np.argmax(np.where(wrong, np.abs(gradient), -1.0)))
        held[k] = False
    return _fallback(H, g)


def _fallback(H, g) -> np.ndarray:
    """The same optimum through scipy's bounded least squares (``H = R'R``)."""
    from scipy.optimize import lsq_linear

    R = np.linalg.cholesky(H).T
    return np.clip(lsq_linear(R, np.linalg.solve(R.T, g), bounds=(0.0, 1.0), method="bvls").x, 0.0, 1.0)


class RigSolver:
    """Weights of ``S`` shapes from the motion of ``K`` control points, frame by frame.

    Parameters
    ----------
    basis : (S, K, 3) float64
        Each shape's displacement at the control points (any unit; the motion's).
    prior_strength : (S,) float64, optional
        ``p_j``: how strongly a prior weight pulls shape ``j`` (0: the geometry alone). Default 0.
    point_weights : (K,) float64, optional
        How much each point's residual counts (default 1): points that only the prior-led shapes move
        (the lids, the brows) can be let go, so that what the geometry misreads there is not forced
        onto other shapes.
    ridge, temporal : float
        See the module's notes (fractions of a shape's squared size).

    Calling ``solver(observed, prior=None)`` with ``observed (T, K, 3)`` (NaN rows: no face, the
    previous weights are held) and ``prior (T, S)`` (NaN: no prior in that frame) returns ``(T, S)``
    weights in [0, 1]. ``solver.last`` is the last frame's weights, the start of the next call (so a
    take can be solved a run of frames at a time).
    """

    def __init__(self, basis, *, prior_strength=None, point_weights=None, ridge: float = RIDGE,
                 temporal: float = TEMPORAL, sparsity: float = SPARSITY):
        basis = as_array(basis, "basis", shape=("S", "K", 3))
        S, K = basis.shape[:2]
        mass = np.ones(K) if point_weights is None else as_array(point_weights, "point_weights", shape=(K,))
        if (mass < 0).any():
            raise ValueError("point_weights must not be negative")
        self.root = np.repeat(np.sqrt(mass), 3)  # each point's weight on its 3 coordinates, as sqrt
        self.A = basis.reshape(S, -1).T * self.root[:, None]
        self.scale = float(np.mean((self.A ** 2).sum(axis=0))) or 1.0
        strength = np.zeros(S) if prior_strength is None else as_array(prior_strength, "prior_strength", shape=(S,))
        if (strength < 0).any() or ridge < 0 or temporal < 0:
            raise ValueError("prior_strength, ridge and temporal must not be negative")
        self.strength = strength
        gram = self.A.T @ self.A / self.scale
        # Each shape's ridge and temporal pull in its own size at the points (a lid's shape moves few
        # points, a jaw's many), floored so a shape that moves no point (tongueOut) stays defined (at 0).
        self.size = np.maximum(np.diag(gram), _FLOOR)
        self.temporal = float(temporal) * self.size
        self.H = gram + np.diag((ridge + temporal) * self.size)
        self.sparsity = float(sparsity) * self.size
        self.last = np.zeros(S)

    def __call__(self, observed, prior=None) -> np.ndarray:
        observed = as_array(observed, "observed", shape=("T", self.A.shape[0] // 3, 3), finite=False)
        T, S = len(observed), self.A.shape[1]
        prior = np.full((T, S), np.nan) if prior is None else as_array(prior, "prior", shape=(T, S), finite=False)
        data = (observed.reshape(T, -1) * self.root) @ self.A / self.scale  # A'Md / s, every frame at once
        has_prior = np.isfinite(prior) & (self.strength > 0)
        out = np.empty((T, S))
        plain = cho_factor(self.H + np.diag(self.strength))
        for t in range(T):
            if not np.isfinite(data[t]).all():
                out[t] = self.last
                continue
            g = data[t] + self.temporal * self.last - self.sparsity
            pull = np.where(has_prior[t], self.strength, 0.0)
            g += pull * np.where(has_prior[t], prior[t], 0.0)
            H = self.H + np.diag(pull)
            usual = has_prior[t].sum() == (self.strength > 0).sum()  # the cached factor holds
            w = cho_solve(plain, g) if usual else np.linalg.solve(H, g)
            if w.min() < 0.0 or w.max() > 1.0:  # the free optimum clipped: the start of the active set
                w = box_qp(H, g, w)
            self.last = out[t] = w
        return out
