"""Curves as CSV, one row per frame: landmarks (``track --csv``), FAPs (one column per FAP the stream
carries), FACS action units (OpenFace 2.2's file), and the per-video rows of a batch summary.

One convention for every per-frame file faceanim writes, so they join on their first columns:

``frame``
    The video's frame, counted from 1 as OpenFace counts (the first frame is 1; a ``.fap``'s frame
    ``n`` is row ``n + 1``).
``timestamp``
    Seconds, the frame's presentation time as the video itself stamps it (its container's pts, so a
    variable frame rate or a start offset is kept, and rows line up with the video in any player);
    for a stream with no video behind it (a ``.fap`` file, an expression), ``frame number / fps``.
    Three decimals, as OpenFace writes.
``success``
    ``1`` where a face was tracked in that frame (or, for FAPs, where the frame carries any), ``0``
    where not; a frame without success leaves its values empty (landmarks, FAPs) or 0 (AUs, as
    OpenFace's do).

The AU file is OpenFace 2.2's as far as its values exist here: ``frame, face_id, timestamp,
confidence, success, pose_Rx, pose_Ry, pose_Rz, AU01_r, ..., AU01_c, ...``, separated by ``", "``
as OpenFace separates them (so scripts that index ``' AU12_r'`` or strip the names both work), ``_r``
intensities on 0-5 and never above 5, ``_c`` presence 0/1. faceanim has no per-frame detector
score: ``confidence`` is 1 where the face was tracked and 0 where not.
"""

from __future__ import annotations

import csv as _csv
from pathlib import Path

import numpy as np

from ..atomic import atomic_output
from ..mpeg4 import fap_table
from ..mpeg4.fapstream import FapStream, curve_columns

__all__ = ["write_fap_csv", "write_au_csv", "write_landmark_csv", "read_curve_csv", "openface_pose",
           "OPENFACE_SCALE", "PRESENCE", "FRAME_COLUMNS"]

OPENFACE_SCALE = 5.0  # OpenFace writes AU intensities 0-5 (FACS A-E as 1-5); faceanim works in 0-1
PRESENCE = 1.0  # an AU is present (AU*_c = 1) from intensity 1 on OpenFace's scale, FACS's A (trace)
FRAME_COLUMNS = ("frame", "timestamp", "success")  # the first columns of every per-frame file


def _frame_cells(number: int, time: float, success: bool) -> list[str]:
    return [str(int(number) + 1), f"{time:.3f}", "1" if success else "0"]


def _write_rows(path, header, rows, separator: str = ",") -> None:
    lines = [separator.join(header)] + [separator.join(cells) for cells in rows]
    with atomic_output(path, suffix=".csv") as tmp:
        tmp.write_text("\n".join(lines) + "\n")


def write_landmark_csv(path, track) -> list[str]:
    """Write a :class:`~faceanim.capture.track.Track`'s landmark pixels: ``frame, timestamp, success``
    (the face found in that frame), ``filled`` (1 where a short gap was filled in from its
    neighbours), ``x0, y0, x1, y1, ...`` in pixels from the image's top-left corner (empty where
    neither found nor filled), then the blendshape scores (0-1) when the track has them. Returns the
    header."""
    pixels = track.pixels()
    header = [*FRAME_COLUMNS, "filled"] + [f"{axis}{i}" for i in range(pixels.shape[1]) for axis in "xy"]
    header += list(track.blendshape_names)
    rows = []
    for t in range(len(track)):
        cells = _frame_cells(t, track.times[t], track.valid[t]) + [str(int(track.filled[t]))]
        cells += ["" if not np.isfinite(v) else f"{v:.2f}" for v in pixels[t].ravel()]
        if track.blendshapes is not None:
            cells += ["" if not np.isfinite(v) else f"{v:.4f}" for v in track.blendshapes[t]]
        rows.append(cells)
    _write_rows(path, header, rows)
    return header


def write_fap_csv(path, stream: FapStream, *, times=None, success=None) -> list[str]:
    """Write ``frame, timestamp, success`` and a column per FAP present in any frame, named
    ``<number>_<name>`` (``3_open_jaw``) in the FAP's own units; a frame without that FAP leaves its
    cell empty. ``times (T,)``: the video's presentation times (default: frame number / fps);
    ``success (T,)``: where the face was tracked (default: the frames carrying any low-level FAP).
    Returns the header."""
    table = fap_table()
    active = curve_columns(stream)
    header = [*FRAME_COLUMNS] + [f"{j + 1}_{table.names[j]}" for j in active]
    frames = stream.frame_numbers if stream.frame_numbers is not None else np.arange(len(stream))
    times = frames / stream.fps if times is None else np.asarray(times, dtype=np.float64)
    ok = stream.mask[:, 2:].any(axis=1) if success is None else np.asarray(success, bool)
    if times.shape != (len(stream),) or ok.shape != (len(stream),):
        raise ValueError(f"times and success must have shape ({len(stream)},), got {times.shape} and {ok.shape}")
    rows = []
    for t in range(len(stream)):
        cells = _frame_cells(frames[t], times[t], ok[t])
        cells += [f"{stream.values[t, j]:g}" if stream.mask[t, j] else "" for j in active]
        rows.append(cells)
    _write_rows(path, header, rows)
    return header


def openface_pose(rotations) -> np.ndarray:
    """(T, 3) ``pose_Rx, pose_Ry, pose_Rz`` in radians, as OpenFace reports them, of head rotations
    ``(T, 3, 3)`` from the head frame (MPEG-4 axes: x to the face's left, y up, z out of the face) to
    the camera's (x right, y up, z towards the viewer): OpenFace's camera has y down and z away, and
    its angles compose as ``R = Rx Ry Rz``; a face looking into the camera reads (0, 0, 0).

    >>> c, s = np.cos(0.2), np.sin(0.2)
    >>> turned = np.array([[[c, 0, s], [0, 1, 0], [-s, 0, c]]])  # about the vertical axis
    >>> [round(float(a), 6) + 0.0 for a in openface_pose(turned)[0]]
    [0.0, -0.2, 0.0]
    """
    flip = np.diag([1.0, -1.0, -1.0])
    R = flip @ np.asarray(rotations, dtype=np.float64) @ flip
    ry = np.arcsin(np.clip(R[:, 0, 2], -1, 1))
    rx = np.arctan2(-R[:, 1, 2], R[:, 2, 2])
    rz = np.arctan2(-R[:, 0, 1], R[:, 0, 0])
    return np.stack([rx, ry, rz], axis=1)


def write_au_csv(path, numbers, intensities, times, success=None, *, pose=None) -> list[str]:
    """Write AU intensities ``(T, A)`` (0-1 scale) for AU ``numbers`` as OpenFace 2.2 writes them (see
    the module's docstring): ``times (T,)`` in seconds (the video's presentation times), ``success
    (T,)`` where the face was tracked, ``pose (T, 3)`` the ``pose_R*`` angles in radians (see
    :func:`openface_pose`; 0 when None). ``AU*_r`` is the intensity times 5, clipped to 0-5 (an
    exaggeration above 1 reads 5); ``AU*_c`` is 1 from :data:`PRESENCE` on. Frames without success
    carry 0, as OpenFace's do. Returns the header (without OpenFace's spaces).

    >>> import tempfile, pathlib
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "aus.csv"
    >>> _ = write_au_csv(out, (12,), [[0.5], [1.6]], [0.0, 0.04])
    >>> print(out.read_text(), end="")
    frame, face_id, timestamp, confidence, success, pose_Rx, pose_Ry, pose_Rz, AU12_r, AU12_c
    1, 0, 0.000, 1.00, 1, 0.000, 0.000, 0.000, 2.50, 1
    2, 0, 0.040, 1.00, 1, 0.000, 0.000, 0.000, 5.00, 1
    """
    values = np.asarray(intensities, dtype=np.float64)
    times = np.asarray(times, dtype=np.float64)
    ok = np.ones(len(values), bool) if success is None else np.asarray(success, bool)
    angles = np.zeros((len(values), 3)) if pose is None else np.asarray(pose, dtype=np.float64)
    if times.shape != (len(values),) or ok.shape != (len(values),) or angles.shape != (len(values), 3):
        raise ValueError(f"times, success and pose must have {len(values)} rows, got {times.shape}, {ok.shape} "
                         f"and {angles.shape}")
    header = ["frame", "face_id", "timestamp", "confidence", "success", "pose_Rx", "pose_Ry", "pose_Rz"]
    header += [f"AU{n:02d}_r" for n in numbers] + [f"AU{n:02d}_c" for n in numbers]
    rows = []
    for t, row in enumerate(values):
        good = bool(ok[t]) and bool(np.isfinite(row).all()) and bool(np.isfinite(angles[t]).all())
        scaled = np.round(np.clip(OPENFACE_SCALE * row, 0.0, OPENFACE_SCALE), 2) if good else np.zeros_like(row)
        # presence read from the written value, so AU*_c agrees with the AU*_r a reader sees
        cells = [str(t + 1), "0", f"{times[t]:.3f}", "1.00" if good else "0.00", "1" if good else "0"]
        cells += [f"{a:.3f}" if good else "0.000" for a in angles[t]]
        cells += [f"{v:.2f}" for v in scaled] + ["1" if v >= PRESENCE else "0" for v in scaled]
        rows.append(cells)
    _write_rows(path, header, rows, separator=", ")
    return header


def read_curve_csv(path) -> tuple[list[str], dict[str, np.ndarray]]:
    """Read a per-frame CSV faceanim (or OpenFace) wrote: its header (names stripped of OpenFace's
    spaces) and ``{column: (T,) float64}``, NaN where a cell is empty. Columns whose cells are not
    numbers are left out.

    Raises
    ------
    InputError
        The file cannot be read.
    FileFormatError
        Not UTF-8 text, no header, or a row whose length is not the header's (the line is named).
    """
    from ..errors import FileFormatError, InputError

    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise FileFormatError(path, "is not a UTF-8 text CSV") from None
    except OSError as exc:
        raise InputError(f"{path}: {exc.strerror or exc}") from None
    rows = list(_csv.reader(text.splitlines(), skipinitialspace=True))
    if not rows or not rows[0]:
        raise FileFormatError(path, "has no header line")
    header = [name.strip() for name in rows[0]]
    columns: dict[str, list] = {name: [] for name in header}
    for number, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        if len(row) != len(header):
            raise FileFormatError(path, f"has {len(row)} cells where the header names {len(header)}", line=number)
        for name, cell in zip(header, row, strict=True):
            columns[name].append(cell.strip())
    numeric = {}
    for name, cells in columns.items():
        try:
            numeric[name] = np.array([float(c) if c else np.nan for c in cells], dtype=np.float64)
        except ValueError:
            continue
    return header, numeric
