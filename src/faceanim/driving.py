"""Driving a named rig: ``faceanim animate VIDEO|take.csv --target rigged.glb``.

A ``.glb`` whose morph targets carry ARKit or FACS AU names (``faceanim rig``'s, or another tool's;
see :mod:`faceanim.rig.drive` for the spellings) is animated through *its own* targets: the output is
the same file with one weight curve per target added (a key per frame, weights in [0, 1]), not the
anonymous shapes ``animate`` writes for other meshes. Three sources drive it:

* **a video** (or a saved track): the weights are solved per frame (:class:`~faceanim.rig.solve.RigSolver`)
  by bounded least squares over the rig's shapes against the tracked motion at the control points the
  rig shares with the tracker (carried into the rig's axes as ``animate`` carries them), fused with the
  Face Landmarker's blendshape scores for the eyes and brows (blinks, squints, widening, gaze, brow
  raises and frowns), which the geometry reads poorly: those shapes are pulled to their scores, and a
  control point is counted in the geometry only as much as other shapes move it (a lid's points are
  left to the blink's score, not forced onto a squint). The scores are calibrated per take: the
  ``--neutral`` window's mean score (else each score's 5th percentile over the take) becomes 0 and 1
  stays 1.
* **a Live Link Face CSV** (:func:`~faceanim.rig.livelink.read_livelink_csv`): ARKit weights by name
  (its head and eye angles are not applied: a rig's morph targets carry no head turn).
* **an OpenFace or py-feat AU CSV**: ``AU12_r`` (OpenFace, 0-5, divided by 5) or ``AU12`` (py-feat,
  0-1) columns; other columns are not read. AU-named targets take the AUs; ARKit-named ones take them
  through :data:`~faceanim.rig.drive.FACS_ARKIT`.

A rig with only some of the 52 shapes (or of the AUs) is driven on the shapes it has: the solve runs
over those alone (motion no shape of the rig can make is left out, not forced onto a neighbour: the
ridge keeps unrelated shapes at rest), and a source's weights for shapes the rig lacks are dropped;
the returned :class:`DrivenRig` says how many targets were driven.
"""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import FileFormatError, InputError
from .textfile import read_text

__all__ = ["DrivenRig", "is_named_rig", "animate_rig", "express_rig", "read_au_csv", "solve_capture", "rig_animation"]

_BASELINE_PERCENTILE = 5.0  # without a --neutral window, a score's rest is this percentile over the take
_AU_COLUMN = re.compile(r"^AU0*(\d{1,2})(?:_?([LR]))?$", re.IGNORECASE)
_DEFAULT_FPS = 30.0  # an AU CSV without timestamps


@dataclass(frozen=True, eq=False)
class DrivenRig:
    """What was written: ``names`` (the driven targets' names in the file), ``weights (T, S)`` in
    [0, 1], ``fps``, and ``driven``: how many morph targets (over all the file's meshes) got a curve."""

    names: tuple[str, ...]
    weights: np.ndarray
    fps: float
    driven: int

    def __len__(self) -> int:
        return len(self.weights)


def is_named_rig(path) -> bool:
    """Whether ``path`` is a ``.glb`` with a morph target of an ARKit or AU name (read from its JSON
    chunk only; a file that cannot be read is left for the loaders to refuse)."""
    from .geometry.meshio import read_glb_json
    from .rig.drive import canonical_name

    if path is None or Path(path).suffix.lower() != ".glb" or not Path(path).is_file():
        return False
    try:
        document = read_glb_json(path)
    except InputError:
        return False
    for mesh in document.get("meshes") or []:
        names = (mesh.get("extras") or {}).get("targetNames") if isinstance(mesh, dict) else None
        if isinstance(names, list) and any(canonical_name(str(n)) for n in names):
            return True
    return False


def _scores_prior(capture, canonical, strength, window) -> np.ndarray | None:
    """``(T, S)`` prior weights from the capture's blendshape scores for the shapes with a strength
    (NaN where there is no face or no score), calibrated against the neutral."""
    from .rig.drive import weights_by_name
    from .rig.livelink import arkit_weights

    if capture.blendshapes is None or not (strength > 0).any():
        return None
    scores = arkit_weights(capture.blendshapes, capture.blendshape_names)
    seen = np.isfinite(scores).all(axis=1)
    if not seen.any():
        return None
    if window is not None and seen[window[0]:window[1]].any():
        rest = np.nanmean(scores[window[0]:window[1]][seen[window[0]:window[1]]], axis=0)
    else:
        rest = np.percentile(scores[seen], _BASELINE_PERCENTILE, axis=0)
    scores = np.clip((scores - rest) / np.maximum(1.0 - rest, 1e-3), 0.0, 1.0)
    from .rig.arkit import ARKIT_NAMES

    prior = weights_by_name(canonical, arkit={n: scores[:, k] for k, n in enumerate(ARKIT_NAMES)},
                            length=len(scores))
    prior[~seen] = np.nan
    prior[:, strength <= 0] = np.nan
    return prior


def solve_capture(rig, target, capture, *, window=None, chunk: int = 512, prior_strength: float | None = None,
                  other_strength: float = 0.0, settings: dict | None = None):
    """``(T, S)`` weights of ``rig``'s recognised targets (:attr:`~faceanim.rig.drive.NamedRig.driven`)
    from a capture (anything with ``motion``, ``blendshapes`` and ``blendshape_names``, as
    :class:`~faceanim.capture.stream.Capture`), solved against the motion at the control points
    ``target`` (the rig's mesh with its points) shares with it, read a run of frames at a time.
    ``prior_strength`` (default :data:`~faceanim.rig.solve.PRIOR`: the eyes' and brows' pull to their
    scores), ``other_strength`` (default 0: the other shapes' pull to theirs; on the tuning draw through
    the tracker 0.1 takes the mouth's weight error from 0.11 to 0.09 but the vertex error from 0.78 to
    0.79, so it is off) and ``settings`` (keywords of :class:`~faceanim.rig.solve.RigSolver`: ridge,
    temporal, sparsity) tune the solve.

    Raises
    ------
    InputError
        Fewer than :data:`~faceanim.retarget.follow.MINIMUM_SHARED_POINTS` shared points on the rig's mesh.
    """
    from .geometry.align import weighted_procrustes
    from .retarget.follow import MINIMUM_SHARED_POINTS, shared_points
    from .rig.drive import EYES_AND_BROWS
    from .rig.solve import PRIOR, RigSolver

    motion = capture.motion
    names = shared_points(motion, target)
    ids = target.ids(names)
    ids, first = np.unique(ids, return_index=True)
    names = [names[i] for i in first]
    on_rig, rig_ids = rig.at(target.mesh.vertices[ids])
    if on_rig.sum() < MINIMUM_SHARED_POINTS:
        raise InputError(f"{rig.path}: only {int(on_rig.sum())} of the tracker's points lie on the mesh with the "
                         f"rig's shapes; at least {MINIMUM_SHARED_POINTS} are needed")
    at = motion.index(names)
    carry = weighted_procrustes(motion.neutral[at], target.mesh.vertices[ids])[:3, :3]
    at, rig_ids = np.asarray(at)[on_rig], rig_ids[on_rig]
    driven = rig.driven
    canonical = [rig.canonical[j] for j in driven]
    from .rig.drive import whole_shape

    pull = PRIOR if prior_strength is None else prior_strength
    leads = np.asarray([c in EYES_AND_BROWS or whole_shape(c) in EYES_AND_BROWS for c in canonical])
    strength = np.where(leads, pull, other_strength)
    prior = _scores_prior(capture, canonical, strength, window)
    basis = rig.shapes[driven][:, rig_ids]
    mass = None
    if prior is not None:  # a point moved mostly by score-led shapes is read from the scores, not its motion
        energy = (basis ** 2).sum(axis=2)
        led = energy[leads].sum(axis=0) / np.maximum(energy.sum(axis=0), 1e-300)
        mass = np.clip(1.0 - led, 0.0, 1.0)
    solver = RigSolver(basis, prior_strength=strength if prior is not None else None, point_weights=mass,
                       **(settings or {}))
    out = np.empty((len(motion), len(driven)))
    valid = np.asarray(motion.valid)
    for a in range(0, len(motion), chunk):
        b = min(a + chunk, len(motion))
        observed = motion.chunk(a, b)[:, at] @ carry.T
        observed[~valid[a:b]] = np.nan
        out[a:b] = solver(observed, None if prior is None else prior[a:b])
    return out


def read_au_csv(path) -> tuple[dict[str, np.ndarray], float]:
    """AU intensities (0-1) from an OpenFace CSV (``AU12_r``, 0-5) or a py-feat one (``AU12``, 0-1):
    ``({"12": (T,), "12L": ...}, fps)``. Header names are stripped (OpenFace writes ``" AU12_r"``);
    columns other than the AUs' are not read, except ``timestamp`` (seconds; fps from its median
    step, else 30) and ``success`` (a row with 0 holds the previous weights).

    Raises
    ------
    InputError
        The file is missing or cannot be read.
    FileFormatError
        Naming the file and line: not UTF-8, no AU column, a row of the wrong length, a value that is
        not a number, an intensity outside its scale (0-5 for ``_r``, 0-1 otherwise).
    """
    path = Path(path)
    text = read_text(path)
    rows = [r for r in csv.reader(text.splitlines()) if r]
    if not rows:
        raise FileFormatError(path, "is empty")
    header = [cell.strip() for cell in rows[0]]
    columns: dict[str, tuple[int, float]] = {}
    for k, cell in enumerate(header):
        # OpenFace's intensity, 0-5, is a lower-case _r (its AU*_c is presence, not read); AU12_R is a side
        intensity = cell.endswith("_r")
        match = _AU_COLUMN.match(cell[:-2] if intensity else cell)
        if match:
            code = f"{int(match.group(1))}{(match.group(2) or '').upper()}"
            scale = 5.0 if intensity else 1.0
            if code not in columns or scale == 5.0:  # OpenFace's intensity over a plain column
                columns[code] = (k, scale)
    if not columns:
        raise FileFormatError(path, "has no AU column (expected OpenFace's AU12_r or py-feat's AU12), and no "
                                    "Timecode column of a Live Link Face take", line=1)
    lower = [c.lower() for c in header]
    stamp = lower.index("timestamp") if "timestamp" in lower else None
    success = lower.index("success") if "success" in lower else None
    values = np.empty((len(rows) - 1, len(columns)))
    times, ok = [], np.ones(len(rows) - 1, dtype=bool)
    for r, row in enumerate(rows[1:]):
        line = r + 2
        if len(row) != len(header):
            raise FileFormatError(path, f"has {len(row)} cells where the header has {len(header)}", line=line)
        try:
            for j, (k, _scale) in enumerate(columns.values()):
                values[r, j] = float(row[k])
            if stamp is not None:
                times.append(float(row[stamp]))
            if success is not None:
                ok[r] = float(row[success]) > 0
        except ValueError:
            raise FileFormatError(path, "holds a cell that is not a number", line=line) from None
    if not len(values):
        raise FileFormatError(path, "holds no rows")
    for j, (k, scale) in enumerate(columns.values()):
        bad = ~np.isfinite(values[:, j]) | (values[:, j] < -1e-6) | (values[:, j] > scale + 1e-6)
        if bad.any():
            r = int(np.argmax(bad))
            raise FileFormatError(path, f"{header[k]} is {values[r, j]:g}; it must lie in [0, {scale:g}]",
                                  line=r + 2)
    scaled = np.clip(values / [s for _, s in columns.values()], 0.0, 1.0)
    scaled[~ok] = np.nan
    fps = _DEFAULT_FPS
    if len(times) > 1:
        step = float(np.median(np.diff(times)))
        if np.isfinite(step) and step > 0:
            fps = 1.0 / step
    return {code: scaled[:, j] for j, code in enumerate(columns)}, fps


def _held(weights: np.ndarray) -> np.ndarray:
    """NaN rows (no face) hold the row before (zeros before the first)."""
    out = np.array(weights, dtype=np.float64)
    for t in range(len(out)):
        if not np.isfinite(out[t]).all():
            out[t] = out[t - 1] if t else 0.0
    return out


def _write(rig, output, weights: np.ndarray, fps: float) -> DrivenRig:
    from .rig.rigfile import write_rig_animation

    driven = rig.driven
    curves: dict[str, np.ndarray] = {}
    for j, index in enumerate(driven):
        curves.setdefault(rig.canonical[index], weights[:, j])
    count = write_rig_animation(rig.path, output, curves, fps)
    return DrivenRig(tuple(rig.names[j] for j in driven), weights, float(fps), count)


def rig_animation(rig, target, driven: DrivenRig):
    """The rig's mesh (``target``'s, as :func:`~faceanim.inputs.load_target` reads the file) moved by
    the driven weights, streamed: each vertex takes the targets' displacements at the rig vertex in its
    place (a vertex of another mesh of the file keeps still)."""
    from .geometry.animation import Animation

    on, ids = rig.at(target.mesh.vertices)
    shapes = rig.shapes[rig.driven][:, ids] * on[None, :, None]
    rest = target.mesh.vertices
    weights = driven.weights
    return Animation.streamed(target.mesh, lambda a, b: rest + np.einsum("ts,svc->tvc", weights[a:b], shapes),
                              len(weights), driven.fps)


def animate_rig(source, output, *, rig, points=None, fdp=None, neutral=None, smoothing=True, progress=None,
                fap=None, csv_path=None, capture=None, preview=None, obj_sequence=None, write_extra=None):
    """``faceanim animate SOURCE --target RIG.glb`` for a rig with named targets (see the module's
    notes): ``source`` a video, a saved track, a Live Link Face CSV or an AU CSV. Returns
    ``(DrivenRig, FapStream or None)`` (FAPs only for a video). ``preview`` (``.mp4``) and
    ``obj_sequence`` (a folder) are checked here before any work and written by ``write_extra(animation,
    target)`` with the rig's mesh moved by the weights (:func:`rig_animation`)."""
    from .inputs import captured_source, load_target, neutral_window
    from .outputs import SEQUENCE_FOLDER, check_outputs
    from .progress import as_progress
    from .rig.drive import weights_by_name
    from .rig.rigfile import read_rig

    output = Path(output)
    check_outputs({"-o": (output, ".glb"), "--fap": (fap, ".fap"), "--csv": (csv_path, ".csv"),
                   "--preview": (preview, ".mp4"), "--obj-sequence": (obj_sequence, SEQUENCE_FOLDER)},
                  inputs={"SOURCE": source, "--target": rig, "--points": points, "--fdp": fdp})
    extra = (preview is not None or obj_sequence is not None) and write_extra is not None
    shown = as_progress(progress)
    named = read_rig(rig)
    canonical = [named.canonical[j] for j in named.driven]
    if Path(source).suffix.lower() == ".csv":
        if fap is not None or csv_path is not None:
            raise InputError(f"{source}: a CSV of weights carries no FAPs; --fap and --csv need a video")
        with open(source, encoding="utf-8-sig", errors="replace") as handle:
            first = handle.readline()
        if "timecode" in [c.strip().lower() for c in first.split(",")]:
            from .rig.arkit import ARKIT_NAMES
            from .rig.livelink import read_livelink_csv

            take = read_livelink_csv(source)
            weights = weights_by_name(canonical, arkit={n: take.weights[:, k] for k, n in enumerate(ARKIT_NAMES)},
                                      length=len(take))
            fps = take.fps
        else:
            aus, fps = read_au_csv(source)
            length = len(next(iter(aus.values())))
            missing = np.isnan(np.column_stack(list(aus.values()))).any(axis=1)
            weights = weights_by_name(canonical, aus=aus, length=length)
            weights[missing] = np.nan
            weights = _held(weights)
        shown.status(f"writing {output} ({len(weights)} frames on {len(canonical)} named targets)")
        driven = _write(named, output, weights, fps)
        if extra:
            target = load_target(rig, points=points, fdp=fdp, progress=shown)
            write_extra(rig_animation(named, target, driven), target)
        return driven, None
    window = neutral_window(neutral, "animate with a named rig")
    target = load_target(rig, points=points, fdp=fdp, progress=shown)
    if capture is None:
        capture = captured_source(source, neutral=neutral, smoothing=smoothing, progress=shown, folder=output.parent)
    shown.status(f"solving the weights of {len(canonical)} named targets over {len(capture.motion)} frames")
    weights = solve_capture(named, target, capture, window=window)
    stream = None
    if fap is not None or csv_path is not None:
        from .motion import clip_to_range, motion_to_faps

        stream, _ = clip_to_range(motion_to_faps(capture.motion, name=Path(source).stem.replace(" ", "_")))
        if fap is not None:
            from .mpeg4.fapfile import write_fap

            write_fap(fap, stream)
        if csv_path is not None:
            from .export import write_fap_csv

            write_fap_csv(csv_path, stream, times=capture.times, success=capture.valid)
    shown.status(f"writing {output}")
    driven = _write(named, output, weights, capture.fps)
    if extra:
        write_extra(rig_animation(named, target, driven), target)
    return driven, stream


def express_rig(output, recipe: dict, *, rig, frames: int, fps: float) -> DrivenRig:
    """An expression's AU recipe (``{"12": 1.0, "6L": 0.5}``) played on a named rig over ``frames``
    (onset, apex, offset): an AU-named target takes its AU's intensity times the envelope, an
    ARKit-named one the AUs through :data:`~faceanim.rig.drive.FACS_ARKIT` (weights clipped to [0, 1])."""
    from .expressions import envelope
    from .rig.drive import weights_by_name
    from .rig.rigfile import read_rig

    named = read_rig(rig)
    canonical = [named.canonical[j] for j in named.driven]
    shape = envelope(frames)
    weights = weights_by_name(canonical, aus={code: value * shape for code, value in recipe.items()}, length=frames)
    return _write(named, output, weights, fps)
