"""Radial basis function interpolation: warps of space and of surfaces from control points.

A fitted RBF is linear in the values at its centres. :class:`RbfWarp` fits once and interpolates
values of any width (a displacement field ``(K, 3)``, or ``T`` frames at once ``(T, K, 3)``);
:meth:`RbfWarp.operator` returns the ``(N, K)`` matrix that maps centre values to values at fixed
points, so animating a mesh costs one matrix product per frame.

Kernels (``r`` is the distance after normalisation, see below):

==================  =========================================  ==============
kernel              basis                                      affine term
==================  =========================================  ==============
``multiquadric``    ``sqrt(r**2 + s_j**2)``, ``s_j`` = distance  no
                    from centre j to its nearest other centre
``thin_plate``      ``r**2 log r``                              yes
``cubic``           ``r**3``                                    yes
``linear``          ``r``                                       yes
``gaussian``        ``exp(-(r / s)**2)``, ``s`` = mean nearest  no
                    centre spacing
==================  =========================================  ==============

``multiquadric`` is the seed's kernel, solved as ``(H + smoothing I) w = values`` with smoothing
0.001 by default. The affine kernels reproduce any affine motion exactly and are solved with the
usual side conditions. Coordinates are centred on the centres' mean and divided by their RMS radius
before solving, so results do not depend on the model's units or position, and ``smoothing`` means
the same on a face in millimetres as in metres.

The same solver runs on other distances (geodesic distances on a surface, see
:mod:`faceanim.geometry.surface`) through :func:`rbf_operator_from_distances`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy import linalg
from scipy.spatial import cKDTree
from scipy.spatial.distance import cdist

from ..validation import as_array

__all__ = ["RbfWarp", "KERNELS", "rbf_operator_from_distances", "apply_operator"]

KERNELS = ("multiquadric", "thin_plate", "cubic", "linear", "gaussian")
_AFFINE = {"thin_plate", "cubic", "linear"}
_DEFAULT_SMOOTHING = {"multiquadric": 1e-3}
COINCIDENT_TOLERANCE = 1e-9  # relative to the centres' RMS radius


def _check_kernel(kernel: str, smoothing) -> float:
    if kernel not in KERNELS:
        raise ValueError(f"kernel must be one of {', '.join(KERNELS)}, got {kernel!r}")
    if smoothing is None:
        return _DEFAULT_SMOOTHING.get(kernel, 0.0)
    smoothing = float(smoothing)
    if not np.isfinite(smoothing) or smoothing < 0:
        raise ValueError(f"smoothing must be a finite number >= 0, got {smoothing}")
    return smoothing


def _basis(kernel: str, r: np.ndarray, shape: np.ndarray | float) -> np.ndarray:
    """Kernel values for distances ``r (..., K)``; ``shape`` is per centre ``(K,)`` or a scalar."""
    if kernel == "multiquadric":
        return np.sqrt(r * r + shape * shape)
    if kernel == "thin_plate":
        with np.errstate(divide="ignore", invalid="ignore"):
            out = r * r * np.log(r)
        out[r == 0] = 0.0
        return out
    if kernel == "cubic":
        return r * r * r
    if kernel == "linear":
        return r.copy()
    return np.exp(-((r / shape) ** 2))


def _shape_parameter(kernel: str, centre_distances: np.ndarray):
    """Per-centre (multiquadric) or global (gaussian) shape from the spacing of the centres."""
    if kernel not in ("multiquadric", "gaussian"):
        return 1.0
    d = centre_distances.copy()
    np.fill_diagonal(d, np.inf)
    nearest = d.min(axis=1)
    return nearest if kernel == "multiquadric" else float(nearest.mean())


@dataclass(frozen=True, eq=False)
class _Solver:
    """The factorised RBF system of one set of centres."""

    kernel: str
    shape: np.ndarray | float
    lu: tuple
    n_centres: int
    affine: bool

    @classmethod
    def fit(cls, kernel, centre_distances, centre_poly, smoothing):
        K = len(centre_distances)
        shape = _shape_parameter(kernel, centre_distances)
        phi = _basis(kernel, centre_distances, shape)
        affine = kernel in _AFFINE
        if affine:
            P = centre_poly
            A = np.block([[phi + smoothing * np.eye(K), P], [P.T, np.zeros((P.shape[1], P.shape[1]))]])
        else:
            A = phi + smoothing * np.eye(K)
        with warnings.catch_warnings():  # a singular system gets the clearer error below
            warnings.simplefilter("ignore", linalg.LinAlgWarning)
            lu = linalg.lu_factor(A, check_finite=False)
        if not np.all(np.isfinite(lu[0])) or np.min(np.abs(np.diag(lu[0]))) < 1e-13 * np.abs(lu[0]).max():
            raise ValueError(
                f"the {kernel} RBF system for these {K} centres is singular; "
                + ("the centres may lie in a plane or line, which leaves the affine term undetermined"
                   if affine else "try a smoothing > 0"))
        return cls(kernel, shape, lu, K, affine)

    def coefficients(self, values: np.ndarray) -> np.ndarray:
        """Weights ``(K [+ D + 1], C*)`` for centre values ``(K, C*)``."""
        rhs = values
        if self.affine:
            extra = self.lu[0].shape[0] - self.n_centres
            rhs = np.concatenate([values, np.zeros((extra,) + values.shape[1:])], axis=0)
        return linalg.lu_solve(self.lu, rhs.reshape(len(rhs), -1), check_finite=False).reshape(rhs.shape)

    def design(self, point_distances: np.ndarray, point_poly: np.ndarray) -> np.ndarray:
        """Rows ``(N, K [+ D + 1])`` evaluating the interpolant at points."""
        phi = _basis(self.kernel, point_distances, self.shape)
        return np.hstack([phi, point_poly]) if self.affine else phi

    def operator(self, B: np.ndarray) -> np.ndarray:
        """``(N, K)`` matrix mapping centre values to the values at the points of design rows ``B``."""
        # B A^-1 = (A^-T B^T)^T; only the columns that multiply the centre values are kept.
        return linalg.lu_solve(self.lu, B.T, trans=1, check_finite=False).T[:, : self.n_centres].copy()


def _coincident_pairs(centres: np.ndarray, tolerance: float) -> np.ndarray:
    return np.array(sorted(cKDTree(centres).query_pairs(tolerance)), dtype=np.int64).reshape(-1, 2)


def _normaliser(centres: np.ndarray):
    origin = centres.mean(axis=0)
    radius = np.sqrt(((centres - origin) ** 2).sum(axis=1).mean())
    return origin, radius if radius > 0 else 1.0


class RbfWarp:
    """An RBF interpolant fitted to values at centres, evaluated anywhere.

    Parameters
    ----------
    centres : (K, D) float64
        Control-point positions (D is 2 or 3; any units).
    values : (K, C) or (T, K, C) float64
        Values at the centres: displacements ``(K, 3)``, or ``T`` frames of them.
    kernel : str
        One of :data:`KERNELS` (see the module text); ``thin_plate`` by default.
    smoothing : float, optional
        Added to the kernel matrix's diagonal (in normalised units). 0.001 for ``multiquadric``
        (the seed's gamma), else 0 (exact interpolation).

    Raises
    ------
    ValueError
        Coincident centres (their indices are named), too few centres for the affine term, or a
        singular system.

    Examples
    --------
    >>> c = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]])
    >>> warp = RbfWarp(c, 2 * c + 1)           # an affine motion ...
    >>> np.allclose(warp([[0.3, 0.2, 0.9]]), [[1.6, 1.4, 2.8]])  # ... is reproduced exactly
    True
    """

    def __init__(self, centres, values, *, kernel: str = "thin_plate", smoothing: float | None = None):
        smoothing = _check_kernel(kernel, smoothing)
        centres = as_array(centres, "centres", shape=("K", None), min_length=1)
        if centres.shape[1] not in (2, 3):
            raise ValueError(f"centres must have shape (K, 2) or (K, 3), got {centres.shape}")
        K, D = centres.shape
        values = as_array(values, "values")
        if values.ndim not in (2, 3) or values.shape[-2] != K:
            raise ValueError(f"values must have shape ({K}, C) or (T, {K}, C) to match centres, got {values.shape}")
        if kernel in _AFFINE and K < D + 1:
            raise ValueError(f"kernel {kernel!r} needs at least {D + 1} centres for its affine term, got {K}")
        self._origin, self._radius = _normaliser(centres)
        self.centres = centres
        self.kernel = kernel
        unit = (centres - self._origin) / self._radius
        pairs = _coincident_pairs(unit, COINCIDENT_TOLERANCE)
        if len(pairs):
            shown = ", ".join(f"{a} and {b}" for a, b in pairs[:5])
            raise ValueError(f"centres must be distinct; coincident centres: {shown}"
                             + (f" (and {len(pairs) - 5} more pairs)" if len(pairs) > 5 else ""))
        self._unit_centres = unit
        distances = cdist(unit, unit)
        self._solver = _Solver.fit(kernel, distances, _poly(unit), smoothing)
        moved = np.moveaxis(values, -2, 0)  # (K, [T,] C)
        self._coefficients = self._solver.coefficients(moved)
        self._value_shape = values.shape

    def _design(self, points: np.ndarray) -> np.ndarray:
        points = as_array(points, "points", shape=("N", self.centres.shape[1]))
        unit = (points - self._origin) / self._radius
        # Exact differences, not |a|^2 + |b|^2 - 2 a.b: that cancels catastrophically near a centre
        # (the linear kernel then missed its own centres by 2e-7).
        return self._solver.design(cdist(unit, self._unit_centres), _poly(unit))

    def __call__(self, points) -> np.ndarray:
        """Interpolated values at ``points (N, D)``: ``(N, C)``, or ``(T, N, C)`` for framed values."""
        B = self._design(points)
        coef = self._coefficients
        out = B @ coef.reshape(len(coef), -1)
        out = out.reshape((len(B),) + coef.shape[1:])
        return np.moveaxis(out, 0, -2)

    def operator(self, points) -> np.ndarray:
        """``(N, K)`` matrix ``M`` with ``M @ values == self(points)`` for any values at these centres."""
        return self._solver.operator(self._design(points))


def _poly(unit_points: np.ndarray) -> np.ndarray:
    return np.hstack([np.ones((len(unit_points), 1)), unit_points])


def rbf_operator_from_distances(centre_distances, point_distances, *, kernel: str = "thin_plate",
                                smoothing: float | None = None, centre_positions=None,
                                point_positions=None) -> np.ndarray:
    """``(N, K)`` RBF operator built from given distances (for example geodesic ones).

    Parameters
    ----------
    centre_distances : (K, K) float64
        Distances between centres.
    point_distances : (N, K) float64
        Distances from each evaluation point to each centre.
    kernel, smoothing
        As for :class:`RbfWarp`. Distances are divided by the RMS of ``centre_distances`` first.
    centre_positions, point_positions : (K, D), (N, D) float64
        Positions for the affine term; required by the affine kernels.
    """
    smoothing = _check_kernel(kernel, smoothing)
    cc = as_array(centre_distances, "centre_distances", shape=("K", "K"), min_length=1)
    K = len(cc)
    pc = as_array(point_distances, "point_distances", shape=("N", K))
    scale = np.sqrt((cc ** 2).mean()) or 1.0
    cp = pp = np.zeros((0, 0))
    if kernel in _AFFINE:
        if centre_positions is None or point_positions is None:
            raise ValueError(f"kernel {kernel!r} needs centre_positions and point_positions for its affine term")
        c = as_array(centre_positions, "centre_positions", shape=(K, None))
        p = as_array(point_positions, "point_positions", shape=(len(pc), c.shape[1]))
        origin, radius = _normaliser(c)
        cp, pp = _poly((c - origin) / radius), _poly((p - origin) / radius)
    solver = _Solver.fit(kernel, cc / scale, cp, smoothing)
    return solver.operator(solver.design(pc / scale, pp))


def apply_operator(operator: np.ndarray, values) -> np.ndarray:
    """Apply an ``(N, K)`` operator to ``(K, C)`` or ``(T, K, C)`` values in one matrix product.

    >>> M = np.array([[0.5, 0.5]])
    >>> apply_operator(M, np.array([[[0., 2.], [2., 0.]]]))
    array([[[1., 1.]]])
    """
    values = np.asarray(values, dtype=np.float64)
    if values.ndim == 2:
        return operator @ values
    T, K, C = values.shape
    flat = operator @ values.transpose(1, 0, 2).reshape(K, T * C)  # one GEMM for all frames
    return flat.reshape(len(operator), T, C).transpose(1, 0, 2)
