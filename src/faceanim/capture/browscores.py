"""Brows from the Face Landmarker's blendshape scores, calibrated per person against the neutral.

The tracker's brow landmarks follow a brow raise by about a third (0.33-0.40 of the true lift on ICT
renders, `benchmarks/roundtrip_ict.py`): its mesh is held to a typical shape. Its blendshape scores are
trained on exactly that cue. Each brow point's height in the head frame is therefore read from the
scores: for a score ``s`` whose highest value over the neutral frames is ``s0``, ``(s - s0) / (1 - s0)``
clipped to [0, 1] says how far the expression is on (so the neutral frames' scores add nothing to
their tracked brows), and

* ``browInnerUp`` raises the inner end of each brow, ``browOuterUp{Left,Right}`` the outer end, by
  :data:`RAISE` x ENS0 at full strength, blended along the brow;
* ``browDown{Left,Right}`` lowers the whole brow by :data:`LOWER` x ENS0.

The scores say how far; the geometry must agree on the way. A brow point rises to the scores' height
only as far as :data:`TRACKED_SHARE` of its tracked rise allows, and falls the same way: on a painted
face the Face Landmarker scores a brow raise during every blink (browOuterUp 0.3-0.4) while the brow
landmarks stay put. The scores only add: a brow never ends below its tracked rise (or above its tracked
fall), since the scores can miss what the landmarks see (on one ICT identity of the five tuning ones the
brow scores peak at 0.05 in a full raise the landmarks show as 0.6 cm; held to the scores, the raise was
lost). So a point tracked ``rise`` with the scores' ``height > 0`` ends at
``max(rise, min(height, rise / TRACKED_SHARE))`` (for ``height < 0``, the same with max and min
swapped); a tracked dip the scores call a raise (a painted face's blink) stays as tracked. Where no
brow score speaks (each under :data:`_SILENT` once calibrated), the tracked movement is kept only as
far as the same side's ``eyeBlink`` score, calibrated as the brows' are (against the neutral frames'
raw median, which a blink among them does not move; with no neutral frames, the 5th percentile over
the video, as the brows'), leaves the eye open: ``movement x (1 - shut)``.
The tracker's brow landmarks move with the lids: on the ICT renders they rise 0.02-0.05 cm through a
blink that moves no brow where the scores say nothing. Where a brow score speaks the damping is off,
and the Face Landmarker scores a raise in many blinks: on the round trip's tuning seed the left upper
brow still rose 0.08 cm through the blink as tracked, 0.13 with the scores' raise (0.14 undamped).
Damping a raise the scores call too lost a brow raise held through a blink (0.6 -> 0.05 cm), so it is
not done. With the eye open, a movement no score calls for stays as tracked (a raise the scores miss).
Only the brow points' vertical movement is changed; their sideways and depth movement stay as tracked,
and so does every other point. A frame without scores (a gap the capture filled) keeps its tracked
heights. The constants were chosen on one
ICT identity pair (seed 3) and reported on others (`benchmarks/brow_scores.py`); the damping by the
eyes' shutting has no constant of its own (``_SILENT`` only tells a silent score from a speaking one).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..validation import as_array
from .scores import filtered_scores, shut_eyes
from .smoothing import OneEuro

__all__ = ["BrowDrive", "BROWS", "RAISE", "LOWER", "TRACKED_SHARE"]

RAISE, LOWER = 0.35, 0.2  # ENS0 at a full score
TRACKED_SHARE = 1 / 3  # of a brow's true rise, what its landmark shows (0.33-0.40 on ICT renders)
_FILTER = OneEuro()
# MediaPipe's brow landmarks, upper then lower contour, inner end to outer end.
BROWS = {"Left": ((336, 296, 334, 293, 300), (285, 295, 282, 283, 276)),
         "Right": ((107, 66, 105, 63, 70), (55, 65, 52, 53, 46))}
_SCORES = ("browInnerUp", "browOuterUpLeft", "browOuterUpRight", "browDownLeft", "browDownRight")
_SILENT = 0.01  # a calibrated score under this (1% of full) says nothing: the filtered scores hover there


@dataclass(frozen=True, eq=False)
class BrowDrive:
    """The brow heights a video's scores call for.

    Parameters
    ----------
    heights : (T, 20) float64
        Vertical displacement (cm, head frame) of each point of :attr:`points` per frame; NaN where
        the frame has no scores.
    points : (20,) int64
        The brow landmarks, in :data:`BROWS` order (left upper, left lower, right upper, right lower).
    shut : (T, 20) float64, optional
        How far the eye on each point's side is shut (its calibrated ``eyeBlink`` score, 0 to 1) where
        no brow score speaks for the point, 0 where one does, NaN where the frame has no scores; None:
        the eyes count as open throughout.
    """

    heights: np.ndarray
    points: np.ndarray
    shut: np.ndarray | None = None

    def __post_init__(self):
        object.__setattr__(self, "heights", as_array(self.heights, "heights", shape=("T", 20), frozen=True,
                                                     finite=False))
        object.__setattr__(self, "points", as_array(self.points, "points", shape=(20,), dtype=np.int64,
                                                    frozen=True))
        if self.shut is not None:
            object.__setattr__(self, "shut", as_array(self.shut, "shut", shape=self.heights.shape, frozen=True,
                                                      finite=False))

    @classmethod
    def of_scores(cls, scores, names, times, ens0: float, neutral_frames, *,
                  smoothing: OneEuro | None = _FILTER) -> BrowDrive | None:
        """From ``scores (T, S)`` named ``names``, at ``times (T,)`` seconds; ``neutral_frames`` the
        frames at rest (indices) the scores are calibrated on, None when the neutral comes from
        elsewhere (then each score's 5th percentile over the video is its rest). ``smoothing``: the
        filter the landmarks had. None when the scores lack a brow score or no neutral frame has
        scores."""
        # the landmarks are filtered before they become motion; the scores that move the brows get the
        # same settings, so a brow does not jitter more than the rest of the face. One way only: the
        # landmarks' filter runs both ways (no lag), but run both ways on the scores the round trip's
        # brows were worse on the tuning seeds (3, 4, 6, 20: 0.601 -> 0.612; benchmarks/roundtrip_ict.py)
        picked = filtered_scores(scores, names, _SCORES, times, smoothing)
        if picked is None:
            return None
        _, smooth = picked
        at_rest = smooth if neutral_frames is None else smooth[neutral_frames]
        at_rest = at_rest[np.isfinite(at_rest).all(axis=1)]
        if not len(at_rest):
            return None
        s0 = np.percentile(at_rest, 5, axis=0) if neutral_frames is None else at_rest.max(axis=0)
        on = np.clip((smooth - s0) / np.maximum(1.0 - s0, 1e-3), 0.0, 1.0)
        inner, outer, down = on[:, 0], {"Left": on[:, 1], "Right": on[:, 2]}, {"Left": on[:, 3], "Right": on[:, 4]}
        shut = shut_eyes(scores, names, times, neutral_frames, smoothing=smoothing)
        columns, points, shut_columns = [], [], []
        for side, contours in BROWS.items():
            for contour in contours:
                for k, point in enumerate(contour):
                    along = k / (len(contour) - 1)  # 0 at the inner end, 1 at the outer
                    raise_ = (1 - along) * inner + along * outer[side]
                    columns.append(ens0 * (RAISE * raise_ - LOWER * down[side]))
                    points.append(point)
                    if shut is not None:
                        silent = (raise_ < _SILENT) & (down[side] < _SILENT)
                        shut_columns.append(np.where(silent, shut[side], 0.0))
        return cls(np.stack(columns, axis=1), np.array(points),
                   np.stack(shut_columns, axis=1) if shut is not None else None)

    def apply(self, displacements, start: int) -> np.ndarray:
        """``displacements (t, L, 3)`` of frames ``start .. start + t`` (head frame, cm), changed in
        place: each brow point's height is the scores', as far as its tracked height agrees, and never
        short of its tracked height; where no score speaks, the tracked height less what the eye's
        shutting explains (see the module); returned."""
        heights = self.heights[start:start + len(displacements)]
        column = displacements[:, self.points, 1]
        if self.shut is not None:  # where no score speaks, what the lids' closing explains is taken away
            column = column * (1.0 - np.nan_to_num(self.shut[start:start + len(displacements)], nan=0.0))
        seen = column / TRACKED_SHARE
        agreed = np.where(heights > 0, np.maximum(column, np.minimum(heights, seen)),
                          np.minimum(column, np.maximum(heights, seen)))
        have = np.isfinite(heights) & np.isfinite(column)
        displacements[:, self.points, 1] = np.where(have, agreed, displacements[:, self.points, 1])
        return displacements
