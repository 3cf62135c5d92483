"""FAP curves in the form the viewer page draws them."""

from __future__ import annotations

import numpy as np

from ..mpeg4 import fap_table
from ..mpeg4.fapstream import FapStream, curve_columns

__all__ = ["fap_curves"]


def fap_curves(stream: FapStream) -> dict:
    """``{title, fps, names, values}`` for the page: one curve per FAP the stream carries, in FAPU units,
    frames without that FAP at 0."""
    table = fap_table()
    active = curve_columns(stream)
    values = np.where(stream.mask, stream.values, 0.0)
    return {"title": f"FAP curves of {stream.name} (FAPU units)", "fps": stream.fps,
            "names": [f"{j + 1} {table.names[j]}" for j in active],
            "values": [np.round(values[:, j], 2).tolist() for j in active]}
