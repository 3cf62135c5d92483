"""The Face Landmarker's blendshape scores as the capture reads them: picked by name, filtered as the
landmarks are, and the eyes' blink scores calibrated against the neutral. The brows
(:mod:`.browscores`) and the blink's sideways slide (:mod:`.blinkslide`) both read them here."""

from __future__ import annotations

import numpy as np

from .smoothing import OneEuro, OneEuroFilter

__all__ = ["BLINKS", "filtered_scores", "shut_eyes", "scores_across_filled_frames"]

BLINKS = ("eyeBlinkLeft", "eyeBlinkRight")


def filtered_scores(scores, names, wanted, times, settings: OneEuro | None):
    """The ``wanted`` columns of ``scores (T, S)`` named ``names``, raw and filtered by ``settings`` (each
    column on its own; None: not filtered), as ``(raw, filtered)``, both ``(T, len(wanted))``; None when
    there are no scores or one of ``wanted`` is missing."""
    names = list(names)
    if scores is None or any(n not in names for n in wanted):
        return None
    raw = np.asarray(scores, dtype=np.float64)[:, [names.index(n) for n in wanted]]
    smooth = (raw if settings is None else
              OneEuroFilter(settings)(raw[:, :, None], np.asarray(times, dtype=np.float64))[:, :, 0])
    return raw, smooth


def shut_eyes(scores, names, times, neutral_frames, *, smoothing: OneEuro | None) -> dict[str, np.ndarray] | None:
    """How far each eye is shut, ``{"Left": (T,), "Right": (T,)}`` in [0, 1] (NaN where a frame has no
    scores), from ``scores (T, S)`` named ``names`` at ``times (T,)``: the ``eyeBlink`` scores filtered
    by ``smoothing``, less their rest, over what is left to 1. The rest is the raw scores' median over
    ``neutral_frames`` (a blink among them does not move it; filtered, a blink's tail spreads over most
    of a 10-frame neutral), or with no neutral frames (None) or none with scores, the filtered scores'
    5th percentile over the video. None when the scores lack a blink score or no frame has them."""
    picked = filtered_scores(scores, names, BLINKS, times, smoothing)
    if picked is None:
        return None
    raw, smooth = picked
    at_rest = raw[neutral_frames] if neutral_frames is not None else raw[:0]
    at_rest = at_rest[np.isfinite(at_rest).all(axis=1)]
    if len(at_rest):
        rest = np.median(at_rest, axis=0)
    else:
        seen = smooth[np.isfinite(smooth).all(axis=1)]
        if not len(seen):
            return None
        rest = np.percentile(seen, 5, axis=0)
    on = np.clip((smooth - rest) / np.maximum(1.0 - rest, 1e-3), 0.0, 1.0)
    return {"Left": on[:, 0], "Right": on[:, 1]}


def scores_across_filled_frames(scores, usable: np.ndarray) -> np.ndarray | None:
    """``scores (T, S)`` with the frames that have landmarks but no scores filled as their landmarks were:
    linearly between the scored frames on either side (a short gap the tracker lost the face in is
    filled so, :func:`~.track.fill_short_gaps`). Without it the drives the scores call for (the brows'
    heights, the blink's slide) were left out on those frames and came back after: a pop in the middle
    of a blink. Frames with landmarks before the first or after the last scored one (a saved track's
    own fill) hold the nearest scores; frames without landmarks stay as they are. Each score column on
    its own. None stays None. The Live Link take (:mod:`faceanim.arkit`) fills its weights here too."""
    if scores is None:
        return None
    scores = np.asarray(scores, dtype=np.float64)
    usable = np.asarray(usable, dtype=bool)
    out = scores
    for column in range(scores.shape[1]):  # each score on its own: a row may lack only some
        scored = np.flatnonzero(np.isfinite(scores[:, column]))
        if not len(scored):
            continue
        wanted = np.flatnonzero(usable & ~np.isfinite(scores[:, column]))
        if len(wanted):
            out = scores.copy() if out is scores else out
            out[wanted, column] = np.interp(wanted, scored, scores[scored, column])
    return out
