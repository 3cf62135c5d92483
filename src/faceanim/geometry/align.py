"""Rigid and similarity alignment of point sets (weighted Procrustes)."""

from __future__ import annotations

import numpy as np

from ..validation import as_array

__all__ = ["weighted_procrustes", "batch_procrustes", "robust_procrustes", "robust_depth_affine"]


def weighted_procrustes(source, target, weights=None, *, scale: bool = True) -> np.ndarray:
    """The similarity (or rigid) transform that best maps ``source`` onto ``target``.

    Minimises ``sum_i w_i |s R source_i + t - target_i|^2`` over rotations ``R`` (no reflection),
    translations ``t`` and, with ``scale=True``, a scale ``s > 0`` (Umeyama 1991; the weighted form of
    Akca 2003, section 2.4, as MediaPipe's face geometry uses it).

    Parameters
    ----------
    source, target : (N, 3) float64
    weights : (N,) float64, optional
        Non-negative; uniform by default.

    Returns
    -------
    (4, 4) float64
        ``[[s R, t], [0, 0, 0, 1]]``; apply as ``p @ M[:3, :3].T + M[:3, 3]``.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> p = rng.normal(size=(10, 3))
    >>> R = np.array([[0., -1, 0], [1, 0, 0], [0, 0, 1]])
    >>> M = weighted_procrustes(p, 2 * p @ R.T + [1, 2, 3])
    >>> np.allclose(M[:3, :3], 2 * R), np.allclose(M[:3, 3], [1, 2, 3])
    (True, True)
    """
    source = as_array(source, "source", shape=("N", 3), min_length=1)
    target = as_array(target, "target", shape=(len(source), 3))
    w = np.ones(len(source)) if weights is None else as_array(weights, "weights", shape=(len(source),))
    if (w < 0).any() or w.sum() <= 0:
        raise ValueError("weights must be non-negative with a positive sum")
    w = w / w.sum()
    mu_s, mu_t = w @ source, w @ target
    cs, ct = source - mu_s, target - mu_t
    covariance = (ct * w[:, None]).T @ cs
    U, S, Vt = np.linalg.svd(covariance)
    flip = np.sign(np.linalg.det(U) * np.linalg.det(Vt))
    D = np.diag([1.0, 1.0, flip if flip != 0 else 1.0])
    R = U @ D @ Vt
    s = 1.0
    if scale:
        variance = (w * (cs * cs).sum(axis=1)).sum()
        if variance <= 0:
            raise ValueError("source points all coincide; their scale is undefined")
        s = float(np.trace(np.diag(S) @ D) / variance)
    M = np.eye(4)
    M[:3, :3] = s * R
    M[:3, 3] = mu_t - s * R @ mu_s
    return M


def batch_procrustes(source, targets, weights) -> np.ndarray:
    """:func:`weighted_procrustes` (with scale) of one ``source (N, 3)`` onto each of ``targets
    (T, N, 3)`` at once: ``(T, 4, 4)``. ``weights`` are ``(N,)`` shared by every frame or ``(T, N)``
    one set a frame. Inputs are trusted (checked by the caller)."""
    w = np.asarray(weights, dtype=np.float64)
    w = np.broadcast_to(w / w.sum(axis=-1, keepdims=True), targets.shape[:2])
    mu_s = w @ source
    mu_t = np.matmul(w[:, None, :], targets)[:, 0]  # matmul, not einsum: BLAS, several times faster
    cs = source - mu_s[:, None]
    ct = targets - mu_t[:, None]
    covariance = np.matmul((ct * w[..., None]).transpose(0, 2, 1), cs)
    U, S, Vt = np.linalg.svd(covariance)
    flip = np.sign(np.linalg.det(U) * np.linalg.det(Vt))
    flip[flip == 0] = 1.0
    U[:, :, 2] *= flip[:, None]
    S[:, 2] *= flip
    R = U @ Vt
    s = S.sum(axis=1) / (w * (cs * cs).sum(axis=-1)).sum(axis=1)
    M = np.tile(np.eye(4), (len(targets), 1, 1))
    M[:, :3, :3] = s[:, None, None] * R
    M[:, :3, 3] = mu_t - np.einsum("tij,tj->ti", M[:, :3, :3], mu_s)
    return M


def robust_procrustes(source, targets, weights, *, scale: float, rounds: int = 5) -> np.ndarray:
    """:func:`batch_procrustes` that lets points which moved away from ``source`` count less.

    Iteratively reweighted: after each fit, a point ``r`` away from its source position keeps
    ``weights / (1 + (r / scale)^2)`` (Cauchy's weight), so a few points carried off together (a
    pair of eye corners whose depth the tracker shifts through a blink) no longer tilt the fit, while points that
    agree within ``scale`` keep their full say. ``(T, 4, 4)``, source onto each target.
    """
    w0 = np.asarray(weights, dtype=np.float64)
    w = np.broadcast_to(w0, targets.shape[:2])
    for _ in range(rounds):
        M = batch_procrustes(source, targets, w)
        fitted = np.matmul(source, M[:, :3, :3].transpose(0, 2, 1)) + M[:, None, :3, 3]
        # residuals measured at the source's size: divide out the fitted scale
        size = np.cbrt(np.abs(np.linalg.det(M[:, :3, :3])))[:, None]
        r = np.linalg.norm(targets - fitted, axis=-1) / size
        w = w0 / (1.0 + (r / scale) ** 2)
    return batch_procrustes(source, targets, w)


def robust_depth_affine(source, targets, weights, directions, *, scale: float, tilt: bool = True,
                        rounds: int = 5) -> np.ndarray:
    """The map along each frame's unit ``directions (T, 3)`` that best brings ``targets (T, N, 3)`` onto
    ``source (N, 3)``, moving points along that direction only, by an affine function of where they are:
    ``(T, 4, 4)`` affine maps, target onto source.

    Per frame, with ``u`` the direction, ``e1``, ``e2`` two unit directions across it and ``c`` the
    source's weighted centre, the coordinate along ``u`` is fitted (weighted least squares) as
    ``(source - c) . u = g (target - c) . u + a1 (target - c) . e1 + a2 (target - c) . e2 + b``: a gain
    (a stretch along ``u``), a shear along ``u`` by the position across it (a depth that tilts), and a
    shift; with ``tilt=False``, the stretch and the shift only (``a1 = a2 = 0``). The map leaves the two
    directions across ``u`` as they are, so a camera looking along ``u`` sees no change. Reweighted as
    :func:`robust_procrustes` (Cauchy's weight at ``scale``), so points an expression carries off count
    less. ``weights (N,)`` are non-negative; the weighted points must not all lie in one plane (with
    ``tilt=False``: not all at one depth along ``u``), or the frame's fit is singular and
    ``numpy.linalg.LinAlgError`` is raised for the whole batch. Inputs are trusted (checked by the caller).

    >>> rng = np.random.default_rng(1)
    >>> p = rng.normal(size=(20, 3))
    >>> tilted = p + [0, 0, 0.2] + np.outer(-0.03 * p[:, 2] + 0.05 * p[:, 1], [0, 0, 1])
    >>> M = robust_depth_affine(p, tilted[None], np.ones(20), np.array([[0, 0, 1.0]]), scale=0.1)
    >>> bool(np.allclose(tilted @ M[0, :3, :3].T + M[0, :3, 3], p))
    True
    """
    targets = np.asarray(targets, dtype=np.float64)
    w0 = np.asarray(weights, dtype=np.float64)
    u = np.asarray(directions, dtype=np.float64)
    centre = (w0 @ source) / w0.sum()
    helper = np.where(np.abs(u[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])  # not along u
    e1 = np.cross(u, helper)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(u, e1)
    axes = np.stack([u, e1, e2], axis=1)  # (T, 3, 3): rows u, e1, e2
    coords = np.matmul(targets - centre, axes.transpose(0, 2, 1))  # (T, N, 3): along u, e1, e2
    design = np.concatenate([coords, np.ones(coords.shape[:2] + (1,))], axis=2)  # (T, N, 4)
    used = [0, 1, 2, 3] if tilt else [0, 3]
    wanted = u @ (source - centre).T  # (T, N)
    w = np.broadcast_to(w0, wanted.shape)
    fit = np.zeros((len(targets), 4))
    columns = design[..., used]
    for round_ in range(rounds + 1):  # a plain fit, then ``rounds`` fits reweighted by the last one's misses
        weighted = columns * w[..., None]
        normal = np.matmul(columns.transpose(0, 2, 1), weighted)
        fit[:, used] = np.linalg.solve(normal, np.matmul(weighted.transpose(0, 2, 1), wanted[..., None]))[..., 0]
        if round_ == rounds:
            break
        moved = np.einsum("tnk,tk->tn", design, fit) - coords[..., 0]  # how far each point goes along u
        r = np.linalg.norm(targets + moved[..., None] * u[:, None, :] - source, axis=-1)
        w = w0 / (1.0 + (r / scale) ** 2)
    # the point x goes to x + u [(g - 1) u + a1 e1 + a2 e2] . (x - c) + b u
    row = fit[:, :3] - np.array([1.0, 0.0, 0.0])
    linear = np.einsum("ti,tj->tij", u, np.einsum("tk,tkj->tj", row, axes))
    M = np.tile(np.eye(4), (len(targets), 1, 1))
    M[:, :3, :3] += linear
    M[:, :3, 3] = fit[:, 3:] * u - np.einsum("tij,j->ti", linear, centre)
    return M
