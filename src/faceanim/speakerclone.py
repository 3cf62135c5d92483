"""The speaker clone's jobs: ``faceanim speaker textures`` (key postures, textures, colour model and
camera added to a speaker model) and ``faceanim speaker render`` (the clone drawn video-realistically
from a parameter sequence). The files they read and write:

* parameters: CSV ``frame, timestamp, <one column per articulatory parameter>`` (what ``faceanim
  speaker analyse --params-csv`` writes); an empty cell is a frame without parameters (drawn as the
  background alone);
* rigid motion: CSV ``frame, rx, ry, rz, tx, ty, tz``: the head's rotation vector (radians) and
  translation (cm) per frame (:mod:`faceanim.speaker.camera`);
* camera: 3 lines of 4 numbers, the 3x4 projection to normalised screen coordinates.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from .errors import FileFormatError, InputError
from .outputs import check_outputs

__all__ = ["make_textures", "render_clone", "read_parameters_csv", "read_motion_csv", "write_motion_csv",
           "MOTION_COLUMNS"]

MOTION_COLUMNS = ("frame", "rx", "ry", "rz", "tx", "ty", "tz")


def _read_rows(path, what: str) -> tuple[list[str], list[list[str]]]:
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    try:
        with open(path, newline="", encoding="utf-8") as handle:
            rows = [row for row in csv.reader(handle) if row]
    except (UnicodeDecodeError, csv.Error) as exc:
        raise FileFormatError(path, f"is not a {what} CSV ({exc})") from None
    if not rows:
        raise FileFormatError(path, f"is empty; a {what} CSV starts with a header line")
    return rows[0], rows[1:]


def _numbers(path, rows, columns: int, start: int, what: str) -> np.ndarray:
    values = np.full((len(rows), columns), np.nan)
    for i, row in enumerate(rows):
        if len(row) != start + columns:
            raise FileFormatError(path, f"has {len(row)} columns where the {what} need {start + columns}", line=i + 2)
        try:
            values[i] = [float(v) if v.strip() else np.nan for v in row[start:]]
        except ValueError:
            raise FileFormatError(path, f"holds a value that is no number in the {what}", line=i + 2) from None
    return values


def read_parameters_csv(path, parameter_count: int) -> np.ndarray:
    """``(T, K)`` articulatory parameters from a CSV of ``frame, timestamp`` and ``K`` columns (NaN where
    a cell is empty).

    Raises
    ------
    InputError
        The file is missing.
    FileFormatError
        Another number of columns than the model's parameters (the line named), or a cell that is no
        number.
    """
    header, rows = _read_rows(path, "parameter")
    if len(header) != 2 + parameter_count:
        raise FileFormatError(path, f"has {len(header)} columns; the speaker model's parameters need "
                                    f"{2 + parameter_count} (frame, timestamp and {parameter_count} parameters)",
                              line=1)
    if not rows:
        raise FileFormatError(path, "holds no frames")
    return _numbers(path, rows, parameter_count, 2, "parameters")


def read_motion_csv(path) -> np.ndarray:
    """``(T, 6)`` rigid motion (rotation vector, radians; translation, cm) from a CSV of
    :data:`MOTION_COLUMNS`.

    Raises
    ------
    InputError, FileFormatError
        As :func:`read_parameters_csv`; a row with a missing value.
    """
    header, rows = _read_rows(path, "rigid motion")
    if [h.strip() for h in header] != list(MOTION_COLUMNS):
        raise FileFormatError(path, f"a rigid motion CSV has the columns {', '.join(MOTION_COLUMNS)}", line=1)
    if not rows:
        raise FileFormatError(path, "holds no frames")
    values = _numbers(path, rows, 6, 1, "rigid motion")
    if not np.isfinite(values).all():
        raise FileFormatError(path, "has a frame without its rigid motion",
                              line=int(np.flatnonzero(~np.isfinite(values).all(axis=1))[0]) + 2)
    return values


def write_motion_csv(path, rigid) -> None:
    """Write ``rigid (T, 6)`` as a rigid motion CSV, complete or not at all."""
    from .atomic import atomic_output

    rigid = np.asarray(rigid, dtype=np.float64)
    with atomic_output(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(MOTION_COLUMNS)
        for t, row in enumerate(rigid):
            writer.writerow([t, *(f"{v:.8g}" for v in row)])


def _frames_of(path, indices) -> list[np.ndarray]:
    """Frames ``indices`` of the video at ``path``, in that order, decoded in one pass."""
    from .capture.video import open_frames

    wanted, found = set(indices), {}
    with open_frames(path) as source:
        for i, (_, rgb) in enumerate(source):
            if i in wanted:
                found[i] = rgb
            if len(found) == len(wanted):
                break
    return [found[i] for i in indices]


def make_textures(video, output, *, model, frames=None, neutral=None, smoothing: bool = True, camera_out=None,
                  motion_out=None, progress=None):
    """``faceanim speaker textures``: track ``video`` (the speaker's, as for ``speaker build``), fit its
    camera and rigid motion, choose the key postures among ``frames`` (``"START:END"``, default all:
    give the model's build frames), take their textures and the colour model, and write the speaker
    file ``model`` with them to ``output`` (which may be ``model``). ``camera_out`` (``.txt``) and
    ``motion_out`` (``.csv``) also write the camera and the rigid motion of every frame.
    Returns ``(appearance, camera_fit)``.
    """
    from .inputs import captured_source
    from .speaker import read_speaker
    from .speaker.appearance import write_appearance
    from .speaker.camera import write_camera
    from .speaker.texturing import appearance_from_runs
    from .speech import parse_frames

    output = Path(output)
    same = Path(model).resolve() == output.resolve()
    check_outputs({"-o": (output, ".npz"), "--camera-out": (camera_out, ".txt"), "--motion-out": (motion_out, ".csv")},
                  inputs={"VIDEO": video, "--neutral": neutral, **({} if same else {"--model": model})})
    speaker = read_speaker(model)
    if frames is not None:
        parse_frames(frames)
    source = Path(video)
    if source.suffix.lower() == ".npz":
        raise InputError(f"{video}: speaker textures needs the video itself (its frames give the textures)")
    # the streamed capture (landmarks and head-frame points on disk, read back a run of frames at a time)
    # Without the noise floor, as the model was built (speaker build): the parameters are fitted to its points.
    capture = captured_source(source, neutral=neutral, smoothing=smoothing, progress=progress, folder=output.parent,
                              floor=False)
    motion = capture.motion
    chosen = np.arange(len(motion)) if frames is None else np.arange(*parse_frames(frames, len(motion)))

    def runs():
        for start, d in motion.chunks():
            yield start, motion.neutral + d, capture.landmarks[start:start + len(d)][..., :2]

    try:
        appearance, fit = appearance_from_runs(
            speaker, names=motion.names, runs=runs, pose=motion.pose, valid=motion.valid, width=capture.width,
            height=capture.height, read_frames=lambda indices: _frames_of(video, indices), frames=chosen)
    except ValueError as exc:
        raise InputError(f"{video}: {exc}") from None
    from .atomic import output_group

    with output_group():
        write_appearance(model, appearance, output)
        if camera_out is not None:
            write_camera(camera_out, fit.camera)
        if motion_out is not None:
            write_motion_csv(motion_out, fit.rigid)
    return appearance, fit


def _background(path, width: int, height: int):
    """``(frames, fps, width, height)``: an iterator of background images (one image repeated, or a
    video's frames) and the video's rate (None for an image)."""
    from .capture.video import IMAGE_SUFFIXES, open_frames

    path = Path(path)
    source = open_frames(path)
    if path.suffix.lower() in IMAGE_SUFFIXES:
        image = next(iter(source))[1]
        source.close()

        def still():
            while True:
                yield image

        return still(), None, image.shape[1], image.shape[0], None
    frames = (rgb for _, rgb in source)
    return frames, source.fps, source.width, source.height, source


def render_clone(output, *, model, params, motion=None, camera=None, background=None, wireframe: bool = False,
                 blend: str = "shader", progress=None) -> int:
    """``faceanim speaker render``: the clone of the speaker file ``model`` (with textures) drawn at the
    parameters of ``params`` (CSV), its head at ``motion`` (CSV; default: still, as in the rest key
    frame), through ``camera`` (a 3x4 text file; default the model's), over ``background`` (an image or
    a video, whose size and rate the output takes; default black at the model's video size), with
    the mesh's edges if ``wireframe``; written to ``output`` (``.mp4``). Returns the frame count.

    Raises
    ------
    InputError
        A model without textures, files that do not parse (one line naming the file and the line),
        a motion with fewer frames than the parameters; nothing is written.
    """
    from .progress import as_progress
    from .render.video import video_writer
    from .speaker import read_speaker
    from .speaker.appearance import read_appearance
    from .speaker.camera import read_camera
    from .speaker.clone import CloneRenderer

    output = Path(output)
    check_outputs({"-o": (output, ".mp4")}, inputs={"--model": model, "--params": params, "--motion": motion,
                                                    "--camera": camera, "--background": background})
    speaker = read_speaker(model)
    appearance = read_appearance(model)
    if appearance is None:
        raise InputError(f"{model}: the speaker model has no textures; add them with faceanim speaker textures "
                         f"VIDEO --model {model} -o {model}")
    parameters = read_parameters_csv(params, speaker.parameter_count)
    rigid = None if motion is None else read_motion_csv(motion)
    if rigid is not None and len(rigid) < len(parameters):
        raise InputError(f"--motion {motion}: {len(rigid)} frames, fewer than the {len(parameters)} of --params")
    P = None if camera is None else read_camera(camera)
    width, height = appearance.frame_size
    frames, fps, handle = None, None, None
    if background is not None:
        frames, fps, width, height, handle = _background(background, width, height)
    if width <= 0 or height <= 0:
        raise InputError(f"{model}: the textures do not say the video's size; give --background")
    fps = fps or speaker.fps
    steps = as_progress(progress).bar(enumerate(parameters), total=len(parameters), desc="render")
    try:
        with CloneRenderer(speaker, appearance, width=width, height=height, blend=blend) as renderer, \
                video_writer(output, fps, width, height) as write:
            black = np.zeros((height, width, 3), dtype=np.uint8)
            for t, a in steps:
                bg = black if frames is None else next(frames, None)
                if bg is None:
                    raise InputError(f"--background {background}: the video ends at frame {t}, before the "
                                     f"{len(parameters)} frames of --params")
                if np.isfinite(a).all():
                    write(renderer.render(a, None if rigid is None else rigid[t], camera=P, background=bg,
                                          wireframe=wireframe))
                else:
                    write(bg)
    finally:
        if handle is not None:
            handle.close()
    return len(parameters)
