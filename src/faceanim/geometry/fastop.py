"""A linear deformation operator applied in single precision, with its error bounds stated.

An RBF or surface-interpolation operator ``M (N, K)`` maps control values to ``N`` points; ``T``
frames cost one ``(N, K) x (K, 3T)`` product, bound by the machine's flops. float32 halves both the
memory traffic and the time per flop. (A low-rank factorisation does not help: an operator that
interpolates its ``K`` controls exactly is the identity on them, so its singular values stay of
order 1 down to the last; the ICT head's thin-plate operator keeps 1.2 of 120 at rank 468.)

Error of one output coordinate ``y_i = M_i . x`` for control values with ``|x_k| <= m``
(``u = 2**-24``, ``r_i = ||M_i||_1``; Higham, *Accuracy and Stability of Numerical Algorithms*, 3.1
and 3.5; Higham & Mary, *A new approach to probabilistic rounding error analysis*, SISC 2019):

* worst case, guaranteed: ``(gamma_K + 2u) r_i m`` with ``gamma_K = K u / (1 - K u)``;
* probabilistic: ``(lambda sqrt(K) u + 2u) r_i m`` with ``lambda = 6``, which holds for each output
  with probability at least ``1 - 2K exp(-18)`` when rounding errors are independent and of mean
  zero (the model float32 GEMM follows closely).

:attr:`Float32Operator.worst_case` and :attr:`Float32Operator.probable` are those factors at the
largest ``r_i``, relative to ``m``, so they mean the same in centimetres, metres or millimetres.
"""

from __future__ import annotations

import numpy as np

from ..validation import as_array

__all__ = ["Float32Operator"]

_U32 = 2.0 ** -24
_LAMBDA = 6.0


class Float32Operator:
    """``M (N, K)`` stored and applied in float32, returning float64.

    Parameters
    ----------
    matrix : (N, K) float64

    Attributes
    ----------
    worst_case, probable : float
        Error factors (see the module text): ``|self(x) - matrix @ x| <= factor * max|x|``.
    row_norms : (N,) float64
        ``||M_i||_1``; the bounds of output ``i`` scale with it.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> M = rng.uniform(-1, 1, size=(50, 40)) / 40
    >>> op = Float32Operator(M)
    >>> x = rng.uniform(-2, 2, size=(40, 3))
    >>> bool(np.abs(op(x) - M @ x).max() <= op.worst_case * 2)
    True
    """

    def __init__(self, matrix):
        M = as_array(matrix, "matrix", shape=("N", "K"), min_length=1)
        N, K = M.shape
        self.shape = (N, K)
        self.row_norms = np.abs(M).sum(axis=1)
        norm = float(self.row_norms.max())
        self.worst_case = (K * _U32 / (1 - K * _U32) + 2 * _U32) * norm
        self.probable = (_LAMBDA * np.sqrt(K) * _U32 + 2 * _U32) * norm
        self._matrix = np.ascontiguousarray(M, dtype=np.float32)

    def __call__(self, values) -> np.ndarray:
        """``matrix @ values`` for ``(K, C)`` or ``(T, K, C)`` values, as float64 ``(N, C)`` / ``(T, N, C)``."""
        values = np.asarray(values)
        K = self.shape[1]
        if values.ndim not in (2, 3) or values.shape[-2] != K:
            raise ValueError(f"values must have shape ({K}, C) or (T, {K}, C), got {values.shape}")
        if values.ndim == 2:
            return (self._matrix @ values.astype(np.float32)).astype(np.float64)
        T, _, C = values.shape
        flat = np.ascontiguousarray(values.transpose(1, 0, 2).reshape(K, T * C), dtype=np.float32)
        out = self._matrix @ flat
        return out.reshape(self.shape[0], T, C).transpose(1, 0, 2).astype(np.float64)
