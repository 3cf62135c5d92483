"""Live Link Face takes: ARKit-52 blendshape weights with head and eye rotations, as a CSV.

The columns are those Epic's Live Link Face app writes: ``Timecode``, ``BlendShapeCount`` (61), the
52 ARKit shapes in Live Link's order and spelling (:data:`SHAPE_COLUMNS`: ``EyeBlinkLeft`` ...
``TongueOut``, the camelCase :data:`~faceanim.rig.arkit.ARKIT_NAMES` with a capital), then
:data:`POSE_COLUMNS` (``HeadYaw``, ``HeadPitch``, ``HeadRoll``, ``LeftEyeYaw`` ... ``RightEyeRoll``).
Weights are in [0, 1]. Angles are radians, right-handed about ARKit's face axes (x towards the
face's own left, y up, z out of the face): yaw turns the face towards its own left, pitch turns it
down, roll tilts it towards its own right; an eye's angles are its gaze in the head, the same way.

``Timecode`` is ``HH:MM:SS:FF.mmm`` as Live Link writes it: hours, minutes, seconds, the frame ``FF``
within the second at a whole frame rate ``R`` (the video's rounded: 25, 30, 24 for 23.976), and
``.mmm`` the thousandths of a frame, so ``t = 3600 HH + 60 MM + SS + (FF + mmm / 1000) / R``.

>>> timecode(3661.5, 30), round(seconds_of("01:01:01:15.000", 30), 6)
('01:01:01:15.000', 3661.5)
"""

from __future__ import annotations

import csv
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..atomic import atomic_output
from ..errors import FileFormatError
from ..textfile import read_text
from ..validation import as_array
from .arkit import ARKIT_NAMES

__all__ = ["Take", "SHAPE_COLUMNS", "POSE_COLUMNS", "COLUMNS", "arkit_weights", "timecode", "seconds_of",
           "write_livelink_csv", "read_livelink_csv", "take_summary"]

SHAPE_COLUMNS: tuple[str, ...] = tuple(n[0].upper() + n[1:] for n in ARKIT_NAMES)
POSE_COLUMNS: tuple[str, ...] = ("HeadYaw", "HeadPitch", "HeadRoll", "LeftEyeYaw", "LeftEyePitch", "LeftEyeRoll",
                                 "RightEyeYaw", "RightEyePitch", "RightEyeRoll")
COLUMNS: tuple[str, ...] = ("Timecode", "BlendShapeCount", *SHAPE_COLUMNS, *POSE_COLUMNS)
_RATES = (24, 25, 30, 48, 50, 60, 100, 120)  # timecode rates a take is read at when none is given
_TIMECODE = re.compile(r"^(\d{1,3}):(\d{2}):(\d{2}):(\d{1,3})(?:\.(\d+))?$")
_SLACK = 1e-6  # a weight this far outside [0, 1] is a rounding of 0 or 1, not an error
_DAY = 86400.0


@dataclass(frozen=True, eq=False)
class Take:
    """A performance as ARKit-52 weights: what a Live Link Face CSV holds.

    Attributes
    ----------
    times : (T,) float64
        Seconds (a video's presentation times; a read take's timecodes, as seconds of the day).
    weights : (T, 52) float64
        Blendshape weights in [0, 1], columns in :data:`~faceanim.rig.arkit.ARKIT_NAMES`' order.
    pose : (T, 9) float64
        Radians, columns as :data:`POSE_COLUMNS`: head yaw, pitch, roll, then each eye's.
    fps : float
        The frame rate (the video's; a read take's, from its timecodes).
    """

    times: np.ndarray
    weights: np.ndarray
    pose: np.ndarray
    fps: float

    def __post_init__(self):
        times = as_array(self.times, "times", shape=("T",), frozen=True)
        T = len(times)
        weights = as_array(self.weights, "weights", shape=(T, len(ARKIT_NAMES)), frozen=True)
        if ((weights < -_SLACK) | (weights > 1 + _SLACK)).any():
            raise ValueError(f"weights must lie in [0, 1], got {weights.min():g} to {weights.max():g}")
        pose = as_array(self.pose, "pose", shape=(T, len(POSE_COLUMNS)), frozen=True)
        if not (math.isfinite(self.fps) and self.fps > 0):
            raise ValueError(f"fps must be a positive number, got {self.fps!r}")
        for name, value in (("times", times), ("weights", weights), ("pose", pose), ("fps", float(self.fps))):
            object.__setattr__(self, name, value)

    def __len__(self) -> int:
        return len(self.times)

    def weight(self, name: str) -> np.ndarray:
        """(T,) the weights of one ARKit shape, by its ARKit name (``jawOpen``) or Live Link's (``JawOpen``)."""
        return self.weights[:, _shape_index(name)]


def _shape_index(name: str) -> int:
    lookup = {n.lower(): i for i, n in enumerate(ARKIT_NAMES)}
    try:
        return lookup[name.lower()]
    except KeyError:
        raise KeyError(f"no ARKit shape {name!r}") from None


def arkit_weights(scores, names) -> np.ndarray:
    """``(T, 52)`` weights in :data:`~faceanim.rig.arkit.ARKIT_NAMES`' order from MediaPipe's
    blendshape ``scores (T, N)`` named ``names`` (its ``_neutral`` is dropped, its 51 ARKit names
    kept; an ARKit shape MediaPipe does not score, ``tongueOut``, is 0). Clipped to [0, 1]; NaN rows
    (frames without a face) stay NaN.

    Raises
    ------
    ValueError
        A name that is neither an ARKit shape nor ``_neutral``, or no ARKit name at all.
    """
    scores = np.asarray(scores, dtype=np.float64)
    out = np.zeros((len(scores), len(ARKIT_NAMES)))
    out[np.isnan(scores).all(axis=1)] = np.nan
    found = 0
    for column, name in enumerate(names):
        if name == "_neutral":
            continue
        try:
            out[:, _shape_index(name)] = scores[:, column]
        except KeyError:
            raise ValueError(f"blendshape {name!r} is not one of ARKit's 52") from None
        found += 1
    if not found:
        raise ValueError("no ARKit blendshape among the scores' names")
    return np.clip(out, 0.0, 1.0)


def _rate(fps: float) -> int:
    """The whole timecode rate of a frame rate (29.97 -> 30, 23.976 -> 24)."""
    return max(1, int(round(fps)))


def timecode(seconds: float, rate: int) -> str:
    """``HH:MM:SS:FF.mmm`` of a time in seconds at the whole timecode ``rate`` (frames per second).

    >>> timecode(0.0, 25), timecode(1.02, 25), timecode(59.999, 60)
    ('00:00:00:00.000', '00:00:01:00.500', '00:00:59:59.940')
    """
    frames = max(float(seconds), 0.0) * rate
    whole = math.floor(frames + 1e-6)  # 0.04 s at 25 fps is frame 1, not frame 0.999...
    thousandths = round(max(frames - whole, 0.0) * 1000)
    if thousandths >= 1000:
        whole, thousandths = whole + 1, 0
    second, frame = divmod(whole, rate)
    minute, second = divmod(second, 60)
    hour, minute = divmod(minute, 60)
    return f"{hour:02d}:{minute:02d}:{second:02d}:{frame:02d}.{thousandths:03d}"


def seconds_of(text: str, rate: int) -> float:
    """Seconds of a ``HH:MM:SS:FF[.sub]`` timecode at the whole ``rate``; ValueError if it is none."""
    match = _TIMECODE.match(text.strip())
    if not match:
        raise ValueError(f"timecode {text!r} is not HH:MM:SS:FF.mmm")
    hour, minute, second, frame = (int(g) for g in match.groups()[:4])
    sub = float(f"0.{match.group(5)}") if match.group(5) else 0.0
    if minute > 59 or second > 59:
        raise ValueError(f"timecode {text!r} has minutes or seconds above 59")
    return 3600 * hour + 60 * minute + second + (frame + sub) / rate


def write_livelink_csv(path, take: Take, *, rate: int | None = None) -> Path:
    """Write ``take`` as a Live Link Face CSV (complete or not at all); ``rate``: the timecode's whole
    frame rate (default: the take's fps rounded). Weights and angles with 6 decimals."""
    rate = _rate(take.fps) if rate is None else int(rate)
    path = Path(path)
    with atomic_output(path, suffix=".csv") as tmp, open(tmp, "w", newline="", encoding="utf-8") as handle:
        handle.write(",".join(COLUMNS) + "\n")
        count = str(len(SHAPE_COLUMNS) + len(POSE_COLUMNS))
        for start in range(0, len(take), 1024):
            rows = np.hstack([take.weights[start:start + 1024], take.pose[start:start + 1024]])
            lines = [",".join([timecode(t, rate), count, *(f"{v:.6f}" for v in row)])
                     for t, row in zip(take.times[start:start + 1024], rows, strict=True)]
            handle.write("\n".join(lines) + "\n")
    return path


def read_livelink_csv(path, *, rate: int | None = None) -> Take:
    """Read a Live Link Face CSV (written by the app, by :func:`write_livelink_csv` or by another
    tool that uses its columns) into a :class:`Take`.

    Columns are matched by name, without regard to case (``EyeBlinkLeft`` or ``eyeBlinkLeft``), in
    any order; ``Timecode`` is required, ``BlendShapeCount`` optional; a shape or angle the file
    lacks is 0. ``rate``: the timecode's whole frame rate; when None, the smallest of 24, 25, 30,
    48, 50, 60, 100 and 120 above every frame number ``FF`` in the file (Live Link's own default is
    60). ``fps`` is one over the median step between rows' times.

    Raises
    ------
    InputError
        The file is missing or cannot be read.
    FileFormatError
        Naming the file and the line: not UTF-8 text, no header or no rows, an unknown or repeated
        column, no ``Timecode``, a row of the wrong length, a timecode that is not
        ``HH:MM:SS:FF.mmm`` or goes back in time, a value that is not a number, a weight outside
        [0, 1] or an angle that is not finite.
    """
    path = Path(path)
    text = read_text(path)
    rows = list(csv.reader(text.splitlines()))
    if not rows or not any(cell.strip() for cell in rows[0]):
        raise FileFormatError(path, "is empty; a Live Link Face CSV starts with a header of column names", line=1)
    header = [cell.strip() for cell in rows[0]]
    known = {name.lower(): ("shape", i) for i, name in enumerate(SHAPE_COLUMNS)}
    known |= {name.lower(): ("pose", i) for i, name in enumerate(POSE_COLUMNS)}
    known |= {"timecode": ("time", 0), "blendshapecount": ("count", 0)}
    where, seen = [], {}
    for column, name in enumerate(header):
        if name.lower() not in known:
            raise FileFormatError(path, f"unknown column {name!r} (column {column + 1}); a Live Link Face CSV "
                                        "has Timecode, BlendShapeCount, the 52 ARKit shapes and head and eye "
                                        "yaw/pitch/roll", line=1)
        if name.lower() in seen:
            raise FileFormatError(path, f"column {name!r} appears twice (columns {seen[name.lower()] + 1} and "
                                        f"{column + 1})", line=1)
        seen[name.lower()] = column
        where.append(known[name.lower()])
    if "timecode" not in seen:
        raise FileFormatError(path, "has no Timecode column", line=1)
    body = [(number, row) for number, row in enumerate(rows[1:], start=2) if any(cell.strip() for cell in row)]
    if not body:
        raise FileFormatError(path, "holds no rows after its header", line=1)
    weights = np.zeros((len(body), len(SHAPE_COLUMNS)))
    pose = np.zeros((len(body), len(POSE_COLUMNS)))
    stamps = []
    for k, (number, row) in enumerate(body):
        if len(row) != len(header):
            raise FileFormatError(path, f"has {len(row)} values but the header names {len(header)} columns",
                                  line=number)
        for (kind, index), name, cell in zip(where, header, row, strict=True):
            if kind == "time":
                match = _TIMECODE.match(cell.strip())
                if not match:
                    raise FileFormatError(path, f"Timecode {cell.strip()!r} is not HH:MM:SS:FF.mmm", line=number)
                stamps.append((number, cell.strip(), int(match.group(4))))
                continue
            try:
                value = float(cell)
            except ValueError:
                raise FileFormatError(path, f"{name} {cell.strip()!r} is not a number", line=number) from None
            if kind == "count":
                if not value.is_integer() or value < 0:
                    raise FileFormatError(path, f"{name} {cell.strip()!r} is not a count", line=number)
            elif kind == "shape":
                if not -_SLACK <= value <= 1 + _SLACK:  # NaN fails too
                    raise FileFormatError(path, f"{name} {cell.strip()} is outside [0, 1]", line=number)
                weights[k, index] = min(max(value, 0.0), 1.0)
            else:
                if not math.isfinite(value):
                    raise FileFormatError(path, f"{name} {cell.strip()} is not a finite angle", line=number)
                pose[k, index] = value
    if rate is None:
        top = max(frame for _, _, frame in stamps)
        rate = next((r for r in _RATES if r > top), top + 1)
    times = np.empty(len(stamps))
    for k, (number, stamp, frame) in enumerate(stamps):
        if frame >= rate:
            raise FileFormatError(path, f"Timecode {stamp!r} has frame {frame}, not below the rate {rate}",
                                  line=number)
        try:
            times[k] = seconds_of(stamp, rate)
        except ValueError as exc:
            raise FileFormatError(path, str(exc), line=number) from None
        if k and times[k] < times[k - 1] - _DAY / 2:  # past midnight
            times[k:] += _DAY
        if k and times[k] < times[k - 1]:
            raise FileFormatError(path, f"Timecode {stamp!r} is earlier than the row before it", line=number)
    steps = np.diff(times)
    steps = steps[steps > 0]
    fps = 1.0 / float(np.median(steps)) if len(steps) else float(rate)
    return Take(times, weights, pose, fps)


def take_summary(take: Take, path, *, top: int = 12, note: str = "") -> str:
    """A ``faceanim fap-info``-style summary: frames, fps, duration, then the ``top`` most active
    shapes (largest range of weight) with their mean, min and max, and the head's angle ranges in
    degrees."""
    duration = float(take.times[-1] - take.times[0]) + 1.0 / take.fps if len(take) else 0.0
    lines = [f"{path}: {len(take)} frames at {take.fps:g} fps ({duration:.2f} s), {len(SHAPE_COLUMNS)} ARKit "
             f"shapes + head and eye yaw/pitch/roll{note}"]
    spread = np.ptp(take.weights, axis=0) if len(take) else np.zeros(len(SHAPE_COLUMNS))
    order = np.argsort(-spread, kind="stable")[:top]
    lines.append(f"{'shape':<20} {'mean':>6} {'min':>6} {'max':>6}")
    for j in order:
        w = take.weights[:, j]
        lines.append(f"{SHAPE_COLUMNS[j]:<20} {w.mean():>6.3f} {w.min():>6.3f} {w.max():>6.3f}")
    head = np.degrees(take.pose[:, :3])
    lines.append("head (degrees): " + ", ".join(
        f"{name[4:].lower()} {lo:+.1f} to {hi:+.1f}" for name, lo, hi in zip(
            POSE_COLUMNS[:3], head.min(axis=0), head.max(axis=0), strict=True)))
    return "\n".join(lines)
