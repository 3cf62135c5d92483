"""The one place where arrays entering faceanim are checked and converted.

Every public function that takes an array passes it through :func:`as_array`, so error messages
look the same everywhere: they name the argument, what was expected and what arrived.
"""

from __future__ import annotations

import numpy as np

__all__ = ["as_array", "as_index_array"]


def _shape_text(shape) -> str:
    return "(" + ", ".join(str(s) for s in shape) + ")"


def as_array(value, name: str, *, shape: tuple = (), dtype=np.float64, finite: bool = True,
             min_length: int = 0) -> np.ndarray:
    """Convert ``value`` to an array of ``dtype`` and check its shape.

    Parameters
    ----------
    value : array_like
        What the caller passed.
    name : str
        The argument's name, used in error messages.
    shape : tuple of (int or str or None)
        Expected shape. An int fixes that axis; a str (``"V"``) or None lets it vary. Empty means
        any shape.
    dtype : numpy dtype
        The dtype to convert to.
    finite : bool
        Reject NaN and infinity (float dtypes only).
    min_length : int
        The least size of the first axis.

    Returns
    -------
    numpy.ndarray
        A C-contiguous array of ``dtype``.

    Examples
    --------
    >>> as_array([[0, 1, 2]], "vertices", shape=("V", 3)).dtype
    dtype('float64')
    >>> as_array([[0, 1]], "vertices", shape=("V", 3))
    Traceback (most recent call last):
    ...
    ValueError: vertices must have shape (V, 3), got (1, 2)
    """
    try:
        arr = np.ascontiguousarray(value, dtype=dtype)
    except (TypeError, ValueError) as exc:
        wanted = np.dtype(dtype).name
        raise TypeError(f"{name} must be an array of {wanted}, got {type(value).__name__}: {exc}") from None
    if shape:
        ok = arr.ndim == len(shape) and all(
            not isinstance(want, int) or got == want for want, got in zip(shape, arr.shape, strict=True))
        if not ok:
            raise ValueError(f"{name} must have shape {_shape_text(shape)}, got {_shape_text(arr.shape)}")
    if min_length and (arr.ndim == 0 or arr.shape[0] < min_length):
        got = 0 if arr.ndim == 0 else arr.shape[0]
        raise ValueError(f"{name} must have at least {min_length} entries, got {got}")
    if finite and np.issubdtype(arr.dtype, np.floating) and not np.isfinite(arr).all():
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise ValueError(f"{name} must be finite, got {arr[tuple(bad)]} at index {tuple(int(i) for i in bad)}")
    return arr


def as_index_array(value, name: str, *, upper: int, shape: tuple = ("N",)) -> np.ndarray:
    """Convert ``value`` to int64 indices and check they lie in ``[0, upper)``.

    Examples
    --------
    >>> as_index_array([0, 2], "ids", upper=3)
    array([0, 2])
    >>> as_index_array([0, 3], "ids", upper=3)
    Traceback (most recent call last):
    ...
    ValueError: ids must lie in [0, 3), got 3 at position 1
    """
    raw = np.asarray(value)
    if raw.size and not np.issubdtype(raw.dtype, np.integer):
        if not (np.issubdtype(raw.dtype, np.floating) and np.all(np.mod(raw, 1) == 0)):
            raise TypeError(f"{name} must hold integer indices, got dtype {raw.dtype}")
    arr = as_array(raw, name, shape=shape, dtype=np.int64, finite=False)
    bad = np.flatnonzero((arr < 0) | (arr >= upper))
    if bad.size:
        pos = np.unravel_index(bad[0], arr.shape)
        where = pos[0] if len(pos) == 1 else tuple(int(p) for p in pos)
        raise ValueError(f"{name} must lie in [0, {upper}), got {arr.flat[bad[0]]} at position {where}")
    return arr
