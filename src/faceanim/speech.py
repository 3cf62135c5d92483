"""The speaker jobs: ``faceanim speaker build`` (a speaker's articulatory model from a speech video)
and ``faceanim speaker analyse`` (a video's FAPs as that model explains them). Decoding a stream
through a model is ``faceanim decode --speaker`` (:func:`faceanim.pipeline.decode`)."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from .atomic import atomic_output
from .errors import InputError
from .inputs import capture_motion
from .outputs import check_outputs

__all__ = ["build_speaker", "analyse_speech", "parse_frames"]


def parse_frames(spec, frame_count: int | None = None) -> tuple[int, int]:
    """``--frames START:END`` (end exclusive) as ``(start, end)``; checked against ``frame_count``
    where it is known.

    >>> parse_frames("10:60", 100)
    (10, 60)
    """
    text = str(spec).strip()
    try:
        start, end = (int(x) for x in text.split(":"))
    except ValueError:
        raise InputError(f"--frames {spec}: give START:END, frame numbers with START < END") from None
    if not 0 <= start < end or (frame_count is not None and end > frame_count):
        limit = "" if frame_count is None else f" (the video has {frame_count} frames)"
        raise InputError(f"--frames {spec}: frames must satisfy 0 <= START < END <= the frame count{limit}")
    return start, end


def _stem(path) -> str:
    return Path(path).stem.replace(" ", "_") or "speaker"


def build_speaker(video, output, *, params: int = 6, frames=None, method: str = "guided", neutral=None,
                  smoothing: bool = True, progress=None):
    """``faceanim speaker build``: track ``video``, build the speaker's linear articulatory model of
    ``params`` parameters from its frames (``frames``: ``"START:END"``, default all) and write it to
    ``output`` (``.npz``, see :mod:`faceanim.speaker.speakerfile`). ``method``: ``"guided"`` (the
    default: jaw first, then the lips) or ``"pca"``; ``benchmarks/speaker_model.py`` measures both
    (guided decodes held-out tracked FAPs closer, PCA explains a little more of the points' variance).
    Returns ``(model, explained)``: the :class:`~faceanim.speaker.SpeakerModel` and the share of the
    mobile points' variance it explains on those frames."""
    from .speaker import METHODS, build_model, reconstruction_error, write_speaker

    output = Path(output)
    check_outputs({"-o": (output, ".npz")}, inputs={"VIDEO": video, "--neutral": neutral})
    if isinstance(params, bool) or not isinstance(params, int) or not 1 <= params <= 64:
        raise InputError(f"--params {params}: give a whole number of parameters from 1 to 64")
    if method not in METHODS:
        raise InputError(f"--method {method}: choose {' or '.join(METHODS)}")
    if frames is not None:
        parse_frames(frames)  # the form is checked before the video is tracked
    # Without the noise floor: a linear model fitted over many frames averages the tracker's noise itself, and
    # the floor, not linear in the motion, would bend it (faceanim.capture.noisefloor). The speaker's other
    # commands capture the same way, as the model was built.
    motion = capture_motion(video, neutral=neutral, smoothing=smoothing, progress=progress, floor=False)
    chosen = np.arange(len(motion)) if frames is None else np.arange(*parse_frames(frames, len(motion)))
    try:
        model = build_model(motion, parameters=params, frames=chosen, method=method)
    except ValueError as exc:
        raise InputError(f"{video}: {exc}") from None
    missed = reconstruction_error(model, motion, chosen)
    seen = motion.displacements[chosen[motion.valid[chosen]]][:, motion.index(model.names)]
    explained = 1.0 - float((missed**2).sum() / ((seen - seen.mean(axis=0)) ** 2).sum())
    write_speaker(output, model)
    return model, explained


def analyse_speech(video, output, *, model, params_csv=None, neutral=None, smoothing: bool = True, progress=None):
    """``faceanim speaker analyse``: the FAPs of ``video`` as the speaker model ``model`` (a file from
    :func:`build_speaker`) explains them, written to ``output`` (``.fap``); ``params_csv`` also writes
    the articulatory parameters per frame (``frame, timestamp, <parameter names>``).

    Each frame's mobile points, as displacements from the video's own neutral face, are fitted by the
    model's parameters (least squares, cm); the FAPs are then the model's own, every one of them on
    every frame with a face, unclipped, so that the model reproduces them (a chin above the neutral's
    gives a negative ``open_jaw``, outside MPEG-4's range). Returns ``(stream, parameters (T, K),
    outside)``, ``outside`` the number of values outside MPEG-4's ranges."""
    from .mpeg4.fapfile import write_fap
    from .speaker import read_speaker

    output = Path(output)
    check_outputs({"-o": (output, ".fap"), "--params-csv": (params_csv, ".csv")},
                  inputs={"VIDEO": video, "--model": model, "--neutral": neutral})
    speaker = read_speaker(model)
    motion = capture_motion(video, neutral=neutral, smoothing=smoothing, progress=progress, floor=False)
    missing = [n for n in speaker.names if n not in set(motion.names)]
    if missing:
        raise InputError(f"{model}: the model moves points the capture of {video} lacks ({', '.join(missing[:5])}"
                         f"{', ...' if len(missing) > 5 else ''})")
    parameters = speaker.fit_points(motion.displacements[:, motion.index(speaker.names)])
    parameters[~motion.valid] = np.nan
    stream = speaker.to_faps(parameters, fps=motion.fps, name=_stem(video))
    write_fap(output, stream)
    if params_csv is not None:
        with atomic_output(params_csv) as tmp, open(tmp, "w", newline="", encoding="utf-8") as handle:
            writer = csv.writer(handle)
            writer.writerow(["frame", "timestamp", *speaker.parameter_names])
            for t, row in enumerate(parameters):
                writer.writerow([t, f"{t / motion.fps:.6g}", *("" if np.isnan(v) else f"{v:.6g}" for v in row)])
    return stream, parameters, int(stream.out_of_range().sum())
