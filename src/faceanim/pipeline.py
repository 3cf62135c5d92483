"""The jobs a person runs, composed from the rooms. Each reads its inputs, checks them against
each other, computes, and writes its output completely or not at all."""

from __future__ import annotations

import signal
import warnings
from pathlib import Path

import numpy as np

from .errors import FileFormatError, InputError
from .expressions import aus, express  # the expression jobs live in their own module; re-exported here
from .geometry import read_mesh, write_mesh
from .geometry.animation import spilled
from .inputs import capture_motion, captured_source, load_target, motion_of_track, neutral_window, target_unit  # noqa: F401 (capture_motion, motion_of_track re-exported)
from .jsonfile import read_json
from .outputs import SEQUENCE_FOLDER, check_outputs
from .retarget import REGIONS, ControlPairs, region_mask, transfer_expression

__all__ = ["transfer", "read_pairs", "read_vertex_mask", "track", "encode", "fap_info", "avatar",
           "load_target", "decode", "animate", "view", "express", "aus"]


def _is_id(value, upper: int = 2**63) -> bool:
    """Whether a JSON value is a vertex id: an integer (not a boolean) in ``[0, upper)``."""
    return isinstance(value, int) and not isinstance(value, bool) and 0 <= value < upper


def read_pairs(path) -> tuple[np.ndarray, np.ndarray]:
    """Read a correspondence file ``{"source": [ids], "target": [ids]}``: two ``(K,) int64`` arrays of
    vertex ids, ``K >= 1`` (checked against the meshes by :meth:`ControlPairs.checked`).

    Raises
    ------
    InputError
        The file is missing or cannot be read.
    FileFormatError
        Not UTF-8 JSON, not such an object, an id that is not a whole number from 0 (``true``,
        ``1.5``, ``-1``, ``2**70``), lists of different lengths, or no pairs.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    data = read_json(path)
    if not isinstance(data, dict) or not {"source", "target"} <= data.keys():
        raise FileFormatError(path, 'must be an object with "source" and "target" lists of vertex ids')
    lists = []
    for key in ("source", "target"):
        ids = data[key]
        if not isinstance(ids, list) or not all(_is_id(i) for i in ids):
            raise FileFormatError(path, f'"{key}" must be a list of integer vertex ids from 0')
        lists.append(np.asarray(ids, dtype=np.int64))
    if len(lists[0]) != len(lists[1]):
        counts = f'"source" has {len(lists[0])} ids but "target" has {len(lists[1])}'
        raise FileFormatError(path, f"{counts}; they must pair up")
    if not len(lists[0]):
        raise FileFormatError(path, "holds no pairs")
    return lists[0], lists[1]


def read_vertex_mask(path, vertex_count: int) -> np.ndarray:
    """Read a vertex mask file, a JSON list of vertex ids: ``(vertex_count,) bool``, True at those ids
    (an id may repeat; an empty list allows no vertex).

    Raises
    ------
    InputError
        The file cannot be read.
    FileFormatError
        Not UTF-8 JSON, not a list, or an id that is not an integer in ``[0, vertex_count)``.
    """
    ids = read_json(path)
    if not isinstance(ids, list) or not all(_is_id(i, vertex_count) for i in ids):
        raise FileFormatError(path, f"must be a JSON list of target vertex ids in [0, {vertex_count})")
    allowed = np.zeros(vertex_count, dtype=bool)
    allowed[ids] = True
    return allowed


def _check_clone_pairs(source, ids, correspondence) -> None:
    """The clone method first warps the source onto the target through the pairs (thin-plate, with an
    affine part): it needs at least 4 of them, at distinct places on the source, not all in one plane."""
    from .geometry import RbfWarp

    if len(ids) < 4:
        raise InputError(f"{correspondence}: the clone method needs at least 4 pairs, got {len(ids)} "
                         "(--method rbf takes fewer)")
    try:  # the warp the registration starts from, made once here on the control points alone
        RbfWarp(source.vertices[ids], np.zeros((len(ids), 3)), kernel="thin_plate")
    except ValueError as exc:  # finite (K, 3) points, K >= 4: only coincident or flat control points are left
        raise InputError(f"{correspondence}: the source's control points cannot start the clone method's warp "
                         f"({exc}; pairs counted from 0)") from None


def transfer(source_neutral, source_expression, target, output, *, correspondence, method: str = "clone",
             mask=None, regions: tuple[str, ...] = (), force: bool = False) -> Path:
    """``faceanim transfer``: write ``target`` wearing the source's expression to ``output``.

    Parameters
    ----------
    source_neutral, source_expression, target, output : path
        Mesh files (.obj, .ply, .glb; output .obj, .ply or .glb).
    correspondence : path
        JSON pairs file, see :func:`read_pairs`.
    method : {"clone", "rbf"}
    mask : path, optional
        JSON list of target vertex ids allowed to move.
    regions : tuple of str
        Face regions allowed to move (needs 68 pairs in the iBUG / Multi-PIE order).
    force : bool
        Replace an ``.obj`` output's material and texture even where faceanim did not write them.
    """
    output = Path(output)
    check_outputs({"-o": (output, (".obj", ".ply", ".glb"))}, force=force, inputs={
        "SRC_NEUTRAL": source_neutral, "SRC_EXPRESSION": source_expression, "TARGET_NEUTRAL": target,
        "--correspondence": correspondence, "--mask": mask})
    src0, src1, dst = read_mesh(source_neutral), read_mesh(source_expression), read_mesh(target)
    if len(src1.vertices) != len(src0.vertices):
        raise InputError(f"{source_expression}: has {len(src1.vertices)} vertices but {source_neutral} has "
                         f"{len(src0.vertices)}; the source expression must be the same mesh as its neutral")
    source_ids, target_ids = read_pairs(correspondence)
    try:
        pairs = ControlPairs.checked(source_ids, target_ids, len(src0.vertices), len(dst.vertices))
    except ValueError as exc:
        raise InputError(f"{correspondence}: {exc}") from None
    if method == "clone":
        _check_clone_pairs(src0, pairs.source, correspondence)
    allowed = None
    if mask is not None:
        allowed = read_vertex_mask(mask, len(dst.vertices))
    if regions:
        unknown = [r for r in regions if r not in REGIONS]
        if unknown:
            raise InputError(f"unknown region {unknown[0]!r}; regions are {', '.join(REGIONS)}")
        if len(pairs.target) != 68:
            raise InputError(f"--region needs the 68 pairs of the iBUG / Multi-PIE layout, got {len(pairs.target)}")
        in_region = region_mask(dst.vertices, dst.vertices[pairs.target], regions)
        allowed = in_region if allowed is None else allowed & in_region
    result = transfer_expression(src0, src1, dst, pairs, method=method, mask=allowed)
    write_mesh(output, result, force=force)
    return output


# ---- capture: video -> Track -> Motion -> FAPs


def track(video, output, *, overlay=None, csv=None, start_face: str = "largest", model=None, options=None,
          progress=None):
    """``faceanim track``: track the face through ``video``; write the Track (``.npz``), and optionally
    an overlay video and a CSV of landmark pixels (see :mod:`faceanim.export.curves` for the columns).
    ``start_face`` (largest, left, right): with several faces, which one to follow; ``options``, a
    :class:`~faceanim.capture.tracker.TrackerOptions`, stands in for it with every setting. Returns the Track."""
    from .capture.headframe import head_frame
    from .capture.overlay import overlay_frames
    from .capture.track import track_video
    from .capture.tracker import TrackerOptions
    from .progress import as_progress
    from .render.video import video_writer

    output = Path(output)
    check_outputs({"-o": (output, ".npz"), "--overlay": (overlay, ".mp4"), "--csv": (csv, ".csv")},
                  inputs={"VIDEO": video, "--model": model})
    shown = as_progress(progress)
    result = track_video(video, options=options or TrackerOptions(start_face=start_face), progress=shown,
                         model=model)
    result.save(output)
    if overlay is not None:
        _, pose = head_frame(result)
        with video_writer(overlay, result.fps, result.width, result.height) as write:
            for frame in shown.bar(overlay_frames(result, pose), total=len(result), desc="drawing the overlay"):
                write(frame)
    if csv is not None:
        from .export.curves import write_landmark_csv

        write_landmark_csv(csv, result)
    return result


def encode(source, output, *, neutral=None, smoothing=True, progress=None, capture=None):
    """``faceanim encode``: video or track -> ``.fap``. Returns (stream, number of clipped values).
    ``capture``, the :class:`~faceanim.capture.stream.Capture` of ``source`` already made (batch makes
    one per video for all its steps), stands in for tracking it again."""
    from .motion import clip_to_range, motion_to_faps
    from .mpeg4.fapfile import write_fap

    output = Path(output)
    check_outputs({"-o": (output, ".fap")}, inputs={"VIDEO_OR_TRACK": source, "--neutral": neutral})
    if capture is None:  # the landmarks on disk: memory flat in length
        capture = captured_source(source, neutral=neutral, smoothing=smoothing, progress=progress,
                                  folder=output.parent)
    stream, clipped = clip_to_range(motion_to_faps(capture.motion,
                                                   name=Path(source).stem.replace(" ", "_") or "faceanim"))
    write_fap(output, stream)
    return stream, clipped


def fap_info(path) -> str:
    """``faceanim fap-info``: a summary of a ``.fap`` file (frames, fps, active FAPs, ranges, and
    every value outside its MPEG-4 range)."""
    from .mpeg4 import fap_table
    from .mpeg4.fapfile import read_fap
    from .mpeg4.fapstream import fap_ranges

    stream = read_fap(path)
    table = fap_table()
    low, high = fap_ranges()
    active = np.flatnonzero(stream.mask.any(axis=0))
    outside = stream.out_of_range()
    lines = [f"{path}: {len(stream)} frames at {stream.fps:g} fps ({len(stream) / stream.fps:.2f} s), "
             f"name {stream.name}, {len(active)} active FAPs, {int(outside.sum())} values out of range"]
    lines.append(f"{'FAP':>4} {'name':<22} {'unit':<5} {'frames':>6} {'min':>9} {'max':>9}  range")
    for j in active:
        present = stream.mask[:, j]
        if j < 2:
            lines.append(f"{j + 1:>4} {table.names[j]:<22} {'-':<5} {int(present.sum()):>6}")
            continue
        v = stream.values[present, j]
        flag = f"  {int(outside[:, j].sum())} out of range" if outside[:, j].any() else ""
        lines.append(f"{j + 1:>4} {table.names[j]:<22} {table.units[j]:<5} {int(present.sum()):>6} {v.min():>9.0f} "
                     f"{v.max():>9.0f}  [{low[j]:g}, {high[j]:g}]{flag}")
    return "\n".join(lines)


# ---- animating a target: FAPs or a video -> Animation -> glTF (and a preview video)


def avatar(photo, output):
    """``faceanim avatar``: a textured 3D face from a portrait, written as a ``.glb`` that carries its
    control points (so it animates without placement). Returns the Target."""
    from .export import write_glb
    from .mpeg4 import metres_per_unit
    from .portrait import avatar_target

    output = Path(output)
    check_outputs({"-o": (output, ".glb")}, inputs={"PHOTO": photo})
    target = avatar_target(photo)
    write_glb(output, target.mesh, extras={"points": dict(target.points)}, metres_per_unit=metres_per_unit(target.fapu))
    return target


def _write_extra_outputs(animation, stream, obj_sequence, csv, progress, recorded=None) -> None:
    """The ``--csv`` FAP curves (timed by the video's own presentation times where a Track ``recorded``
    is given) and the ``--obj-sequence``."""
    from .export import write_fap_csv, write_obj_sequence

    if csv is not None:
        timing = {} if recorded is None else {"times": recorded.times, "success": recorded.valid}
        write_fap_csv(csv, stream, **timing)
    if obj_sequence is not None:
        progress.status(f"writing {len(animation)} OBJ files into {obj_sequence}")
        write_obj_sequence(obj_sequence, animation)


def _write_glb(path, animation, unit: float) -> None:
    """``animation`` as a ``.glb``, in metres (``unit``: metres per model unit, see
    :func:`~faceanim.inputs.target_unit`)."""
    from .export import morphs_from_animation, write_glb

    write_glb(path, animation.mesh, morphs_from_animation(animation), metres_per_unit=unit)


def _letterbox(image: np.ndarray, size: int) -> np.ndarray:
    """``image`` scaled to fit a black ``size`` x ``size`` square, centred, nothing cut off."""
    from PIL import Image

    h, w = image.shape[:2]
    scale = size / max(h, w)
    fitted = np.asarray(Image.fromarray(image).resize((max(1, round(w * scale)), max(1, round(h * scale)))))
    canvas = np.zeros((size, size, 3), np.uint8)
    top, left = (size - fitted.shape[0]) // 2, (size - fitted.shape[1]) // 2
    canvas[top:top + fitted.shape[0], left:left + fitted.shape[1]] = fitted
    return canvas


def _preview(path, animation, target, progress, *, source_frames=None, size: int = 480) -> None:
    """Render the animated target (textured when it has a texture), beside the source frames if given."""
    from .render.camera import front_camera
    from .render.rasterizer import Renderer
    from .render.video import video_writer

    face = animation.mesh.vertices[target.ids(list(target.points))]
    camera = front_camera(face, size, size, vertical_fov=20.0, margin=1.25)
    mode = "textured" if animation.mesh.texture is not None else "shaded"
    width = size * (2 if source_frames is not None else 1)
    source = iter(source_frames) if source_frames is not None else None
    with Renderer(size, size) as renderer, video_writer(path, animation.fps, width, size) as write:
        for positions in progress.bar(animation.frames(), total=len(animation), desc="rendering the preview"):
            frame = renderer.render(animation.mesh, camera, positions=positions, mode=mode)
            if source is not None:
                left = next(source, None)
                canvas = np.zeros_like(frame) if left is None else _letterbox(left, size)
                frame = np.hstack([canvas, frame])
            write(frame)


def _beside(main, other, progress):
    """``(main(), other(progress))``, ``other`` run in a thread meanwhile: the video's tracking keeps
    one core busy (MediaPipe's graph, frame after frame) while the target's placement and parts can
    take another. An error of ``main`` (a bad ``--parts`` file, a face of no human size), or an
    interrupt while ``other`` is waited for, stops ``other`` at its next frame and is raised;
    ``other``'s own error is raised once ``main`` is done."""
    from concurrent.futures import ThreadPoolExecutor

    stop: list[int] = []
    pool = ThreadPoolExecutor(1, thread_name_prefix="faceanim")
    try:
        running = pool.submit(other, progress.stopped_by(stop))
        done = main()
        return done, running.result()
    except BaseException as error:
        stop.append(getattr(error, "signum", signal.SIGINT))
        raise
    finally:
        pool.shutdown(wait=True)


def _workers(workers) -> int:
    """The processes a job deforms its frames with (:func:`~faceanim.geometry.animation.worker_count`),
    a bad number refused as the job's input, before any work."""
    from .geometry.animation import worker_count

    try:
        return worker_count(workers)
    except ValueError:
        raise InputError(f"--workers must be a whole number from 1, got {workers!r}") from None


def _ready_target(target, mesh_path, points, fdp, parts, progress):
    """The target (a ready one, or loaded from its files), its parts and its unit (metres per model
    unit), all told before any long work: a bad ``--parts`` file, parts that cannot be told apart or a
    face of no human size are refused at once, naming the target."""
    from .parts import face_parts, read_parts_file

    labels = None if parts is None else read_parts_file(parts)
    if mesh_path is not None:
        name = str(mesh_path)
    else:
        name = "the target" if target is not None else "the avatar"
    target = target or load_target(mesh_path, points=points, fdp=fdp, progress=progress)
    return target, face_parts(target, labels=labels, source=name), target_unit(target, name)


def decode(fap_path, output, *, target_mesh=None, points=None, fdp=None, preview=None, head_motion=False,
           target=None, obj_sequence=None, csv=None, progress=None, parts=None, speaker=None, workers=None):
    """``faceanim decode``: a ``.fap`` file onto a target mesh, written as an animated ``.glb``.
    ``target``, a ready :class:`~faceanim.target.Target`, stands in for the mesh and its points;
    ``progress``, a :class:`~faceanim.progress.Progress`, shows the long steps (quiet when None);
    ``parts``, a ``PARTS.json`` (see :func:`~faceanim.parts.read_parts_file`), labels the target's parts
    where its file and its geometry do not tell them apart; ``speaker``, a speaker model file
    (``faceanim speaker build``), interprets the stream first
    (:meth:`~faceanim.speaker.SpeakerModel.regularise`); ``workers``, the processes deforming the frames
    (default :func:`~faceanim.geometry.animation.worker_count`). Returns the streamed
    :class:`~faceanim.geometry.animation.Animation`: reading its frames deforms them again."""
    from .mpeg4.fapfile import read_fap
    from .progress import as_progress
    from .retarget.decode import animate_faps

    output = Path(output)
    check_outputs({"-o": (output, ".glb"), "--preview": (preview, ".mp4"), "--csv": (csv, ".csv"),
                   "--obj-sequence": (obj_sequence, SEQUENCE_FOLDER)},
                  inputs={"FILE.fap": fap_path, "--target": target_mesh, "--points": points, "--fdp": fdp,
                          "--parts": parts, "--speaker": speaker})
    workers = _workers(workers)
    shown = as_progress(progress)
    stream = read_fap(fap_path)
    if speaker is not None:
        from .speaker import read_speaker, refusals_named

        model = read_speaker(speaker)
        with refusals_named(fap_path, speaker):
            stream = model.regularise(stream)
    target, pieces, unit = _ready_target(target, target_mesh, points, fdp, parts, shown)
    shown.status(f"playing {len(stream)} frames of FAPs on the target ({len(target.mesh.vertices):,} vertices)")
    animation = animate_faps(stream, target, head_motion=head_motion, parts=pieces)
    with spilled(animation, folder=output.parent, progress=shown, workers=workers) as kept:  # deformed once
        shown.status(f"writing {output} ({len(animation)} frames as morph targets)")
        _write_glb(output, kept, unit)
        _write_extra_outputs(kept, stream, obj_sequence, csv, shown)
        if preview is not None:
            _preview(preview, kept, target, shown)
    return animation


def _named_rig_route(source, target_mesh, target, head_motion, via) -> bool:
    """Whether ``animate`` drives a named rig (a CSV of weights, or a ``--target`` ``.glb`` whose morph
    targets carry ARKit or AU names; see :mod:`faceanim.driving`), refusing at once what that route
    does not do."""
    from .driving import is_named_rig
    from .rig.drive import EXPECTED_NAMES

    weights = Path(source).suffix.lower() == ".csv"
    if not weights and (target is not None or not is_named_rig(target_mesh)):
        return False
    if target_mesh is None:
        raise InputError(f"{source}: a CSV of weights drives a rig: give --target a .glb whose morph targets carry "
                         f"{EXPECTED_NAMES}")
    for given, option in ((head_motion, "--head-motion"), (via != "motion", "--via faps")):
        if given:
            raise InputError(f"{target_mesh}: a named rig is animated through its own morph weights; {option} is "
                             "not available with it")
    return True


def animate(video, output, *, target_mesh=None, points=None, fdp=None, preview=None, fap=None, head_motion=False,
            progress=None, neutral=None, target=None, obj_sequence=None, csv=None, via="motion", smoothing=True,
            parts=None, capture=None, workers=None):
    """``faceanim animate``: a video of a face drives a target mesh. ``target``, a ready
    :class:`~faceanim.target.Target`, stands in for the mesh and its points. ``neutral``: the frames
    at rest (``FRAME`` or ``START:END``; found automatically when None); ``smoothing``: the One Euro filter.

    ``via="motion"`` follows the tracked Motion directly (every point the target shares, in 3D);
    a target sharing too few points (a JSON file of other names) falls back to the FAPs, with a
    warning. ``via="faps"`` plays the FAP stream, as ``decode`` would play the ``.fap`` file.
    ``progress``, a :class:`~faceanim.progress.Progress`, shows the long steps (quiet when None).
    ``capture``, the :class:`~faceanim.capture.stream.Capture` of ``video`` already made, stands in
    for tracking it again. ``workers``: the processes deforming the frames (default
    :func:`~faceanim.geometry.animation.worker_count`). Returns ``(animation, stream)``: the streamed
    :class:`~faceanim.geometry.animation.Animation` (reading its frames deforms them again) and the FAPs.

    A ``target_mesh`` ``.glb`` whose morph targets carry ARKit or FACS AU names is a named rig: its own
    targets are animated instead (:func:`faceanim.driving.animate_rig`; ``video`` may then also be a Live
    Link Face or AU CSV), and ``(DrivenRig, stream or None)`` is returned."""
    from .capture.overlay import overlay_frames
    from .motion import clip_to_range, motion_to_faps
    from .mpeg4.fapfile import write_fap
    from .progress import as_progress
    from .retarget.decode import animate_faps
    from .retarget.follow import MINIMUM_SHARED_POINTS, animate_motion, shared_points

    if via not in ("motion", "faps"):
        raise InputError(f"via must be motion or faps, got {via!r}")
    workers = _workers(workers)
    rig_route = _named_rig_route(video, target_mesh, target, head_motion, via)
    if rig_route:
        from .driving import animate_rig
        from .export import write_obj_sequence
        from .progress import as_progress

        def write_extra(animation, target):  # the rig's mesh moved by its weights: a preview, OBJ files
            with spilled(animation, folder=Path(output).parent, progress=as_progress(progress),
                         workers=workers) as kept:
                if obj_sequence is not None:
                    write_obj_sequence(obj_sequence, kept)
                if preview is not None:
                    _preview(preview, kept, target, as_progress(progress))

        return animate_rig(video, output, rig=target_mesh, points=points, fdp=fdp, neutral=neutral,
                           smoothing=smoothing, progress=progress, fap=fap, csv_path=csv, capture=capture,
                           preview=preview, obj_sequence=obj_sequence, write_extra=write_extra)
    output = Path(output)
    check_outputs({"-o": (output, ".glb"), "--fap": (fap, ".fap"), "--preview": (preview, ".mp4"),
                   "--csv": (csv, ".csv"), "--obj-sequence": (obj_sequence, SEQUENCE_FOLDER)},
                  inputs={"VIDEO": video, "--target": target_mesh, "--points": points, "--fdp": fdp, "--parts": parts})
    neutral_window(neutral, "animate")  # said before any work is done
    shown = as_progress(progress)

    def ready():
        return _ready_target(target, target_mesh, points, fdp, parts, shown)

    # The landmarks and the motion stay in unnamed temporary files beside the output (freed with the
    # animation returned): memory does not grow with the video's length.
    if capture is None:
        (target, pieces, unit), capture = _beside(ready, lambda shown_there: captured_source(
            video, neutral=neutral, smoothing=smoothing, progress=shown_there, folder=output.parent), shown)
    else:
        target, pieces, unit = ready()
    motion = capture.motion
    stream, _ = clip_to_range(motion_to_faps(motion, name=Path(video).stem.replace(" ", "_")))
    if via == "motion" and len(shared_points(motion, target)) < MINIMUM_SHARED_POINTS:
        warnings.warn(f"the target shares only {len(shared_points(motion, target))} control points with the tracker; "
             "it is driven through the FAPs instead", stacklevel=2)
        via = "faps"
    shown.status(f"{'following the tracked motion' if via == 'motion' else 'playing the FAPs'} on the target "
                 f"({len(target.mesh.vertices):,} vertices)")
    if via == "motion":
        animation = animate_motion(motion, target, head_motion=head_motion, gaze=stream, parts=pieces)
    else:
        animation = animate_faps(stream, target, head_motion=head_motion, parts=pieces)
    with spilled(animation, folder=output.parent, progress=shown, workers=workers) as kept:  # deformed once
        shown.status(f"writing {output} ({len(animation)} frames as morph targets)")
        _write_glb(output, kept, unit)
        _write_extra_outputs(kept, stream, obj_sequence, csv, shown, capture)
        if fap is not None:
            write_fap(fap, stream)
        if preview is not None:
            _preview(preview, kept, target, shown, source_frames=overlay_frames(capture, motion.pose))
    return animation, stream


# ---- looking at the result: the web viewer


def view(model, *, video=None, fap=None, port: int = 8765):
    """``faceanim view``: check the files, then return the (not yet serving) viewer server for them.

    Every input is checked before the server exists, so a bad file or a busy port is a one-line error
    and nothing is left listening."""
    from .capture.video import open_frames
    from .geometry.meshio import read_glb_json
    from .mpeg4.fapfile import read_fap
    from .viewer import ViewerFiles, ViewerServer, fap_curves

    model = Path(model)
    if model.suffix.lower() != ".glb":
        raise InputError(f"{model}: the viewer shows binary glTF (.glb) files")
    if not model.is_file():
        raise InputError(f"{model}: no such file")
    if not read_glb_json(model).get("meshes"):
        raise InputError(f"{model}: holds no mesh to show")
    if not 0 <= int(port) <= 65535:
        raise InputError(f"--port must be between 0 and 65535, got {port}")
    if video is not None:
        video = Path(video)
        with open_frames(video) as frames:
            if next(iter(frames), None) is None:
                raise InputError(f"{video}: holds no frames")
    curves = fap_curves(read_fap(fap), name=Path(fap).name) if fap is not None else None
    return ViewerServer(ViewerFiles(model, video, curves, title=model.stem), port=int(port))
