"""The sideways slide the tracker draws around a shutting eye, taken out by the eye's blink score.

The Face Landmarker draws a shut eye longer than the open one: as the lids close, its outer eye
corner and the lids' outer halves slide outwards, and their neighbours with them. On the round trip's
ICT renders (`benchmarks/roundtrip_ict.py`, tuning seed 3) the left outer corner moved 0.44 cm
sideways in a full blink where the face moved it 0.02, and the skin up to 2.5 cm from the eye's
centre 0.1-0.5 cm; on the shared real videos the outer corner slides 0.1-0.24 cm with a blink on 5 of
7. A real blink pulls the lids slightly inwards if at all (the orbicularis closes towards the inner
corner), so the slide is the tracker's.

Each landmark near an eye therefore keeps its sideways movement (the head frame's x) only as far as
that eye is open: ``x * (1 - w * shut)``, where ``shut`` is the same side's ``eyeBlink`` score
calibrated against the neutral (:func:`~.scores.shut_eyes`, as the brows' scores are) and ``w`` is 1 within
:data:`NEAR` x ES0 of the eye's centre (the middle of its two corners at rest), falling linearly to 0
at :data:`FAR` x ES0; the brows' own points (:data:`~.browscores.BROWS`) keep theirs (a frown with
the eyes shut pulls them in). Height and depth stay as tracked (the lids' closing is their height). A smile
with the eyes shut loses the sideways part of its movement near the eyes, which is small beside its
rise. Where a frame has no scores, nothing changes.

Measured on the round trip's tuning seeds 3, 4, 6 and 20 (mean of the per-seed medians of the blink
segment, 2026-11-24): 0.826 without, 0.798 with the fall-off from 1.5 to 3 cm, 0.793 from 2 to 3.5 cm,
0.791 from 2.5 to 4 cm; damping the depth as well changed it by 0.004 or less and damping the height
undid the blink (0.930). The plateau's middle, 2 to 3.5 cm, is about 0.3 to 0.55 of these faces' ES0
(6.2-7.0 cm). The other segments (jaw, smile, brows) moved by 0.001 or less. Leaving the brows'
points out changed none of the four segments' means by more than 0.001.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..validation import as_array
from .browscores import BROWS
from .scores import BLINKS, shut_eyes
from .smoothing import OneEuro

__all__ = ["BlinkSlide", "EYE_CORNERS", "NEAR", "FAR"]

#: Each eye's outer and inner corner among MediaPipe's landmarks.
EYE_CORNERS = {"Left": (263, 362), "Right": (33, 133)}
_FACE_MESH = 468  # MediaPipe's face mesh; the iris points follow
NEAR, FAR = 0.3, 0.55  # of ES0: the slide is taken out fully within NEAR of an eye's centre, not at all beyond FAR


@dataclass(frozen=True, eq=False)
class BlinkSlide:
    """How much of each landmark's sideways movement a video's blinks take out.

    Parameters
    ----------
    shut : (T, 2) float64
        How far the left and the right eye are shut per frame (:func:`~.scores.shut_eyes`); NaN where the frame
        has no scores.
    reach : (2, L) float64
        How fully each landmark's slide goes with the left and the right eye (``w`` of the module), 0
        to 1.
    """

    shut: np.ndarray
    reach: np.ndarray

    def __post_init__(self):
        object.__setattr__(self, "shut", as_array(self.shut, "shut", shape=("T", 2), frozen=True, finite=False))
        object.__setattr__(self, "reach", as_array(self.reach, "reach", shape=(2, "L"), frozen=True))

    @classmethod
    def of_scores(cls, scores, names, times, rest, es0: float, neutral_frames, *,
                  smoothing: OneEuro | None) -> BlinkSlide | None:
        """From the scores (as :func:`~.scores.shut_eyes`) and the landmarks' ``rest (L, 3)`` (head frame, cm;
        MediaPipe's layout) with the face's ``es0``; None without blink scores."""
        shut = shut_eyes(scores, names, times, neutral_frames, smoothing=smoothing)
        if shut is None:
            return None
        rest = np.asarray(rest, dtype=np.float64)
        reach = []
        for side in BLINKS:
            centre = rest[list(EYE_CORNERS[side.removeprefix("eyeBlink")])].mean(axis=0)
            distance = np.linalg.norm(rest - centre, axis=1) / es0
            reach.append(np.clip((FAR - distance) / (FAR - NEAR), 0.0, 1.0))
        reach = np.stack(reach)
        reach[:, _FACE_MESH:] = 0.0  # the irises move with the eyeballs, not the skin
        # the brows keep their own sideways movement (a frown with the eyes shut pulls them in)
        reach[:, [p for side in BROWS.values() for contour in side for p in contour]] = 0.0
        return cls(np.stack([shut["Left"], shut["Right"]], axis=1), reach)

    def apply(self, displacements, start: int) -> np.ndarray:
        """``displacements (t, L, 3)`` of frames ``start .. start + t`` (head frame, cm), changed in
        place: each landmark's sideways movement less the share its eyes' shutting takes out; returned."""
        shut = np.nan_to_num(self.shut[start:start + len(displacements)], nan=0.0)
        # where the two eyes' reaches overlap (none do on MediaPipe's canonical face) the larger share is
        # taken out; (t, L) temporaries only, not (t, 2, L)
        taken = np.maximum(shut[:, :1] * self.reach[0], shut[:, 1:] * self.reach[1])
        displacements[:, :, 0] *= 1.0 - taken
        return displacements
