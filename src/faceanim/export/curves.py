"""FAP curves as CSV: one row per frame, one column per FAP the stream carries, for spreadsheets,
plotting and animation tools that import curves."""

from __future__ import annotations

import numpy as np

from ..atomic import atomic_output
from ..mpeg4 import fap_table
from ..mpeg4.fapstream import FapStream, curve_columns

__all__ = ["write_fap_csv"]


def write_fap_csv(path, stream: FapStream) -> list[str]:
    """Write ``frame, time`` and a column per FAP present in any frame, named ``<number>_<name>``
    (``3_open_jaw``) in the FAP's own units; a frame without that FAP leaves its cell empty.
    Returns the header."""
    table = fap_table()
    active = curve_columns(stream)
    header = ["frame", "time"] + [f"{j + 1}_{table.names[j]}" for j in active]
    rows = [",".join(header)]
    frames = stream.frame_numbers if stream.frame_numbers is not None else np.arange(len(stream))
    for t in range(len(stream)):
        cells = [str(int(frames[t])), f"{frames[t] / stream.fps:.4f}"]
        cells += [f"{stream.values[t, j]:g}" if stream.mask[t, j] else "" for j in active]
        rows.append(",".join(cells))
    with atomic_output(path, suffix=".csv") as tmp:
        tmp.write_text("\n".join(rows) + "\n")
    return header
