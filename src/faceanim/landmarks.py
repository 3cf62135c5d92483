"""MediaPipe's face-mesh layout: which landmark is which feature point, iBUG-68 point or lip contour.

Pure tables and the names they give, with no tracker behind them: the capture names its landmarks
with them, and the rooms that meet MediaPipe's mesh elsewhere (placing points on a target, the
generic face, the rigs, the speaker clone's lips) read the same tables instead of importing the
capture.

Indices are into MediaPipe's 478-point face mesh with iris refinement (468-472 the subject's right
iris, centre 468; 473-477 the left iris, centre 473). MediaPipe's canonical face has +x on the
subject's left, as MPEG-4 does. Only points that the mesh observes are listed: the teeth, tongue,
ears, hair line and the head-rotation centre (groups 6, 7, 9.8-9.11, 10, 11) are not. Where a
feature point falls between mesh vertices the nearest vertex along the same contour is used.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

__all__ = ["EYE_LIDS", "FEATURE_POINT_LANDMARK", "IBUG68_LANDMARK", "LIP_OUTER", "LIP_INNER", "LIP_BETWEEN",
           "landmark_names"]

FEATURE_POINT_LANDMARK: Mapping[str, int] = MappingProxyType({  # read-only: a shared table
    # chin and inner lips
    "2.1": 152, "2.2": 13, "2.3": 14, "2.4": 308, "2.5": 78, "2.6": 311, "2.7": 81, "2.8": 402, "2.9": 178,
    "2.10": 199, "2.11": 400, "2.12": 176, "2.13": 397, "2.14": 172,
    # eyes: lid margins, pupils (iris centres), corners
    "3.1": 386, "3.2": 159, "3.3": 374, "3.4": 145, "3.5": 473, "3.6": 468,
    "3.7": 263, "3.8": 133, "3.11": 362, "3.12": 33,
    # eyebrows (upper contour)
    "4.1": 336, "4.2": 107, "4.3": 334, "4.4": 105, "4.5": 300, "4.6": 70,
    # cheeks and cheek bones
    "5.1": 425, "5.2": 205, "5.3": 345, "5.4": 116,
    # outer lips
    "8.1": 0, "8.2": 17, "8.3": 291, "8.4": 61, "8.5": 269, "8.6": 39, "8.7": 405, "8.8": 181,
    "8.9": 37, "8.10": 267,
    # nose
    "9.1": 294, "9.2": 64, "9.3": 4, "9.4": 98, "9.5": 327, "9.6": 193, "9.7": 417, "9.12": 197,
    "9.13": 437, "9.14": 217, "9.15": 2,
})

# The 68-point iBUG / Multi-PIE layout (dlib, OpenFace): jaw 0-16 (subject's right ear to left),
# brows 17-26, nose 27-35, eyes 36-47, outer lips 48-59, inner lips 60-67. Brows, nose, eyes and lips
# follow the layout's definitions. The jaw points mark the visible face contour, which no fixed mesh
# vertex follows; they were fitted, as mirror pairs, to dlib's jaw points on the 18 faces of
# shared/data/dlib_faces (benchmarks/landmarks_dlib.py reports the error). Three nose points were
# refitted the same way: 29, a third of the way up the ridge from the tip, is 195 (5 sits next to the
# tip); the alar bases 31/35 are 75/305 (98/327 sit higher, on the wing). Mean error there, in
# inter-ocular distances: 0.081 -> 0.056 and 0.066 -> 0.044; the ICT-FaceKit neutral, which was not
# used to choose them, agrees (benchmarks/placement_ict.py).
IBUG68_LANDMARK: tuple[int, ...] = (
    127, 137, 177, 215, 172, 136, 149, 148, 152, 377, 378, 365, 397, 435, 401, 366, 356,
    70, 63, 105, 66, 107, 336, 296, 334, 293, 300,
    168, 197, 195, 4, 75, 97, 2, 326, 305,
    33, 160, 158, 133, 153, 144, 362, 385, 387, 263, 373, 380,
    61, 39, 37, 0, 267, 269, 291, 405, 314, 17, 84, 181,
    78, 82, 13, 312, 308, 317, 14, 87,
)

# Each eye's lids, upper over lower, facing point by point from the outer corner to the inner (the corners
# themselves are not pairs): MediaPipe's eye contours, MPEG-4's 3.1 over 3.3 and 3.2 over 3.4 among them.
EYE_LIDS: Mapping[str, tuple[tuple[int, ...], tuple[int, ...]]] = MappingProxyType({
    "left": ((466, 388, 387, 386, 385, 384, 398), (249, 390, 373, 374, 380, 381, 382)),
    "right": ((246, 161, 160, 159, 158, 157, 173), (7, 163, 144, 145, 153, 154, 155)),
})

# The lips' outer and inner contours (the inner one is the mouth opening), each closed and in order
# around the mouth: from the subject's right corner over the upper lip, then back along the lower lip.
LIP_OUTER: tuple[int, ...] = (61, 185, 40, 39, 37, 0, 267, 269, 270, 409, 291, 375, 321, 405, 314, 17, 84, 181, 91,
                              146)
LIP_INNER: tuple[int, ...] = (78, 191, 80, 81, 82, 13, 312, 311, 310, 415, 308, 324, 318, 402, 317, 14, 87, 178, 88,
                              95)
# The points on the red of the lips between the two contours (inside the outer one on MediaPipe's canonical
# face, not on either contour), in index order.
LIP_BETWEEN: tuple[int, ...] = (11, 12, 15, 16, 38, 41, 42, 62, 72, 73, 74, 76, 77, 85, 86, 89, 90, 96, 179, 180,
                                183, 184, 268, 271, 272, 292, 302, 303, 304, 306, 307, 315, 316, 319, 320, 325,
                                403, 404, 407, 408)


def landmark_names(count: int) -> tuple[str, ...]:
    """Names of MediaPipe's first ``count`` landmarks: the MPEG-4 feature point where one sits, else ``mp<i>``."""
    names = [f"mp{i}" for i in range(count)]
    for point, index in FEATURE_POINT_LANDMARK.items():
        if index < count:
            names[index] = point
    return tuple(names)
