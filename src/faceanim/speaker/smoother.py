"""The speaker model's temporal prior as a smoother within a window of frames, consistent with the
quantiser's cells: :meth:`faceanim.speaker.SpeakerModel.regularise` with ``window``.

A decoder that reads a ``.fba`` packet by packet (:class:`faceanim.mpeg4.fapcoder.FbaDecoder`) already
waits for a packet's last frame before it has any of its frames; within that delay it can estimate
each frame's parameters from the frames after it as well as those before. Over a window of ``W``
frames the estimate is the most probable trajectory of the parameters under the model's temporal
prior (each parameter a first-order autoregression, :attr:`~faceanim.speaker.SpeakerModel.persistence`)
given the FAPs received: the fixed-interval smoother of the causal filter ``temporal=True`` computes
frame by frame, started from the filter's state at the window before (its mean and covariance, so
nothing is lost at the window's edge).

With ``quant`` (a coded stream), a received FAP also says where its value lies: within half a step
of the value decoded (the coder's reconstruction is ``step x round(value / step)``). At coarse steps
this matters more than the rounding error's variance: a FAP that decodes to the same value for many
frames, or that has just crossed into the next cell, bounds the parameters far better than a Gaussian
error of variance step^2 / 12 says. The estimate therefore also pays, for every FAP it would put
outside its cell, a steep quadratic penalty on the distance outside (consistent reconstruction,
softened so that a FAP the model cannot bring inside, on a stream the model did not make, does not
make the problem infeasible).

The objective is convex and piecewise quadratic; it is minimised by Newton's method on the active
set of cell bounds (exact in a few steps: each step solves one linear system of ``W x K`` unknowns,
block-tridiagonal), with a backtracking step for safety.
"""

from __future__ import annotations

import numpy as np

__all__ = ["CELL_PENALTY", "smooth_run"]

# The penalty on a FAP's distance outside its cell, per squared step, beside the Gaussian term's 12 per
# squared step (a rounding error's variance is 1/12 step^2): outside the cell costs ~100 times as much,
# so the estimate stays inside wherever the model can reach (steeper changes nothing measurable on
# the tuning streams; see benchmarks/fap_coding.py).
CELL_PENALTY = 1e3
_ITERATIONS = 30


def smooth_run(G: np.ndarray, offset: np.ndarray, values: np.ndarray, received: np.ndarray, weight: np.ndarray,
               noise: float, persistence: np.ndarray, mean0: np.ndarray, cov0: np.ndarray, *,
               cells: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """The smoothed parameters of a run of frames that each carry enough FAPs.

    Parameters
    ----------
    G : (J, K) float64
        FAPs per unit of each parameter (the model's :attr:`fap_matrix`).
    offset : (J,) float64
        The FAPs at parameters 0.
    values : (n, J) float64
        The FAPs received (any value where not received).
    received : (n, J) bool
    weight : (J,) float64
        Each FAP's weight: errors are measured as ``weight x (FAP - model's FAP)``; with ``cells``, one
        over each FAP's step, so that the cell is ``[-0.5, 0.5]``.
    noise : float
        The variance of a weighed FAP's error (1/12 for steps, the ridge for cm).
    persistence : (K,) float64
        The prior's autoregression.
    mean0, cov0 : (K,) and (K, K) float64
        The prior of the run's first frame (0 and the identity where it has no past).
    cells : (J,) float64 or None
        Each FAP's cell's half-width in weighed units (a coded stream): FAPs outside it are penalised;
        None: no cells.

    Returns
    -------
    a : (n, K) float64
        The parameters of each frame.
    cov_last : (K, K) float64
        The posterior covariance of the last frame's parameters (to carry into the next run).
    """
    n, K = len(values), G.shape[1]
    F = persistence
    qi = 1.0 / (1.0 - persistence**2)
    P0 = _solve(cov0, np.eye(K), K)  # its inverse (banded LAPACK: unthreaded, quick at K x K)
    # the weighed rows (J, K), their outer products (J, K*K), and the targets z (n, J), zero where not
    # received; a frame's rows are those it received (its residuals below are masked so)
    H = weight[:, None] * G
    outer = (H[:, :, None] * H[:, None, :]).reshape(len(H), K * K)
    z = np.where(received, weight * (values - offset), 0.0)
    # the constant part of the Hessian: the prior (block tridiagonal) and the Gaussian term
    t, k = np.arange(n), np.arange(K)
    base = np.zeros((n, K, n, K))
    base[t, :, t, :] = (received @ outer).reshape(n, K, K) / noise
    diagonal = np.tile(qi, (n, 1))
    diagonal[0] = 0
    diagonal[:-1] += F * qi * F
    base[t[:, None], k, t[:, None], k] += diagonal
    base[0, :, 0, :] += P0
    base[t[:-1, None], k, t[1:, None], k] = -F * qi
    base[t[1:, None], k, t[:-1, None], k] = -F * qi
    base = base.reshape(n * K, n * K)

    def objective(a):
        d0 = a[0] - mean0
        value = d0 @ P0 @ d0
        if n > 1:
            step = a[1:] - F * a[:-1]
            value += (step**2 * qi).sum()
        r = (a @ H.T) * received - z
        value += (r**2).sum() / noise
        if cells is not None:
            value += CELL_PENALTY * (np.maximum(np.abs(r) - cells, 0.0) ** 2 * received).sum()
        return value, r

    # start: the Gaussian solution (one linear solve), then Newton on the cells' active set
    rhs0 = np.zeros((n, K))
    rhs0[0] = P0 @ mean0
    rhs0 += z @ H / noise
    a = _solve(base, rhs0.reshape(-1), K).reshape(n, K)
    if cells is not None:
        value, r = objective(a)
        for _ in range(_ITERATIONS):
            over = (np.abs(r) > cells) & received
            if not over.any():
                break
            target = np.where(over, z + cells * np.sign(r), 0.0)  # the bound each active FAP is pulled to
            hess = _penalised(base, outer, over, n, K)
            rhs = rhs0 + CELL_PENALTY * (target @ H)
            new = _solve(hess, rhs.reshape(-1), K).reshape(n, K)
            scale, done = 1.0, False
            while scale > 1e-4:  # backtrack until the objective does not rise
                trial = a + scale * (new - a)
                trial_value, trial_r = objective(trial)
                if trial_value <= value + 1e-12 * abs(value):
                    done = np.abs(trial - a).max() <= 1e-12
                    a, value, r = trial, trial_value, trial_r
                    break
                scale /= 2
            else:
                break
            if done:
                break
        final = _penalised(base, outer, (np.abs(r) > cells) & received, n, K)
    else:
        final = base
    unit = np.zeros((n * K, K))
    unit[-K:] = np.eye(K)
    cov_last = _solve(final, unit, K)[-K:]
    return a, (cov_last + cov_last.T) / 2


def _penalised(base: np.ndarray, outer: np.ndarray, over: np.ndarray, n: int, K: int) -> np.ndarray:
    """The Hessian ``base`` plus the cell penalty's blocks for the FAPs ``over (n, J)`` their cells
    (``outer``: each FAP's weighed row's outer product, (J, K*K))."""
    hess = base.copy().reshape(n, K, n, K)
    t = np.arange(n)
    hess[t, :, t, :] += CELL_PENALTY * (over @ outer).reshape(n, K, K)
    return hess.reshape(n * K, n * K)


def _solve(matrix: np.ndarray, rhs: np.ndarray, K: int) -> np.ndarray:
    """``matrix^-1 rhs`` for the symmetric positive definite Hessian, whose nonzeros lie within ``K`` of
    the diagonal (a frame's parameters couple among themselves and to the same parameter one frame
    away): a banded Cholesky solve, linear in the frames (and single-threaded)."""
    from scipy.linalg import solveh_banded

    N = len(matrix)
    bands = np.zeros((K + 1, N))
    for d in range(K + 1):  # upper form: bands[K - d, j] = matrix[j - d, j]
        bands[K - d, d:] = np.diagonal(matrix, d)
    return solveh_banded(bands, rhs, lower=False, check_finite=False)
