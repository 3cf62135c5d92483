"""Dense correspondence between two faces: the source registered onto the target, cached per pair.

The source's parts that hold a control point are warped through the control pairs (a thin-plate
spline, exact for any affine difference in pose and size), then registered onto the target's surface
by optimal-step non-rigid ICP (:func:`~faceanim.geometry.nicp.register_surface`), with the control
points as landmarks and, for a known control-point layout, the face's contours (lip lines, eyelids,
brows, nose) matched as curves (:mod:`~faceanim.retarget.contours`) as further landmarks at half
weight, and the eyes' rims (where a target without eye sockets ends inside the lids,
:func:`~faceanim.retarget.contours.opening_rims`) likewise, and the upper lids' skin at its relative
height between the lid line and the brow (:func:`~faceanim.retarget.contours.lid_bands`, weight
:data:`LID_WEIGHT`). The registration also records which side of
the eye openings and the mouth each source vertex lies on (:func:`~faceanim.retarget.contours.opening_sides`,
:data:`~faceanim.retarget.contours.SIDED`), so that :class:`~faceanim.retarget.DenseTransfer` never
carries motion across the lids or the lips (but at the mouth's corners,
:data:`~faceanim.retarget.contours.SIDE_CORNERS`).

A registration takes seconds to tens of seconds (26,719 vertices), so it is kept in an in-process
LRU cache of the last :data:`CACHE_SIZE` registrations, keyed by SHA-1 digests of both meshes'
vertices and triangles, the control pairs, the contour layout and the options. Nothing is written
to disk: a registration is tied to the exact meshes, and a stale file cache could hand back one
made for another version of a mesh.
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from ..geometry.mesh import Mesh
from ..geometry.nicp import NicpOptions, register_surface
from ..geometry.rbf import RbfWarp
from ..geometry.topology import component_labels
from .contours import (
    LANDMARK_WEIGHTS,
    LAYOUT_SIZES,
    LAYOUTS,
    LID_BANDS,
    SIDE_CORNERS,
    SIDED,
    lid_bands,
    matched_contours,
    opening_rims,
    opening_sides,
)

__all__ = ["FaceRegistration", "register_faces", "CACHE_SIZE", "CONTOUR_WEIGHT", "LID_UPPER", "LID_WEIGHT",
           "RIM_WEIGHT"]

CACHE_SIZE = 8
CONTOUR_WEIGHT = 0.5  # landmark weight of a contour point, relative to a control point
RIM_WEIGHT = 0.5  # landmark weight of a point on an opening's rim (see contours.opening_rims)
#: Landmark weight of a point of the upper lids' skin placed by its height between lid and brow
#: (contours.lid_bands). ICT-FaceKit's tuning pairs, clone 68 median / worst before -> after:
#: seed 4 (sigma 2.5) 0.175 / 0.441 -> 0.151 / 0.391, seed 5 (sigma 2.5) 0.141 / 0.441 -> 0.138 / 0.360,
#: 11: 0.098 / 0.291 -> 0.084 / 0.258, 7: 0.077 / 0.159 -> 0.071 / 0.159, 3 unchanged. The relative height is
#: itself only good to about 0.1 cm across identities, so the band is a weak pull, not a contour: at 0.1,
#: seed 11's eyeBlink_R rose to 0.300 and seed 7's to 0.164 (from 0.087).
LID_WEIGHT = 0.05
#: What the lid band measures height to (contours.LID_UPPER_ENDS): the brow. The crease, or the mean of the two
#: landings, were measured on the tuning pairs and not adopted (see contours.lid_bands; 2026-11-23,
#: benchmarks/transfer_ict_lids.py): "mean" helped the sigma-2.5 seed 5 (0.138 / 0.360 -> 0.131 / 0.333) and
#: seed 4's eyeBlink_L, but took sigma-1.5 seed 11 from 0.084 / 0.258 to 0.089 / 0.294.
LID_UPPER = "brow"
# No band places the skin round the mouth. Tried (2026-11-23, tuning pairs only): each vertex placed by its
# relative place between the outer lip line and a ring through the jaw line under the mouth and the nose base,
# by angle read off the lip loop, as landmarks at weight 0.05. On the sigma-2.5 pairs 4 and 5 those relative
# places put the same skin 0.41 / 0.39 cm apart (median; coordinates like the lid band's, across and up the upper
# lip, 0.08-0.29 cm even on ICT's own triangulation), where the registration lands it within 0.23 / 0.19 cm:
# seed 4 went 0.151 -> 0.148, seed 5 0.138 -> 0.149. That skin registered exactly would give 0.122 / 0.127
# (benchmarks/results/transfer_ict_budget.md): no one region's registration error holds those pairs' medians.
_cache: OrderedDict = OrderedDict()


@dataclass(frozen=True, eq=False)
class FaceRegistration:
    """``mesh``: the source's registered part (its own triangles, target units); ``source_vertices (N,)``:
    the source vertex id of each of its vertices; ``fit`` and ``landmark_error`` as in
    :class:`~faceanim.geometry.nicp.Registration`; ``contour_points``: how many contour points held it;
    ``layout``: the control points' layout (None when none was matched) and ``sides (N,)``: which side of
    the layout's :data:`~faceanim.retarget.contours.SIDED` openings each vertex lies on
    (:func:`~faceanim.retarget.contours.opening_sides`; all 0 without a layout)."""

    mesh: Mesh
    source_vertices: np.ndarray
    fit: float
    landmark_error: float
    contour_points: int
    layout: str | None = None
    sides: np.ndarray | None = None


def _digest(*arrays) -> str:
    h = hashlib.sha1()
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(str((a.dtype.str, a.shape)).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def register_faces(source: Mesh, target: Mesh, source_ids, target_ids, *, contours: str | None = "auto",
                   options: NicpOptions | None = None) -> FaceRegistration:
    """Register the source face onto the target face (cached; see the module text).

    Parameters
    ----------
    source, target : Mesh
    source_ids, target_ids : (K,) int64
        Control pairs, ``K >= 4``.
    contours : {"auto", "ibug68", "thesis16"} or None
        The control points' layout, whose contours are matched as curves. ``auto``: ``ibug68`` for
        68 pairs (the iBUG / Multi-PIE order), none otherwise.
    options : NicpOptions, optional

    Raises
    ------
    InputError
        The registration did not converge (the message gives the residuals reached).
    """
    options = NicpOptions() if options is None else options
    source_ids = np.asarray(source_ids, dtype=np.int64)
    target_ids = np.asarray(target_ids, dtype=np.int64)
    if contours == "auto":
        contours = "ibug68" if len(source_ids) == 68 else None
    if contours is not None and contours not in LAYOUTS:
        raise ValueError(f"contours must be 'auto', None or one of {', '.join(LAYOUTS)}, got {contours!r}")
    if contours is not None and len(source_ids) != LAYOUT_SIZES[contours]:
        raise ValueError(f"the {contours} layout has {LAYOUT_SIZES[contours]} control points, "
                         f"got {len(source_ids)} pairs")
    key = (_digest(source.vertices, source.triangles), _digest(target.vertices, target.triangles),
           _digest(source_ids, target_ids), contours, LID_UPPER, repr(options))
    if key in _cache:
        _cache.move_to_end(key)
        return _cache[key]
    result = _register(source, target, source_ids, target_ids, contours, options)
    _cache[key] = result
    while len(_cache) > CACHE_SIZE:
        _cache.popitem(last=False)
    return result


def _part_with(mesh: Mesh, ids: np.ndarray) -> tuple[Mesh, np.ndarray, np.ndarray]:
    """The parts (connected components) of ``mesh`` that hold any of ``ids``: the sub-mesh, its
    vertices' ids in ``mesh``, and ``ids`` in the sub-mesh."""
    label = component_labels(mesh)
    keep = np.isin(label, np.unique(label[ids]))
    keep &= np.isin(np.arange(len(mesh.vertices)), np.unique(mesh.triangles))
    kept = np.flatnonzero(keep)
    index = np.full(len(mesh.vertices), -1)
    index[kept] = np.arange(len(kept))
    tris = index[mesh.triangles]
    return Mesh(mesh.vertices[kept], tris[(tris >= 0).all(axis=1)]), kept, index[ids]


def _register(source, target, source_ids, target_ids, contours, options) -> FaceRegistration:
    # Only the parts that hold control points take part: not the teeth, eyeballs or lashes of either.
    part, kept, local = _part_with(source, source_ids)
    target, _, target_ids = _part_with(target, target_ids)

    landmarks, points = local, target.vertices[target_ids]
    weights = np.ones(len(local))
    if contours is not None:
        for k, w in LANDMARK_WEIGHTS.get(contours, {}).items():
            weights[k] = w
        on_curve, curve_points = matched_contours(part, target, local, target_ids, contours)
        on_rim, rim_points = opening_rims(part, target, local, target_ids, contours)
        fresh = ~np.isin(on_rim, np.r_[landmarks, on_curve])
        landmarks = np.r_[landmarks, on_curve, on_rim[fresh]]
        points = np.r_[points, curve_points, rim_points[fresh]]
        weights = np.r_[weights, np.full(len(on_curve), CONTOUR_WEIGHT), np.full(fresh.sum(), RIM_WEIGHT)]
        if LID_BANDS[contours]:
            on_lid, lid_points = lid_bands(part, target, local, target_ids, contours, upper=LID_UPPER)
            fresh = ~np.isin(on_lid, landmarks)
            landmarks = np.r_[landmarks, on_lid[fresh]]
            points = np.r_[points, lid_points[fresh]]
            weights = np.r_[weights, np.full(fresh.sum(), LID_WEIGHT)]
    src_pts = part.vertices[local]
    warp = RbfWarp(src_pts, target.vertices[target_ids] - src_pts, kernel="thin_plate")
    start = part.vertices + warp(part.vertices)
    reg = register_surface(part, target, source_landmarks=landmarks, target_points=points,
                           landmark_weights=weights, initial=start, options=options)
    sides = np.zeros(len(kept), dtype=np.int64) if contours is None else \
        opening_sides(part, local, contours, openings=SIDED[contours], corners=SIDE_CORNERS[contours])
    return FaceRegistration(Mesh(reg.vertices, part.triangles), kept, reg.fit, reg.landmark_error,
                            len(landmarks) - len(local), contours, sides)


def clear_cache() -> None:
    """Forget every cached registration."""
    _cache.clear()
