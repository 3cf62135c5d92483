"""The one place where arrays entering faceanim are checked and converted.

Every public function that takes an array passes it through :func:`as_array`, so error messages
look the same everywhere: they name the argument, what was expected and what arrived. With
``frozen=True`` it also hands back an array nobody else can write: the vocabulary types (``Mesh``,
``Target``, ``Track``, ``Motion``) keep their arrays that way, so what they cache from them cannot go
stale.
"""

from __future__ import annotations

import numpy as np

__all__ = ["as_array", "as_index_array", "restore_frozen"]


def _shape_text(shape) -> str:
    """A shape as Python writes a tuple: ``(V, 3)``, ``(T,)``."""
    return "(" + ", ".join(str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"


def as_array(value, name: str, *, shape: tuple = (), dtype=np.float64, finite: bool = True,
             min_length: int = 0, frozen: bool = False) -> np.ndarray:
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
    frozen : bool
        Return a read-only array that shares its memory with nothing the caller can write:
        ``value`` itself when it already is one (an owned, read-only, C-contiguous array of
        ``dtype``), the converted array when converting made a new one, else a read-only copy.

    Returns
    -------
    numpy.ndarray
        A C-contiguous array of ``dtype``. A bool ``dtype`` accepts only bools and the numbers 0
        and 1 (0.5 is no truth value).

    Examples
    --------
    >>> as_array([[0, 1, 2]], "vertices", shape=("V", 3)).dtype
    dtype('float64')
    >>> as_array([[0, 1]], "vertices", shape=("V", 3))
    Traceback (most recent call last):
    ...
    ValueError: vertices must have shape (V, 3), got (1, 2)
    >>> mine = np.zeros((2, 3))
    >>> kept = as_array(mine, "vertices", frozen=True)
    >>> kept.flags.writeable, np.shares_memory(kept, mine)
    (False, False)
    >>> as_array(kept, "vertices", frozen=True) is kept  # already frozen: taken, not copied
    True
    """
    if np.dtype(dtype) == np.bool_:
        _check_truth_values(value, name)
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
    return _frozen(arr, value) if frozen else arr


def _check_truth_values(value, name: str) -> None:
    """Refuse numbers other than 0 and 1 where booleans are wanted (numpy would call 0.5 True)."""
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError):
        return  # the conversion itself reports it
    if raw.dtype == np.bool_ or not (np.issubdtype(raw.dtype, np.number) and raw.size):
        return
    bad = np.flatnonzero((raw != 0) & (raw != 1))
    if bad.size:
        pos = tuple(int(p) for p in np.unravel_index(bad[0], raw.shape))
        raise ValueError(f"{name} must hold booleans (or 0 and 1), got {raw.flat[bad[0]]} at index {pos}")


def _frozen(arr: np.ndarray, given) -> np.ndarray:
    """``arr`` (``given`` converted) read-only, copied unless no one else can reach its memory."""
    if arr.flags.owndata and not arr.flags.writeable:
        return arr  # already frozen by its owner (another vocabulary type, a cached table)
    made_here = arr is not given and arr.flags.owndata and isinstance(given, (np.ndarray, list, tuple))
    if not made_here:
        arr = arr.copy()
    arr.flags.writeable = False
    return arr


def restore_frozen(obj, state: dict) -> None:
    """``__setstate__`` for the frozen vocabulary types: pickling and :func:`copy.deepcopy` hand
    back writable arrays (numpy does not keep the flag), fresh and held by nobody else, so they are
    marked read-only again."""
    for value in state.values():
        if isinstance(value, np.ndarray):
            value.flags.writeable = False
    obj.__dict__.update(state)


def as_index_array(value, name: str, *, upper: int, shape: tuple = ("N",), frozen: bool = False) -> np.ndarray:
    """Convert ``value`` to int64 indices and check they lie in ``[0, upper)`` (``frozen`` as for
    :func:`as_array`).

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
    return _frozen(arr, value) if frozen else arr
