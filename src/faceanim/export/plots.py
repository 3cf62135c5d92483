"""Curves drawn where people would rather look than read: a ``.fap`` file, an AU CSV (``faceanim aus``
or OpenFace's) or a take of blendshape curves (a ``track --csv`` with blendshapes, an ARKit / Live Link
Face take) as one PNG, one panel per group of the face (jaw, lips, brows, lids, eyes, cheeks and nose,
head), each on its own scale and in its own unit, with ticks, over time in seconds.

Units: a FAP is drawn as a multiple of its FAPU (``open_jaw`` 0.3 is a drop of 0.3 times the face's
mouth-nose separation: the ``.fap``'s integer divided by 1024), angles in degrees (FAP angle units are
1e-5 rad; OpenFace's ``pose_R*`` are radians), AUs on OpenFace's 0-5 intensity scale, blendshapes as
weights 0-1. A panel with many curves names the most active ones (by their range) and draws the rest
thin and grey, saying "N most active of M".
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..errors import FileFormatError, InputError

__all__ = ["plot", "draw", "figure_png", "fap_png", "Panel", "curve_panels", "fap_panels", "GROUPS", "MOST_ACTIVE"]

GROUPS = ("jaw", "lips", "brows", "lids", "eyes", "cheeks & nose", "head", "other")
MOST_ACTIVE = 6  # curves named per panel; the rest are drawn grey

# FAP number -> group (FAPs 1 and 2, visemes and expressions, are selections, not curves)
_FAP_GROUPS = {**{n: "jaw" for n in (3, 14, 15, 18)}, **{n: "lips" for n in (*range(4, 14), 16, 17, *range(51, 61))},
               **{n: "lids" for n in range(19, 23)}, **{n: "eyes" for n in range(23, 31)},
               **{n: "brows" for n in range(31, 39)}, **{n: "cheeks & nose" for n in (*range(39, 43), *range(61, 65))},
               **{n: "head" for n in (48, 49, 50)}, **{n: "other" for n in (*range(43, 48), *range(65, 69))}}
_AU_GROUPS = {**{n: "brows" for n in (1, 2, 4)}, **{n: "lids" for n in (5, 7, 41, 42, 43, 44, 45, 46)},
              **{n: "cheeks & nose" for n in (6, 9, 11, 13, 33, 34, 35, 38, 39)},
              **{n: "lips" for n in (8, 10, 12, 14, 15, 16, 17, 18, 20, 22, 23, 24, 25, 28)},
              **{n: "jaw" for n in (26, 27, 29, 30, 31)}, **{n: "eyes" for n in (61, 62, 63, 64)},
              **{n: "head" for n in range(51, 59)}}
_BLENDSHAPE_GROUPS = (("jaw", "jaw"), ("mouth", "lips"), ("brow", "brows"), ("eyeblink", "lids"),
                      ("eyesquint", "lids"), ("eyewide", "lids"), ("eyelook", "eyes"), ("cheek", "cheeks & nose"),
                      ("nose", "cheeks & nose"), ("head", "head"), ("lefteye", "eyes"), ("righteye", "eyes"))


class Panel:
    """One group's curves: ``name``, the y axis' ``unit``, ``curves`` ``{label: (T,) float64}``."""

    def __init__(self, name: str, unit: str):
        self.name, self.unit, self.curves = name, unit, {}

    def __repr__(self) -> str:
        return f"Panel({self.name!r}, {self.unit!r}, {len(self.curves)} curves)"

    def ranked(self) -> list[str]:
        """The curves' labels, most active (widest range) first; the first :data:`MOST_ACTIVE` are named."""
        return sorted(self.curves, key=lambda k: -_activity(self.curves[k]))

    @property
    def note(self) -> str:
        """What the panel shows: ``"6 most active of 22"`` where some curves go unnamed, else ``"3 curves"``."""
        count = len(self.curves)
        return f"{MOST_ACTIVE} most active of {count}" if count > MOST_ACTIVE else f"{count} curves"


def _panels(named: list[tuple[str, str, str, np.ndarray]]) -> list[Panel]:
    """Panels in :data:`GROUPS` order from ``(group, unit, label, curve)``; a group whose curves come
    in two units (a FAPU and degrees) gets a panel per unit."""
    panels: dict[tuple[str, str], Panel] = {}
    for group, unit, label, curve in named:
        if np.isfinite(curve).any():
            panels.setdefault((group, unit), Panel(group, unit)).curves[label] = curve
    return [panels[key] for key in sorted(panels, key=lambda k: (GROUPS.index(k[0]), k[1]))]


def _fap_panels(values: dict[int, np.ndarray]):
    from ..mpeg4 import fap_table
    from ..mpeg4.fapu import ANGLE_UNIT

    table = fap_table()
    named = []
    for number, curve in values.items():
        unit = table.units[number - 1]
        if unit == "AU":  # FAP angle units: 1e-5 rad
            named.append((_FAP_GROUPS[number], "degrees", table.names[number - 1], np.degrees(curve * ANGLE_UNIT)))
        else:
            named.append((_FAP_GROUPS[number], "x FAPU (MNS0, MW0, ENS0, ES0, IRISD0)",
                          f"{table.names[number - 1]} ({unit})", curve / 1024.0))
    for panel in _panels(named):  # the unit names only the FAPUs the panel uses
        if panel.unit.startswith("x FAPU"):
            used = sorted({label.rsplit("(", 1)[1].rstrip(")") for label in panel.curves})
            panel.unit = "x " + ", ".join(f"{u}0" for u in used)
        yield panel


def fap_panels(stream) -> tuple[np.ndarray, list[Panel]]:
    """The curves of a :class:`~faceanim.mpeg4.fapstream.FapStream` as ``(times (T,) in seconds,
    panels)``: one panel per group (and unit), FAPs in multiples of their FAPU, angles in degrees,
    frames without a FAP NaN."""
    from ..mpeg4.fapstream import curve_columns

    frames = stream.frame_numbers if stream.frame_numbers is not None else np.arange(len(stream))
    values = {j + 1: np.where(stream.mask[:, j], stream.values[:, j], np.nan) for j in curve_columns(stream)}
    return frames / stream.fps, list(_fap_panels(values))


def curve_panels(path) -> tuple[np.ndarray, str, list[Panel]]:
    """Read ``path`` (``.fap``, or a CSV of FAP, AU or blendshape curves) into ``(times (T,) in
    seconds, or frame numbers, the x axis' label, panels)``.

    Raises
    ------
    InputError
        A missing file, a suffix other than .fap or .csv, or a CSV with no curves faceanim knows.
    """
    from .curves import read_curve_csv

    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    suffix = path.suffix.lower()
    if suffix == ".fap":
        from ..mpeg4.fapfile import read_fap

        times, panels = fap_panels(read_fap(path))
        return times, "time (s)", panels
    if suffix != ".csv":
        raise InputError(f"{path}: plot reads a .fap file or a .csv of FAP, AU or blendshape curves")
    header, columns = read_curve_csv(path)
    if "timestamp" in columns:
        x, label = columns["timestamp"], "time (s)"
    elif "frame" in columns:
        x, label = columns["frame"], "frame"
    else:
        x, label = np.arange(len(next(iter(columns.values()), []))), "row"
    faps = {int(m.group(1)): columns[name] for name in header
            if (m := re.fullmatch(r"(\d+)_[a-z_]+", name)) and name in columns and int(m.group(1)) in _FAP_GROUPS}
    if faps:
        return x, label, list(_fap_panels(faps))
    named = []
    for name in header:
        if name not in columns:
            continue
        if m := re.fullmatch(r"AU(\d+)_r", name):
            named.append((_AU_GROUPS.get(int(m.group(1)), "other"), "intensity (0-5)", f"AU{m.group(1)}",
                          columns[name]))
        elif m := re.fullmatch(r"pose_R([xyz])", name):
            word = {"x": "pitch (Rx)", "y": "yaw (Ry)", "z": "roll (Rz)"}[m.group(1)]
            named.append(("head", "degrees", word, np.degrees(columns[name])))
    if not named:  # blendshapes: ARKit / MediaPipe names, any case (Live Link Face writes JawOpen)
        for name in header:
            lowered = name.lower()
            group = next((g for prefix, g in _BLENDSHAPE_GROUPS if lowered.startswith(prefix)), None)
            if name in columns and group is not None:
                unit = "as in the file" if group == "head" or lowered.startswith(("lefteye", "righteye")) \
                    else "weight (0-1)"
                named.append((group, unit, name, columns[name]))
            elif name in columns and lowered.startswith("tongue"):
                named.append(("other", "weight (0-1)", name, columns[name]))
    if not named:
        raise FileFormatError(path, "holds no FAP (3_open_jaw), AU (AU12_r) or blendshape (jawOpen) columns to plot")
    return x, label, _panels(named)


def _activity(curve: np.ndarray) -> float:
    finite = curve[np.isfinite(curve)]
    return float(np.ptp(finite)) if len(finite) else 0.0


def draw(x, xlabel: str, panels: list[Panel], *, title: str, figure_class=None):
    """A matplotlib ``Figure`` of ``panels`` over ``x`` (see :func:`plot`), not yet drawn to a file."""
    if figure_class is None:
        from matplotlib.figure import Figure as figure_class
    figure = figure_class(figsize=(11, 0.6 + 2.1 * len(panels)), dpi=100, layout="constrained")
    axes = figure.subplots(len(panels), 1, sharex=True, squeeze=False)[:, 0]
    figure.suptitle(title, fontsize=12)
    for ax, panel in zip(axes, panels, strict=True):
        ranked = panel.ranked()
        named, rest = ranked[:MOST_ACTIVE], ranked[MOST_ACTIVE:]
        for label in rest:
            ax.plot(x, panel.curves[label], color="0.75", linewidth=0.7)
        for label in named:
            ax.plot(x, panel.curves[label], linewidth=1.4, label=label)
        ax.set_title(f"{panel.name}: {panel.note}", loc="left", fontsize=10)
        ax.set_ylabel(panel.unit, fontsize=9)
        ax.grid(True, color="0.9", linewidth=0.6)
        ax.tick_params(labelsize=8, labelbottom=True)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    axes[-1].set_xlabel(xlabel)
    return figure


def plot(source, output, *, title: str | None = None) -> list[Panel]:
    """``faceanim plot``: draw the curves of ``source`` (see :func:`curve_panels`) into the PNG
    ``output``, one panel per group, each with its own y scale, unit and ticks, over a shared time
    axis. Written complete or not at all. Returns the panels drawn.

    Raises
    ------
    ImportError
        matplotlib is missing (the ``plot`` extra: ``pip install 'faceanim[plot]'``).
    """
    from ..atomic import atomic_output
    from ..outputs import check_outputs

    output = Path(output)
    check_outputs({"-o": (output, ".png")}, inputs={"FILE": source})
    x, xlabel, panels = curve_panels(source)
    if not panels:
        raise InputError(f"{source}: no curve holds a value to plot")
    _check_axes(source, x, xlabel, panels)
    png = figure_png(x, xlabel, panels, title=title or Path(source).name)
    with atomic_output(output, suffix=".png") as tmp:
        tmp.write_bytes(png)
    return panels


_LARGEST = 1e300  # the largest value a plot's axis takes, with room for its margins and tick steps


def _check_axes(source, x, xlabel: str, panels: list[Panel]) -> None:
    """Refuse, naming the file, an axis with a value beyond 1e300 in magnitude: no scale can show it
    (the axis' span or its margins overflow a float, and matplotlib's tick locator fails)."""
    for label, values in [(xlabel, np.asarray(x, dtype=np.float64)),
                          *((name, curve) for panel in panels for name, curve in panel.curves.items())]:
        finite = np.abs(values[np.isfinite(values)])
        if len(finite) and finite.max() > _LARGEST:
            raise FileFormatError(source, f"{label} reaches {finite.max():g} in magnitude; a plot's axis holds "
                                          f"values up to {_LARGEST:g}")


def fap_png(stream, *, title: str, dpi: int = 100) -> bytes:
    """A FapStream's curves over time, drawn as ``faceanim plot`` draws a ``.fap``, as PNG bytes."""
    times, panels = fap_panels(stream)
    return figure_png(times, "time (s)", panels, title=title, dpi=dpi)


def figure_png(x, xlabel: str, panels: list[Panel], *, title: str, dpi: int = 100) -> bytes:
    """:func:`draw`'s figure as PNG bytes (what ``faceanim plot`` writes, the demo report embeds and
    ``faceanim batch --do plot`` writes per video).

    Raises
    ------
    ImportError
        matplotlib is missing (the ``plot`` extra: ``pip install 'faceanim[plot]'``).
    """
    import io

    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError:
        raise ImportError("faceanim plot needs matplotlib: pip install 'faceanim[plot]'") from None
    figure = draw(x, xlabel, panels, title=title, figure_class=Figure)
    FigureCanvasAgg(figure)
    png = io.BytesIO()
    figure.savefig(png, format="png", dpi=dpi)
    return png.getvalue()
