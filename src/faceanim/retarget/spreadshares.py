"""How much of the skin's spread each skin vertex takes, and how it is bounded.

The spread (:class:`~faceanim.retarget.transfer.SparseTransfer`, biharmonic along the skin) carries the
control points' motion to the skin between them. Two per-vertex shares shape it in
:class:`~faceanim.retarget.deform.PartsDeformer`: how far each vertex's field is bounded (round the lips it
stays biharmonic, :func:`bounded_shares`), and how much of the motion it takes at all (the scalp above the
face mesh is held, :func:`scalp_hold`).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..landmarks import LIP_INNER, LIP_OUTER, landmark_names
from ..target import Target

__all__ = ["LIPS_UNBOUNDED", "SCALP_FADE", "bounded_shares", "scalp_hold"]

#: Of the mouth's width: the skin spreads its controls' motion as the biharmonic field within the first of
#: the lips' control points, bounded (no vertex past its controls) beyond the second, and blended between.
LIPS_UNBOUNDED = (0.25, 0.5)


#: Of the face's ES0: above the top of its face mesh (MediaPipe's points placed on it) the skin's spread
#: fades out over this height, and the skin beyond is held (:func:`scalp_hold`).
SCALP_FADE = 0.15
_FOREHEAD_TOP = 10  # MediaPipe's face-mesh point at the top of the forehead's middle


def scalp_hold(target: Target, skin_vertices: np.ndarray, up: np.ndarray) -> np.ndarray | None:
    """``(S,)`` per skin vertex, the share of the spread's motion it takes: 1 up to the height (along
    ``up``) of the highest of the target's points placed as MediaPipe's face mesh, falling linearly to 0
    over :data:`SCALP_FADE` x its ES0 above it; None for a target without a FAPU or without the face
    mesh's forehead top (MediaPipe's point 10): where some of MediaPipe's points carry MPEG-4 names
    (:func:`~faceanim.landmarks.landmark_names`), a target given its feature points alone has those, and
    its highest, the brows, would hold the forehead.

    Above the face mesh's top (MediaPipe's forehead top, 1.7-1.9 cm above the brows on ICT's faces)
    nothing is measured, and the spread carried a brow raise on up the forehead, decaying with its
    falloff: 0.07-0.26 cm up at 2-6 cm above the brows on the round trip's tuning seeds, where ICT's brow
    raise moves the skin 0.1-0.15 cm down and 0.2 forward (the forehead bunches; the hairline does not rise
    with the brows, the frontalis pulling the brows up towards it). Held instead, past a fade of about a
    centimetre: the tuning seeds' brows 0.499 -> 0.464 (motion route; no video 0.374 -> 0.341), every
    segment else within 0.002, every seed better; a fade from half a centimetre below the top 0.465, over
    2 cm 0.470 (``benchmarks/roundtrip_ict.py``, scratch runs 2026-11-28). The top is the face mesh's, not
    the highest control's: driven through its MPEG-4 feature points alone (``--via faps``), whose highest
    are the brows, the forehead between brows and hairline was held too, and seed 3's brows went 0.50 ->
    0.68 through the FAPs."""
    mesh_names = landmark_names(468)
    names = [name for name in mesh_names if name in target.points]
    if mesh_names[_FOREHEAD_TOP] not in target.points or target.fapu is None or not target.fapu.es0 > 0:
        return None
    top = float((target.mesh.vertices[target.ids(names)] @ up).max())
    return np.clip(1.0 - (skin_vertices @ up - top) / (SCALP_FADE * target.fapu.es0), 0.0, 1.0)


def bounded_shares(target: Target, skin_vertices: np.ndarray) -> np.ndarray:
    """``(S,)`` per skin vertex, how far its spread is bounded (see ``BiharmonicInterpolation``).

    Bounded, no skin vertex moves past its controls: the biharmonic field's negative lobes carried a lid's
    skin past its lash line and amplified a tracker's errors between neighbouring points (on the ICT round
    trip's tuning seeds, blink 0.623 -> 0.582 and brows 0.537 -> 0.525 bounded everywhere). At the lips the
    bounded field turned a few triangles on the line where the lips meet in some wide smiles, and the fold
    relaxer then flattened the smile (round-trip pairs 109 and 309 with no video: the smile's worst 5% of
    frames 0.43 -> 0.60), so round the lips it stays biharmonic. A target without named lip points is
    bounded everywhere."""
    lips = [n for n in (landmark_names(478)[i] for i in LIP_OUTER + LIP_INNER) if n in target.points]
    width = target.mouth_width
    if not lips or width <= 0:
        return np.ones(len(skin_vertices))
    near, far = (width * share for share in LIPS_UNBOUNDED)
    distance, _ = cKDTree(target.mesh.vertices[target.ids(lips)]).query(skin_vertices)
    return np.clip((distance - near) / (far - near), 0.0, 1.0)
