"""The jaw's depth from its drop.

A face seen from the front shows how far the chin falls, but hardly how far it swings back: the jaw
turns about its hinge in front of the ears, so an open jaw moves the chin down and back by about the
same amount. MediaPipe's depth for the lower face follows that turn only in part (on ICT-FaceKit's
jawOpen, a third of the chin's backward travel; ``benchmarks/roundtrip_ict.py``). Here the turn is
read from the chin's drop, which the picture does show, and the depth of every point the jaw carries
is corrected to match it, leaving whatever else MediaPipe saw in depth (a pout, a jaw thrust) as it was.
"""

from __future__ import annotations

import numpy as np

__all__ = ["jaw_carried", "correct_jaw_depth"]

# MediaPipe's face-oval points level with the tragus; the jaw's hinge sits midway between them.
_EAR_POINTS = (234, 454)
_MOUTH_CORNERS = (61, 291)
_LOWER_LIP_BOTTOM = 17


def jaw_carried(rest: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Which landmarks the jaw carries, which of those are the chin, and the hinge, from a rest face.

    ``rest (L >= 468, 3)``: MediaPipe's landmarks at rest in the head frame (+y up, +z out). Returns
    ``(carried, chin, hinge)``: indices of the points below the mouth corners and inside the jaw's
    angles; of those, the points well below the lower lip (the chin, which only the jaw moves); and
    the hinge ``(3,)``, midway between the ears.
    """
    rest = np.asarray(rest, dtype=np.float64)[:468]
    width = abs(rest[_EAR_POINTS[0], 0] - rest[_EAR_POINTS[1], 0])
    hinge = rest[list(_EAR_POINTS)].mean(axis=0)
    inside = np.abs(rest[:, 0] - hinge[0]) < 0.3 * width
    corners = rest[list(_MOUTH_CORNERS), 1].mean()
    carried = np.flatnonzero(inside & (rest[:, 1] < corners - 0.02 * width))
    chin = np.flatnonzero(inside & (rest[:, 1] < rest[_LOWER_LIP_BOTTOM, 1] - 0.07 * width))
    return carried, chin, hinge


def correct_jaw_depth(rest: np.ndarray, displacements: np.ndarray, *, out: np.ndarray | None = None) -> np.ndarray:
    """``displacements (T, L, 3)`` with the depth of the jaw's points made to agree with the chin's drop
    (written into ``out`` when given: the displacements themselves may be).

    Per frame, the jaw's turn about the hinge (a small angle about the x axis) is fitted twice over
    the chin points: once to their vertical motion, once to their depth. The carried points' depth
    then gains the difference between the two turns, at their own lever arm, fading out over the
    points beside and just below the mouth corners (:func:`_carried_share`). A face whose chin does
    not move (a smile, a blink) is left unchanged. NaN frames stay NaN.
    """
    if out is None:
        d = np.array(displacements, dtype=np.float64)
    else:
        d = out
        if d is not displacements:
            d[...] = displacements
    _, chin, hinge = jaw_carried(rest)
    if len(chin) == 0:
        return d
    arm = np.asarray(rest, dtype=np.float64)[:, :3] - hinge
    # a turn by a small angle t (chin down and back for t > 0) moves p by t * (0, -arm_z, arm_y)
    by_drop = -arm[chin, 2]
    by_depth = arm[chin, 1]
    turn_seen_in_drop = d[:, chin, 1] @ by_drop / (by_drop @ by_drop)
    turn_seen_in_depth = d[:, chin, 2] @ by_depth / (by_depth @ by_depth)
    share = _carried_share(np.asarray(rest, dtype=np.float64)[:468])
    moved = np.flatnonzero(share > 0)
    d[:, moved, 2] += (turn_seen_in_drop - turn_seen_in_depth)[:, None] * (share[moved] * arm[moved, 1])[None]
    return d


def _carried_share(rest: np.ndarray) -> np.ndarray:
    """``(468,)`` how much of the depth correction each point takes: 1 within 0.3 face widths of the
    middle and 0.12 widths below the mouth corners, fading to 0 at 0.4 widths beside the middle and
    at 0.02 widths below the corners (where :func:`jaw_carried`'s hard edges were). That hard edge left
    the jaw's sides 2 cm apart in depth from their neighbours just outside it, a crease along the jaw."""
    width = abs(rest[_EAR_POINTS[0], 0] - rest[_EAR_POINTS[1], 0])
    hinge = rest[list(_EAR_POINTS)].mean(axis=0)
    corners = rest[list(_MOUTH_CORNERS), 1].mean()
    beside = np.clip((0.4 * width - np.abs(rest[:, 0] - hinge[0])) / (0.1 * width), 0.0, 1.0)
    below = np.clip((corners - 0.02 * width - rest[:, 1]) / (0.1 * width), 0.0, 1.0)
    share = beside * below
    return share * share * (3 - 2 * share)
