"""Where MPEG-4 feature points sit in the 68-point iBUG / Multi-PIE landmark layout.

Only points that the 68-point layout marks directly are listed (index 0-67 into that layout). The
layout numbers the subject's right side first: 17-21 are the right eyebrow (outer to inner), 36-41
the right eye, starting at its outer corner. MPEG-4 left and right are also the face's own sides.
"""

from __future__ import annotations

__all__ = ["MULTIPIE68_OF_FEATURE_POINT", "THESIS_16"]

MULTIPIE68_OF_FEATURE_POINT: dict[str, int] = {
    "2.1": 8,    # bottom of the chin
    "2.2": 62,   # middle of inner upper lip
    "2.3": 66,   # middle of inner lower lip
    "2.4": 64,   # left corner of inner lip contour
    "2.5": 60,   # right corner of inner lip contour
    "3.1": 43,   # upper inner left eyelid (43 and 44 flank its centre)
    "3.2": 38,   # upper inner right eyelid
    "3.3": 47,   # lower inner left eyelid
    "3.4": 40,   # lower inner right eyelid
    "3.7": 45,   # outer corner of left eye
    "3.8": 39,   # inner corner of right eye
    "3.11": 42,  # inner corner of left eye
    "3.12": 36,  # outer corner of right eye
    "4.1": 22,   # inner corner of left eyebrow
    "4.2": 21,   # inner corner of right eyebrow
    "4.3": 24,   # uppermost point of left eyebrow
    "4.4": 19,   # uppermost point of right eyebrow
    "4.5": 26,   # outer corner of left eyebrow
    "4.6": 17,   # outer corner of right eyebrow
    "8.1": 51,   # middle of outer upper lip
    "8.2": 57,   # middle of outer lower lip
    "8.3": 54,   # left corner of outer lip contour
    "8.4": 48,   # right corner of outer lip contour
    "9.1": 35,   # left nostril border (the 68 layout's outer nostril point)
    "9.2": 31,   # right nostril border
    "9.3": 30,   # nose tip
    "9.15": 33,  # bottom middle edge of the nose
}

# The 16 feature points of the thesis' RBF experiment: nose tip, outer lip middles and corners, inner
# and outer brow corners, the four eye corners, the upper eyelids and the chin. (The thesis numbers
# the eye points differently from Table C-1; these are chosen by their description.)
THESIS_16 = ("9.3", "8.1", "8.2", "8.3", "8.4", "4.1", "4.2", "4.5", "4.6",
             "3.7", "3.11", "3.8", "3.12", "3.1", "3.2", "2.1")
