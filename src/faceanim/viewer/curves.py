"""FAP curves in the form the viewer page draws them: grouped as ``faceanim plot`` groups them."""

from __future__ import annotations

from pathlib import PureWindowsPath

import numpy as np

from ..export.plots import MOST_ACTIVE, fap_panels
from ..mpeg4.fapstream import FapStream

__all__ = ["fap_curves"]


def _json_curve(curve: np.ndarray) -> list:
    """A curve as JSON numbers, 4 decimals, frames without a value ``null`` (a gap in the line)."""
    return [None if np.isnan(v) else v for v in np.round(curve, 4).tolist()]


def fap_curves(stream: FapStream, *, name: str | None = None) -> dict:
    """The page's curves of ``stream``: ``{title, fps, times, groups}``; ``name`` (the file's, say)
    goes in the title, else the stream's own.

    ``times`` (T,) in seconds; ``groups`` one per panel of :func:`~faceanim.export.plots.fap_panels`
    (jaw, lips, brows, lids, eyes, cheeks & nose, head, other), each ``{name, unit, note, curves}``
    with its curves most active first, each ``{label, values, named}``: the first
    :data:`~faceanim.export.plots.MOST_ACTIVE` are named, the rest drawn grey, as ``note`` says
    ("6 most active of 22"). FAPs are in multiples of their FAPU, angles in degrees, frames without
    the FAP ``null``.
    """
    times, panels = fap_panels(stream)
    if name is None:
        name = PureWindowsPath(stream.name).name or stream.name  # .fap names are often Windows paths
    groups = [{"name": panel.name, "unit": panel.unit, "note": panel.note,
               "curves": [{"label": label, "values": _json_curve(panel.curves[label]), "named": rank < MOST_ACTIVE}
                          for rank, label in enumerate(panel.ranked())]}
              for panel in panels]
    return {"title": f"FAP curves of {name}", "fps": stream.fps, "times": np.round(times, 4).tolist(),
            "groups": groups}
