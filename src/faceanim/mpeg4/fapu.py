"""Face Animation Parameter Units: the face's own yardsticks, measured on its neutral pose."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..validation import as_array
from .tables import fap_table

__all__ = ["Fapu", "fapu_from_points", "metres_per_unit", "ANGLE_UNIT"]

ANGLE_UNIT = 1e-5  # radians per AU
HUMAN_ES0 = 0.063  # metres: a typical adult's eye separation (pupil to pupil)
_UNITS = {1.0: "metre", 0.1: "decimetre", 0.01: "centimetre", 0.001: "millimetre"}


@dataclass(frozen=True)
class Fapu:
    """The five distances of a neutral face (model units) behind the FAPUs.

    A translational FAP value ``f`` in unit ``MNS`` moves its point by ``f * mns0 / 1024``; see
    :meth:`scale`.
    """

    irisd0: float
    es0: float
    ens0: float
    mns0: float
    mw0: float

    def __post_init__(self):
        for name in ("irisd0", "es0", "ens0", "mns0", "mw0"):
            value = getattr(self, name)
            if not np.isfinite(value) or value <= 0:
                raise ValueError(f"FAPU {name} must be a positive distance, got {value}")

    def unit(self, name: str) -> float:
        """Model units (or radians for ``AU``) per one FAP unit of ``name``."""
        if name == "AU":
            return ANGLE_UNIT
        if name == "na":
            return float("nan")
        try:
            return getattr(self, name.lower() + "0") / 1024.0
        except AttributeError:
            raise KeyError(f"unknown FAPU {name!r}") from None

    def scale(self) -> np.ndarray:
        """(68,) model units (radians for angles, NaN for FAPs 1-2) per unit of each FAP.

        >>> f = Fapu(irisd0=1.0, es0=6.0, ens0=4.0, mns0=2.048, mw0=5.0)
        >>> float(f.scale()[2])  # open_jaw is in MNS
        0.002
        """
        return np.array([self.unit(u) for u in fap_table().units])


def fapu_from_points(points: Mapping[str, np.ndarray]) -> Fapu:
    """Measure FAPU from neutral feature-point positions in MPEG-4 axes (+X face's left, +Y up).

    Uses the definitions of ISO/IEC 14496-2 Table 1: IRISD0 = 3.1.y - 3.3.y (averaged with
    3.2.y - 3.4.y), ES0 = 3.5.x - 3.6.x, ENS0 = 3.5.y - 9.15.y (pupils averaged), MNS0 =
    9.15.y - 2.2.y, MW0 = 8.3.x - 8.4.x.

    Parameters
    ----------
    points : mapping of str to (3,) array
        Feature-point name to position; must hold 2.2, 3.1-3.6, 8.3, 8.4 and 9.15.

    Raises
    ------
    KeyError
        A needed point is missing (all missing ones are named).
    ValueError
        A distance is not positive: the face is not upright and facing +Z, or points are swapped.
    """
    needed = ("2.2", "3.1", "3.2", "3.3", "3.4", "3.5", "3.6", "8.3", "8.4", "9.15")
    missing = [n for n in needed if n not in points]
    if missing:
        raise KeyError(f"FAPU needs feature points {', '.join(missing)}")
    p = {n: as_array(points[n], f"point {n}", shape=(3,)) for n in needed}
    pupils_y = 0.5 * (p["3.5"][1] + p["3.6"][1])
    return Fapu(
        irisd0=0.5 * ((p["3.1"][1] - p["3.3"][1]) + (p["3.2"][1] - p["3.4"][1])),
        es0=p["3.5"][0] - p["3.6"][0],
        ens0=pupils_y - p["9.15"][1],
        mns0=p["9.15"][1] - p["2.2"][1],
        mw0=p["8.3"][0] - p["8.4"][0],
    )


def metres_per_unit(fapu: Fapu) -> float:
    """Metres per model unit of a face, told from its size: the power of ten among the metre, decimetre,
    centimetre and millimetre that makes its eye separation ES0 human.

    A person's eyes sit about 6.3 cm apart; each candidate unit accepts an ES0 within a factor of
    sqrt(10) of that (2 to 20 cm), so exactly one fits any ES0 from 0.02 to 200 model units. The
    decimetre is there for faces normalised to a height of one or two units. A face whose eyes would be
    under 2 cm apart even in metres, or over 20 cm apart even in millimetres, is refused.

    Parameters
    ----------
    fapu : Fapu
        The face's FAPU (model units); only ``es0`` is used.

    Returns
    -------
    float
        1.0, 0.1, 0.01 or 0.001.

    Raises
    ------
    ValueError
        ES0 fits none of the units (the message gives ES0 and what it would mean).

    Examples
    --------
    >>> metres_per_unit(Fapu(irisd0=1.0, es0=6.8, ens0=4.8, mns0=1.6, mw0=6.9))  # a face in centimetres
    0.01
    >>> metres_per_unit(Fapu(irisd0=10.0, es0=62.0, ens0=48.0, mns0=16.0, mw0=50.0))  # in millimetres
    0.001
    """
    es0 = float(fapu.es0)
    unit = 10.0 ** -round(np.log10(es0 / HUMAN_ES0))  # the nearest power of ten, in log
    unit = min(_UNITS, key=lambda u: abs(u - unit))
    if not HUMAN_ES0 / np.sqrt(10) <= es0 * unit <= HUMAN_ES0 * np.sqrt(10):
        raise ValueError(f"FAPU es0 (eye separation) of {es0:g} model units is no human face in metres, "
                         f"decimetres, centimetres or millimetres ({es0 * unit * 100:g} cm as {_UNITS[unit]}s; "
                         "expected 2 to 20 cm)")
    return unit
