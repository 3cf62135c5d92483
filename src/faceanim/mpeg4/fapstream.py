"""`FapStream`: the 68 MPEG-4 FAPs per frame, in FAPU, with the mask of which are present."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..validation import as_array
from .tables import FAP_COUNT, fap_table

__all__ = ["curve_columns", "FapStream", "fap_ranges", "held"]


@dataclass(frozen=True, eq=False)
class FapStream:
    """A FAP animation.

    Parameters
    ----------
    values : (T, 68) float64
        Low-level FAP values (FAPs 3-68) in their own units (``shared/mpeg4/faps.csv``); column
        ``i`` is FAP ``i + 1``. Columns 0 and 1 (the high-level FAPs) and absent FAPs hold 0.
    mask : (T, 68) bool
        Which FAPs each frame carries.
    fps : float
        Frames per second.
    frame_numbers : (T,) int64, optional
        As written in a ``.fap`` file; default ``0 .. T-1``.
    visemes : (T, 4) int64, optional
        FAP 1 fields (viseme_select1, viseme_select2, viseme_blend, viseme_def) where masked in.
    expressions : (T, 6) int64, optional
        FAP 2 fields (expression_select1, expression_intensity1, expression_select2,
        expression_intensity2, init_face, expression_def) where masked in.
    name : str
        Sequence name (one token, no whitespace).
    """

    values: np.ndarray
    mask: np.ndarray
    fps: float
    frame_numbers: np.ndarray | None = None
    visemes: np.ndarray | None = None
    expressions: np.ndarray | None = None
    name: str = "faceanim"

    def __post_init__(self):
        values = as_array(self.values, "values", shape=("T", FAP_COUNT))
        T = len(values)
        mask = np.asarray(self.mask)
        if mask.shape != (T, FAP_COUNT) or mask.dtype != bool:
            raise ValueError(f"mask must be a bool array of shape ({T}, {FAP_COUNT}), got {mask.dtype} {mask.shape}")
        if not np.isfinite(self.fps) or self.fps <= 0:
            raise ValueError(f"fps must be a positive number, got {self.fps}")
        if not self.name or any(c.isspace() for c in self.name):
            raise ValueError(f"name must be one token without whitespace, got {self.name!r}")
        frames = np.arange(T) if self.frame_numbers is None else np.asarray(self.frame_numbers, dtype=np.int64)
        if frames.shape != (T,):
            raise ValueError(f"frame_numbers must have shape ({T},), got {frames.shape}")
        for field, width, column in (("visemes", 4, 0), ("expressions", 6, 1)):
            extra = getattr(self, field)
            if extra is None:
                if mask[:, column].any():
                    raise ValueError(f"mask sets FAP {column + 1} but no {field} are given")
                continue
            extra = np.asarray(extra, dtype=np.int64)
            if extra.shape != (T, width):
                raise ValueError(f"{field} must have shape ({T}, {width}), got {extra.shape}")
            object.__setattr__(self, field, extra)
        values = np.where(mask, values, 0.0)
        values[:, :2] = 0.0
        object.__setattr__(self, "values", values)
        object.__setattr__(self, "mask", mask)
        object.__setattr__(self, "frame_numbers", frames)
        object.__setattr__(self, "fps", float(self.fps))

    def __len__(self) -> int:
        return len(self.values)

    def out_of_range(self) -> np.ndarray:
        """(T, 68) bool: present values outside the I-frame range of Table C-1 (see :func:`fap_ranges`)."""
        low, high = fap_ranges()
        return self.mask & ((self.values < low) | (self.values > high))


def held(stream: FapStream) -> np.ndarray:
    """(T, 68) values where a FAP absent from a frame keeps its last value (0 before its first), as an
    MPEG-4 decoder does for FAPs a frame does not carry."""
    values = np.where(stream.mask, stream.values, np.nan)
    values[0] = np.where(np.isnan(values[0]), 0.0, values[0])
    for t in range(1, len(values)):
        missing = np.isnan(values[t])
        values[t, missing] = values[t - 1, missing]
    return values


def fap_ranges() -> tuple[np.ndarray, np.ndarray]:
    """(68,) lowest and highest legal value of each FAP, in its own units.

    Table C-1 prints the I-frame bounds in quantised units; a value in FAPU is the bound times the
    FAP's quantiser step (``shared/mpeg4/fapu.md`` section 5). Unidirectional FAPs, for which the table
    prints only a maximum, get 0 as their minimum. FAPs 1 and 2 (high-level) get +-inf.

    >>> low, high = fap_ranges()
    >>> float(low[2]), float(high[2])  # open_jaw: unidirectional, 1080 x QP 4
    (0.0, 4320.0)
    """
    table = fap_table()
    high = table.i_max * table.quant_step
    low = np.where(np.isnan(table.i_min), 0.0, table.i_min * table.quant_step)
    high[:2], low[:2] = np.inf, -np.inf
    return low, high


def curve_columns(stream: FapStream) -> np.ndarray:
    """Columns of the low-level FAPs (3-68) that any frame carries: the FAPs that are curves over time
    (1 and 2, visemes and expressions, are selections, not values)."""
    present = np.flatnonzero(stream.mask.any(axis=0))
    return present[present >= 2]
