"""The MPEG-4 face tables (ISO/IEC 14496-2 Table C-1 and Figure 2) as package data, read once.

Each table is parsed once and shared, so it is frozen: tuples, and read-only arrays.

The CSV files in ``data/`` are copies of ``shared/mpeg4/faps.csv`` and ``fdp_points.csv``; their
README there gives the sources and where sources disagree. Axes follow MPEG-4: +X is the face's own
left, +Y up, +Z out of the face.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from functools import cache
from importlib import resources

import numpy as np

from ..validation import as_array

__all__ = ["FapTable", "FeaturePointTable", "fap_table", "feature_points", "FAP_COUNT"]

FAP_COUNT = 68
_AXES = {"+X": (1, 0, 0), "-X": (-1, 0, 0), "+Y": (0, 1, 0), "-Y": (0, -1, 0), "+Z": (0, 0, 1), "-Z": (0, 0, -1)}


def _rows(name: str) -> list[dict[str, str]]:
    with resources.files(__package__).joinpath("data", name).open(encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def _number(text: str) -> float:
    return float(text) if text.strip() else np.nan


@dataclass(frozen=True, eq=False)
class FapTable:
    """The 68 FAPs; row ``i`` is FAP number ``i + 1``.

    Attributes
    ----------
    names : tuple of str
        Canonical names (``open_jaw``, ``stretch_l_cornerlip``, ...).
    feature_points : tuple of tuple of str
        The feature point(s) each FAP moves (empty for FAPs the table gives none).
    units : tuple of str
        ``MNS``, ``MW``, ``ENS``, ``ES``, ``IRISD``, ``AU`` (angle, 1e-5 rad) or ``na``.
    bidirectional : (68,) bool
    direction : (68, 3) float64
        Unit vector of positive motion for translational FAPs in MPEG-4 axes; zero for rotations
        and the high-level FAPs 1 and 2.
    quant_step : (68,) float64
        Quantiser step QP.
    i_min, i_max, p_min, p_max : (68,) float64
        I- and P-frame bounds as printed, in quantised units (NaN where none is printed); the range in
        FAPU is the bound times ``quant_step`` (see ``shared/mpeg4/fapu.md`` section 5).

    The arrays are read-only: the table is shared by every caller of :func:`fap_table`.
    """

    names: tuple[str, ...]
    feature_points: tuple[tuple[str, ...], ...]
    units: tuple[str, ...]
    bidirectional: np.ndarray
    direction: np.ndarray
    quant_step: np.ndarray
    i_min: np.ndarray
    i_max: np.ndarray
    p_min: np.ndarray
    p_max: np.ndarray

    def __post_init__(self):
        for name in ("bidirectional", "direction", "quant_step", "i_min", "i_max", "p_min", "p_max"):
            value = getattr(self, name)
            object.__setattr__(self, name, as_array(value, name, dtype=value.dtype, finite=False, frozen=True))

    def number(self, name: str) -> int:
        """FAP number (1-68) of a name.

        >>> fap_table().number("open_jaw")
        3
        """
        try:
            return self.names.index(name) + 1
        except ValueError:
            raise KeyError(f"unknown FAP name {name!r}") from None


@cache
def fap_table() -> FapTable:
    """The FAP table, parsed once."""
    rows = sorted(_rows("faps.csv"), key=lambda r: int(r["number"]))
    assert [int(r["number"]) for r in rows] == list(range(1, FAP_COUNT + 1))
    direction = np.array([_AXES.get(r["axis"], (0, 0, 0)) for r in rows], dtype=np.float64)
    return FapTable(
        names=tuple(r["name"] for r in rows),
        feature_points=tuple(tuple(p for p in r["fdp"].split(";") if p != "na") for r in rows),
        units=tuple(r["unit"] for r in rows),
        bidirectional=np.array([r["uni_bi"] == "B" for r in rows]),
        direction=direction,
        quant_step=np.array([_number(r["quant_step_QP"]) for r in rows]),
        i_min=np.array([_number(r["i_min"]) for r in rows]),
        i_max=np.array([_number(r["i_max"]) for r in rows]),
        p_min=np.array([_number(r["p_min"]) for r in rows]),
        p_max=np.array([_number(r["p_max"]) for r in rows]),
    )


@dataclass(frozen=True, eq=False)
class FeaturePointTable:
    """The 84 MPEG-4 feature points (FDP), in the order of ``fdp_points.csv``.

    ``names`` are ``"group.index"`` strings (``"8.3"``); ``sides`` are ``left``, ``right``,
    ``middle`` or ``unknown`` (always the face's own side); ``moved_by`` lists FAP numbers.
    """

    names: tuple[str, ...]
    descriptions: tuple[str, ...]
    sides: tuple[str, ...]
    moved_by: tuple[tuple[int, ...], ...]

    def index(self, name: str) -> int:
        """Row of a feature point name.

        >>> feature_points().index("2.1")
        0
        """
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"unknown MPEG-4 feature point {name!r}") from None


@cache
def feature_points() -> FeaturePointTable:
    """The feature-point table, parsed once."""
    rows = _rows("fdp_points.csv")
    return FeaturePointTable(
        names=tuple(r["fdp"] for r in rows),
        descriptions=tuple(r["description"] for r in rows),
        sides=tuple(r["side"] for r in rows),
        moved_by=tuple(tuple(int(x) for x in r["moved_by_faps"].split(";") if x) for r in rows),
    )
