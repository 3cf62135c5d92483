"""What the jobs read: a `Target` from the files a person names, and a `Motion` from a video or a
saved track. ``pipeline`` and ``expressions`` both use these (``pipeline`` re-exports them), so
neither of the two job modules imports the other."""

from __future__ import annotations

import sys
from pathlib import Path

from .errors import InputError
from .geometry import read_mesh

__all__ = ["load_target", "capture_motion", "captured_source", "motion_of_track", "neutral_window", "target_unit"]


def load_target(mesh_path=None, *, points=None, fdp=None, progress=None):
    """A Target from a mesh file and its control points, taken from, in order: a JSON file, an Xface
    ``.fdp``, the points a faceanim ``.glb`` carries, automatic placement (render, track, cast back).
    With no mesh, the avatar of the embedded portrait (see :func:`avatar_target`). ``progress``
    (a :class:`~faceanim.progress.Progress`) is told of the avatar or the placement."""
    from .geometry.meshio import glb_extras
    from .portrait import avatar_target
    from .progress import as_progress
    from .retarget.placement import auto_target
    from .target import Target, target_from_fdp, target_from_json

    if points is not None and fdp is not None:
        raise InputError("give the control points once: --points or --fdp, not both")
    if mesh_path is None:
        if points is not None or fdp is not None:
            raise InputError("--points and --fdp describe a --target mesh; give the mesh too")
        as_progress(progress).status("making the avatar of the embedded portrait (no --target given)")
        return avatar_target()
    mesh = read_mesh(mesh_path)
    _check_extent(mesh, mesh_path)
    if points is not None:
        return target_from_json(mesh, points)
    if fdp is not None:
        return target_from_fdp(mesh, fdp)
    carried = glb_extras(mesh_path).get("points")
    if isinstance(carried, dict):
        return Target.from_points(mesh, carried, source=str(mesh_path))
    as_progress(progress).status(f"placing control points on {Path(mesh_path).name} (rendered, tracked, cast back)")
    return auto_target(mesh)


_LARGEST_COORDINATE = 1e9  # model units; far beyond any face in any unit, far inside what squares hold


def _check_extent(mesh, path) -> None:
    """Refuse, naming the file, a mesh no face can be: one spanning fewer than two directions (a point,
    a line), or with coordinates so large that the geometry's squared distances overflow."""
    import numpy as np

    largest = float(np.abs(mesh.vertices).max(initial=0.0))
    if largest > _LARGEST_COORDINATE:
        raise InputError(f"{path}: has coordinates as large as {largest:.3g}; a face's are far below "
                         f"{_LARGEST_COORDINATE:.0e} in any unit (scale the mesh)")
    extent = np.sort(np.ptp(mesh.vertices, axis=0))
    if extent[1] <= 1e-12 * max(extent[2], 1e-300):
        raise InputError(f"{path}: its vertices span {extent[2]:.3g} in one direction and "
                         f"{extent[1]:.3g} across it; a face needs a surface, not a line or a point")


def capture_motion(source, *, neutral=None, smoothing=True, progress=None, floor=None):
    """The Motion of a video (or of a saved ``.npz`` track), held in memory. ``neutral``: ``FRAME``,
    ``START:END`` or an image of the same face at rest; found automatically when None. ``smoothing``:
    the One Euro filter; ``floor``: drop the motion under the tracker's noise floor
    (:mod:`faceanim.capture.noisefloor`), None as ``smoothing`` says (``--no-filter`` turns both off). (The jobs
    stream a long video through :func:`captured_source` instead.)"""
    from .capture.track import Track, track_video
    from .progress import as_progress

    source = Path(source)
    if neutral is not None:
        _check_neutral_image(neutral)  # before the video is tracked, not after
    recorded = (Track.load(source) if source.suffix.lower() == ".npz"
                else track_video(source, progress=as_progress(progress)))
    _report_gaps(source, recorded.gaps())
    return motion_of_track(recorded, neutral=neutral, smoothing=smoothing, floor=floor)


def captured_source(source, *, neutral=None, smoothing=True, progress=None, folder=None, floor=None):
    """The streamed :class:`~faceanim.capture.stream.Capture` of a video (or of a saved ``.npz``
    track): :func:`capture_motion`'s motion with the landmarks kept in unnamed temporary files in
    ``folder`` (the job's output folder), so that memory does not grow with the video's length.
    ``smoothing`` and ``floor`` as there."""
    from .capture.smoothing import OneEuro
    from .capture.stream import captured
    from .capture.track import Track
    from .progress import as_progress

    source = Path(source)
    if neutral is not None:
        _check_neutral_image(neutral)  # before the video is tracked, not after
    given = Track.load(source) if source.suffix.lower() == ".npz" else source
    capture = captured(given, smoothing=OneEuro() if smoothing else None, progress=as_progress(progress),
                       folder=folder, floor=_floor(floor, smoothing), **_neutral_choice(neutral, given))
    _report_gaps(source, capture.gaps())
    return capture


def neutral_window(neutral, command: str) -> tuple[int, int] | None:
    """``--neutral`` of a command that takes it only as frames (``FRAME`` or ``START:END``), checked
    before any work: the window, None when not given; an image is refused, naming ``command``. (The
    window is checked against the video's length once it is tracked.)"""
    from .capture.neutral import parse_neutral

    if neutral is None:
        return None
    choice = parse_neutral(str(neutral))
    if not isinstance(choice, tuple):
        raise InputError(f"--neutral {neutral}: {command} takes the neutral as FRAME or START:END (frames)")
    return choice


def _neutral_choice(neutral, given) -> dict:
    """``--neutral`` as :func:`~faceanim.capture.stream.captured` takes it: a frame window (checked
    against the track's length once it is known), or the head-frame points of an image."""
    from .capture.headframe import head_frame
    from .capture.neutral import parse_neutral
    from .capture.track import Track, track_video
    from .capture.tracker import TrackerOptions

    if neutral is None:
        return {}
    choice = parse_neutral(str(neutral), len(given) if isinstance(given, Track) else None)
    if isinstance(choice, tuple):
        return {"neutral": choice}  # a video's length is known once tracked: captured checks the window then
    still = track_video(choice, options=TrackerOptions(static=True), progress=False)
    points, _ = head_frame(still)
    return {"neutral_points": points[0]}


def _report_gaps(source, gaps) -> None:
    """Say on stderr which stretches of the video have no face (they carry no FAPs)."""
    if gaps:
        frames = sum(b - a + 1 for a, b in gaps)
        print(f"faceanim: {source}: {frames} frames in {len(gaps)} stretches have no face "
              f"(first: frames {gaps[0][0]}-{gaps[0][1]}); they carry no FAPs", file=sys.stderr)


def _check_neutral_image(neutral) -> None:
    """A ``--neutral`` that is no frame range names an image (or video, or folder of images) that exists."""
    from .capture.neutral import parse_neutral

    choice = parse_neutral(str(neutral))  # the track's length is checked once it is known
    if not isinstance(choice, tuple) and not Path(choice).exists():
        raise InputError(f"--neutral {choice}: no such image, or frame number (FRAME or START:END)")


def motion_of_track(recorded, *, neutral=None, smoothing=True, floor=None):
    """The Motion of a Track: its neutral from ``FRAME``, ``START:END``, an image of the face at rest,
    or found automatically (None); ``smoothing``: the One Euro filter; ``floor``: the noise floor (None:
    as ``smoothing`` says)."""
    from .capture.headframe import head_frame, track_to_motion
    from .capture.neutral import parse_neutral
    from .capture.smoothing import OneEuro
    from .capture.track import track_video
    from .capture.tracker import TrackerOptions

    window = neutral_points = None
    if neutral is not None:
        choice = parse_neutral(str(neutral), len(recorded))
        if isinstance(choice, tuple):
            window = choice
        else:
            still = track_video(choice, options=TrackerOptions(static=True), progress=False)
            points, _ = head_frame(still)
            neutral_points = points[0]
    return track_to_motion(recorded, neutral=window, smoothing=OneEuro() if smoothing else None,
                           neutral_points=neutral_points, floor=_floor(floor, smoothing))


def _floor(floor, smoothing) -> bool:
    """Whether a job's capture has the noise floor: as asked, or (None) as its filter is, so that
    ``--no-filter`` gives the tracked motion with neither."""
    return bool(smoothing) if floor is None else bool(floor)


def target_unit(target, source: str) -> float:
    """Metres per model unit of ``target``, told from its FAPU before any long work: a face of no human
    size is refused at once, naming it."""
    from .mpeg4 import metres_per_unit

    try:
        return metres_per_unit(target.fapu)
    except ValueError as exc:
        raise InputError(f"{source}: {exc}") from None
