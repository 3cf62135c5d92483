"""Curves as CSV, one row per frame: FAPs (one column per FAP the stream carries) and FACS action
units (OpenFace's columns), for spreadsheets, plotting and animation tools that import curves."""

from __future__ import annotations

import numpy as np

from ..atomic import atomic_output
from ..mpeg4 import fap_table
from ..mpeg4.fapstream import FapStream, curve_columns

__all__ = ["write_fap_csv", "write_au_csv", "OPENFACE_SCALE"]

OPENFACE_SCALE = 5.0  # OpenFace writes AU intensities 0-5 (FACS A-E as 1-5); faceanim works in 0-1


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


def write_au_csv(path, numbers, intensities, fps: float, success=None) -> list[str]:
    """Write AU intensities ``(T, A)`` (0-1 scale) for AU ``numbers`` as OpenFace writes them:
    ``frame`` (from 1), ``timestamp`` (s), ``success`` (1 where a face was tracked), then
    ``AU01_r, AU02_r, ...`` on OpenFace's 0-5 scale; frames without a face carry 0, as OpenFace's
    do. Returns the header."""
    values = np.asarray(intensities, dtype=np.float64)
    ok = np.ones(len(values), bool) if success is None else np.asarray(success, bool)
    header = ["frame", "timestamp", "success"] + [f"AU{n:02d}_r" for n in numbers]
    rows = [",".join(header)]
    for t, row in enumerate(values):
        good = ok[t] and np.isfinite(row).all()
        cells = [str(t + 1), f"{t / fps:.3f}", "1" if good else "0"]
        cells += [f"{OPENFACE_SCALE * v:.2f}" if good else "0.00" for v in row]
        rows.append(",".join(cells))
    with atomic_output(path, suffix=".csv") as tmp:
        tmp.write_text("\n".join(rows) + "\n")
    return header
