"""The expression jobs: make an AU recipe or an emotion on a face (``express``), and read AU
intensities from a video (``aus``). Composed from ``synth`` and the other rooms; ``pipeline``
re-exports both.

Two routes put an expression on a target face:

* ``direct`` (the default): the muscles are placed on the target by its own feature points and
  act on its own vertices.
* ``generic``: the seed's route. The expression is made on the generic face (MediaPipe's canonical
  mesh, :mod:`faceanim.generic`), the generic face is registered onto the target through their
  shared feature points (a thin-plate warp, then the dense registration), each target vertex is
  projected onto the registered generic surface and takes the displacement at its landing point
  (:class:`~faceanim.retarget.DenseTransfer`, the P1/P2 projection method done for every vertex at once).

``direct`` is the default: on ICT-FaceKit the cosine of the AU fields with ICT's FACS shapes has
median 0.88 both ways, lowest 0.59 direct and 0.64 through the generic face
(``benchmarks/facs_ict.py``), but the generic face has less surface than the target (no inner lips,
no lid folds, nothing beyond MediaPipe's outline), and the projection can only carry what it has:
the jaw's and chin's AUs (17, 27, 30) read 0.84-0.92 through it against 0.90-0.96 direct.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from .errors import InputError

__all__ = ["express", "aus", "expression_recipe", "ROUTES", "slider_codes", "au_fap_table", "expression_motion",
           "generic_carrier"]

ROUTES = ("direct", "generic")
_SUFFIXES = (".obj", ".glb", ".fap")
FPS_RANGE = (1.0, 1000.0)  # --fps: a .fap holds a whole frame rate (never 0); above 1000 no player keeps up
MAX_FRAMES = 10_000  # --frames: one onset-apex-offset of 6.7 minutes at 25 fps; each frame is made by the muscles


def expression_recipe(*, au=None, emotion=None, intensity=None) -> dict:
    """The AU recipe asked for by ``--au`` or ``--emotion [--intensity]`` (exactly one of the two)."""
    from .synth.emotions import emotion_recipe
    from .synth.facs import parse_recipe

    if (au is None) == (emotion is None):
        raise InputError("give either --au (like 6:0.8,12:1.0) or --emotion (joy, sadness, anger, fear, disgust, "
                         "surprise), not both or neither")
    if au is not None:
        if intensity is not None:
            raise InputError("--intensity scales an --emotion; with --au, write each intensity in the recipe")
        return parse_recipe(au)
    return emotion_recipe(emotion, 1.0 if intensity is None else intensity)


def envelope(frames: int) -> np.ndarray:
    """Onset-apex-offset weights ``(frames,)``: a smooth rise over the first 30%, the apex held over
    the middle 40%, a smooth fall over the last 30% (zero at both ends)."""
    t = np.linspace(0.0, 1.0, frames)
    ramp = np.minimum(np.clip(t / 0.3, 0, 1), np.clip((1 - t) / 0.3, 0, 1))
    return ramp * ramp * (3 - 2 * ramp)  # smoothstep


def slider_codes() -> tuple[str, ...]:
    """The AU codes a model carries as morph targets: both sides together, except the AUs that need
    a side (jaw sideways, wink), which come per side."""
    from .synth.facs import ACTION_UNITS

    return tuple(code for number, au in ACTION_UNITS.items()
                 for code in ((f"{number}L", f"{number}R") if au.needs_side else (str(number),)))


def expression_motion(face, fields: np.ndarray, fps: float, *, at_points: bool = False):
    """A :class:`~faceanim.motion.Motion` of the target's control points under displacement
    ``fields (T, V, 3)`` (or ``(T, P, 3)`` at the target's points, in their order, with
    ``at_points``), in the face frame (MPEG-4 axes, origin between the eyes' corners)."""
    from .motion import Motion

    names = tuple(face.target.points)
    ids = face.target.ids(names)
    origin = 0.5 * (face.point("3.7", "L") + face.point("3.7", "R"))
    neutral = face.local(face.mesh.vertices[ids] - origin)
    displacements = face.local(np.asarray(fields) if at_points else fields[:, ids])
    pose = np.broadcast_to(np.eye(4), (len(fields), 4, 4)).copy()
    return Motion(names, neutral, displacements, pose, fps, face.target.fapu)


def au_fap_table(face, codes, fields) -> dict:
    """``{"AU12": {"12": value, ...}}``: the FAPs each AU at intensity 1 makes on this face (what
    the viewer mixes into a ``.fap``)."""
    from .motion import motion_to_faps

    stream = motion_to_faps(expression_motion(face, fields, 25.0))
    table = {}
    for k, code in enumerate(codes):
        used = stream.mask[k] & (np.abs(stream.values[k]) >= 1)
        table[f"AU{code}"] = {str(j + 1): int(round(stream.values[k, j])) for j in np.flatnonzero(used)
                              if j >= 2 and j not in (47, 48, 49)}  # no head rotation in an expression
    return table


def generic_carrier(target, named: str = "the target"):
    """The generic face and the map carrying its displacements onto ``target`` (warp + projection);
    ``named``, where the target's points come from, for the errors."""
    from .generic import generic_target
    from .retarget.transfer import ControlPairs, DenseTransfer
    from .synth import MuscleFace

    source = generic_target()
    shared = [n for n in source.points if n in target.points and not n.startswith("mp")]
    if len(shared) < 8:
        raise InputError(f"the generic route needs the target's MPEG-4 feature points; it shares only "
                         f"{len(shared)} with the generic face")
    ids = target.ids(shared)
    vertices, counts = np.unique(ids, return_counts=True)
    if (counts > 1).any():  # the generic face's points are distinct: two of them cannot land on one vertex
        vertex = vertices[counts > 1][0]
        names = " and ".join(n for n, i in zip(shared, ids, strict=True) if i == vertex)
        raise InputError(f"{named}: the generic route needs each feature point on its own vertex; {names} share "
                         f"vertex {vertex}")
    pairs = ControlPairs.checked(source.ids(shared), target.ids(shared), len(source.mesh.vertices),
                                 len(target.mesh.vertices))
    return MuscleFace(source), DenseTransfer(source.mesh, target.mesh, pairs)


def _target_fields(target, recipe, frames, route, named: str = "the target"):
    """The target's displacement per frame as ``fields(start, stop) -> (stop - start, V, 3)``, the
    number of frames (1 for a still), the recipe made at the apex (after the exaggeration guard,
    which warns once there), and the target as a muscle face. Frames are made when asked for, so
    a long expression is never held whole."""
    from .synth import MuscleFace
    from .synth.expression import synthesise

    target_face = MuscleFace(target)
    if route == "direct":
        face, carry = target_face, None
    else:
        face, carry = generic_carrier(target, named)
    apex, made = synthesise(face, recipe)
    weights = np.ones(1) if frames is None else envelope(frames)

    def field(w: float) -> np.ndarray:  # every frame made, not blended, so the jaw and lids turn on arcs
        made_here = apex if w == 1.0 else synthesise(face, {k: v * w for k, v in made.items()})[0]
        return made_here if carry is None else carry(made_here)

    def fields(start: int, stop: int) -> np.ndarray:
        return np.stack([field(w) for w in weights[start:stop]])

    return fields, len(weights), made, target_face


def express(output, *, au=None, emotion=None, intensity=None, target_mesh=None, points=None, fdp=None,
            frames=None, fps: float = 25.0, route: str = "direct", target=None, progress=None, force: bool = False):
    """``faceanim express``: an AU recipe or an emotion on a target face, written as ``.obj`` (the
    still face), ``.glb`` (still, or onset-apex-offset over ``frames``, 3 to :data:`MAX_FRAMES`, at
    ``fps`` in :data:`FPS_RANGE`; with every AU as a named morph target) or ``.fap``. ``progress``, a
    :class:`~faceanim.progress.Progress`, shows the long steps (quiet when None); ``force`` replaces an
    ``.obj``'s material and texture even where faceanim did not write them. Returns ``(animation, recipe
    made)``: the target's :class:`~faceanim.geometry.animation.Animation` (one frame for a still;
    streamed, so its frames are made again when read). With ``frames`` and a ``target_mesh`` ``.glb``
    whose morph targets carry AU or ARKit names, the rig's own sliders are animated instead
    (:func:`faceanim.driving.express_rig`: the recipe's intensities times the onset-apex-offset
    envelope, through :data:`~faceanim.rig.drive.FACS_ARKIT` for ARKit names) and a
    :class:`~faceanim.driving.DrivenRig` stands in for the animation."""
    from .export import MorphSet, morphs_from_animation, write_glb
    from .geometry import write_mesh
    from .geometry.animation import Animation, spilled
    from .inputs import load_target, target_unit
    from .mpeg4.fapfile import write_fap
    from .outputs import check_outputs
    from .progress import as_progress
    from .synth.expression import au_fields

    output = Path(output)
    check_outputs({"-o": (output, _SUFFIXES)}, inputs={"--target": target_mesh, "--points": points, "--fdp": fdp},
                  force=force)
    if route not in ROUTES:
        raise InputError(f"--route must be one of {', '.join(ROUTES)}, got {route!r}")
    low, high = FPS_RANGE
    if isinstance(fps, bool) or not isinstance(fps, (int, float, np.number)) or not low <= fps <= high:
        raise InputError(f"--fps must be a number from {low:g} to {high:g}, got {fps!r}")
    if frames is not None and (isinstance(frames, bool) or not isinstance(frames, (int, float, np.number))
                               or not 3 <= frames <= MAX_FRAMES or int(frames) != frames):
        raise InputError(f"--frames must be a whole number from 3 to {MAX_FRAMES}, got {frames!r}")
    if output.suffix.lower() == ".fap" and fps != round(fps):
        warnings.warn(f"--fps {fps:g} is written to the .fap as {round(fps)}: the format holds whole frame rates",
                      stacklevel=2)
    if frames is not None and output.suffix.lower() == ".obj":
        raise InputError(f"{output}: an OBJ holds one still face; write .glb or .fap for --frames")
    recipe = expression_recipe(au=au, emotion=emotion, intensity=intensity)
    if frames is not None and output.suffix.lower() == ".glb" and target is None:
        from .driving import express_rig, is_named_rig

        if is_named_rig(target_mesh):  # a rig's own AU / ARKit sliders are driven, not vertex motion baked
            return express_rig(output, recipe, rig=target_mesh, frames=int(frames), fps=float(fps)), recipe
    shown = as_progress(progress)
    target = target or load_target(target_mesh, points=points, fdp=fdp, progress=shown)
    if output.suffix.lower() == ".glb":  # refused now, not after the muscles' work, if of no human size
        unit = target_unit(target, str(target_mesh) if target_mesh is not None else "the target")
    named = next((str(p) for p in (points, fdp, target_mesh) if p is not None), "the target")
    fields, count, made, face = _target_fields(target, recipe, None if frames is None else int(frames), route, named)
    rest = target.mesh.vertices
    animation = Animation.streamed(target.mesh, lambda a, b: rest + fields(a, b), count, fps)
    suffix = output.suffix.lower()
    with spilled(animation, folder=output.parent, progress=shown if frames is not None else None,
                 desc="making the expression") as kept:
        if suffix == ".obj":
            write_mesh(output, target.mesh.with_vertices(kept.chunk(0, 1)[0]), force=force)
        elif suffix == ".fap":
            from .motion import clip_to_range, motion_to_faps

            ids = target.ids(list(target.points))
            at_points = np.concatenate([chunk[:, ids] - rest[ids] for chunk in kept.chunks()])
            motion = expression_motion(face, at_points, fps, at_points=True)
            stream, _ = clip_to_range(motion_to_faps(motion, name=output.stem or "faceanim"))
            write_fap(output, stream)
        else:
            codes = slider_codes()
            shown.status(f"writing {output} with {len(codes)} AU sliders as morph targets")
            sliders = au_fields(face, codes)
            if frames is None:
                morphs = MorphSet(np.concatenate([kept.chunk(0, 1) - rest, sliders]),
                                  ("expression", *(f"AU{c}" for c in codes)),
                                  default_weights=np.r_[1.0, np.zeros(len(codes))])
            else:
                animated = morphs_from_animation(kept)
                weights = np.hstack([animated.weights, np.zeros((count, len(codes)))])
                names = (*animated.names, *(f"AU{c}" for c in codes))
                morphs = MorphSet(np.concatenate([animated.targets, sliders]), names, weights, fps)
            from .synth.facs import recipe_text

            write_glb(output, target.mesh, morphs, extras={"points": dict(target.points), "recipe": recipe_text(made),
                                                           "au_faps": au_fap_table(face, codes, sliders)},
                      metres_per_unit=unit)
    return animation, made


def aus(video, output, *, neutral=None, smoothing=True, progress=None, capture=None):
    """``faceanim aus``: per-frame FACS AU intensities of a video (or a saved ``.npz`` track), as
    OpenFace 2.2's CSV (``frame, face_id, timestamp, confidence, success, pose_R*, AU*_r, AU*_c``; see
    :mod:`faceanim.export.curves`), timed by the video's own presentation times. Returns ``(AU numbers,
    (T, A) intensities on the 0-1 scale)`` (the CSV's ``AU*_r`` are these times 5, at most 5).
    ``capture``, the :class:`~faceanim.capture.stream.Capture` of ``video`` already made, stands in
    for tracking it again."""
    from .capture.smoothing import OneEuro, one_euro
    from .export.curves import openface_pose, write_au_csv
    from .generic import landmark_target
    from .inputs import captured_source
    from .motion import rotation_part
    from .outputs import check_outputs
    from .progress import as_progress
    from .synth import MuscleFace
    from .synth.fitting import AuFitter, bilateral

    output = Path(output)
    check_outputs({"-o": (output, ".csv")}, inputs={"VIDEO": video, "--neutral": neutral})
    recorded = capture or captured_source(video, neutral=neutral, smoothing=smoothing, progress=as_progress(progress),
                                          folder=output.parent)  # the landmarks on disk: memory flat in length
    motion = recorded.motion
    face = MuscleFace(landmark_target(motion.neutral[:468]))
    fitter = AuFitter(face, motion.names[:468])
    values = fitter.read_motion(motion)
    if smoothing:
        values = np.clip(one_euro(values[:, :, None], recorded.times, OneEuro(min_cutoff=2.0, beta=0.5))[:, :, 0],
                         0, 2)
    numbers, table = bilateral(fitter.codes, values)
    pose = openface_pose(rotation_part(motion.pose))
    write_au_csv(output, numbers, table, recorded.times, recorded.valid & motion.valid, pose=pose)
    return numbers, table
