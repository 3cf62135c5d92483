"""The lips and their surroundings as a mesh, as the clone's analysis by synthesis draws them (:mod:`.analysis`):
the synthesis mesh's own triangles around the mouth (:func:`mouth_mesh`, the colour comparison) or a
reduced mesh of at most 50 triangles (:func:`analysis_mesh`, the lip-probability comparison).

The reduced analysis mesh is chosen from the model's points by name: 12 points of the outer lip
contour and 14 of the inner (MediaPipe's lip landmarks), and a ring of 8 points around the mouth (the
model's points nearest to an ellipse of 0.95 x 0.7 mouth widths), triangulated again (Delaunay over
the rest shape's x, y): 34 points, at most 50 triangles (inner points are dropped, last first, while
there are more). The key textures are read at each point's UV: a coarser cut of the same surface.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import Delaunay

from ..errors import InputError
from ..landmarks import landmark_names
from ..validation import as_index_array
from .model import SpeakerModel

__all__ = ["AnalysisMesh", "analysis_mesh", "mouth_mesh", "MAX_TRIANGLES"]

MAX_TRIANGLES = 50
# MediaPipe's lip contours (outer and inner, each from the right corner along the upper lip and back
# along the lower), thinned to 12 and 14 points: the opening, where the lips' image changes most, has
# the more (14 inner points against 8 measured a little closer to MediaPipe's opening on the build frames).
_OUTER = (61, 40, 37, 0, 267, 270, 291, 321, 314, 17, 84, 91)
_INNER = (78, 191, 80, 81, 13, 311, 310, 415, 308, 318, 402, 14, 178, 88)
_RING = 8
_RING_AXES = (0.95, 0.7)  # in mouth widths: the ring lies beyond the box
# The synthesis mesh's triangles the colour comparison draws: those whose centre (rest shape, head frame)
# lies within 0.95 mouth widths across, 0.6 above and 0.75 below the lips' centre (the box, 0.75 x
# 0.425 mouth widths about the mouth, with room for the jaw to drop).
_MOUTH_REGION = (0.95, 0.6, 0.75)


def _mp_name(index: int) -> str:
    return landmark_names(478)[index]


@dataclass(frozen=True, eq=False)
class AnalysisMesh:
    """The lips and their surroundings as a mesh: the reduced mesh of the lip-probability comparison
    (:func:`analysis_mesh`, at most 50 triangles) or the synthesis mesh's triangles around the mouth
    (:func:`mouth_mesh`, the colour comparison).

    Parameters
    ----------
    points : (V,) int64
        Indices into the model's mobile then static points.
    triangles : (F, 3) int64
        Into ``points``.
    outer, inner : (12,), (<= 14,) int64
        The lip contours (indices into ``points``, in order around the mouth).
    """

    points: np.ndarray
    triangles: np.ndarray
    outer: np.ndarray
    inner: np.ndarray

    def __post_init__(self):
        points = as_index_array(self.points, "points", upper=np.iinfo(np.int64).max, shape=("V",), frozen=True)
        V = len(points)
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "triangles", as_index_array(self.triangles, "triangles", upper=V, shape=("F", 3),
                                                             frozen=True))
        object.__setattr__(self, "outer", as_index_array(self.outer, "outer", upper=V, shape=("L",), frozen=True))
        object.__setattr__(self, "inner", as_index_array(self.inner, "inner", upper=V, shape=("M",), frozen=True))

    @property
    def lips(self) -> np.ndarray:
        return np.concatenate([self.outer, self.inner])


def _lip_points(model: SpeakerModel) -> tuple[list[int], list[int]]:
    """The outer and inner lip contours' indices into the model's mobile then static points."""
    names = tuple(model.names) + tuple(model.static_names)
    lookup = {n: i for i, n in enumerate(names)}
    outer = [lookup[_mp_name(i)] for i in _OUTER if _mp_name(i) in lookup]
    inner = [lookup[_mp_name(i)] for i in _INNER if _mp_name(i) in lookup]
    if len(outer) < len(_OUTER) or len(inner) < len(_INNER):
        raise InputError("the speaker model lacks the lip contour points the analysis needs "
                         f"({len(_OUTER) - len(outer) + len(_INNER) - len(inner)} of MediaPipe's lip points missing)")
    return outer, inner


def mouth_mesh(model: SpeakerModel, triangles=None, opening=None) -> AnalysisMesh:
    """The synthesis mesh around the mouth: the triangles of ``triangles (F, 3)`` (into the model's
    mobile then static points; default the model's) whose centre at rest lies in the region
    :data:`_MOUTH_REGION` about the lips, so that the analysis draws exactly the surface the clone's
    renderer draws there (same vertices, same UV, same triangles). ``opening``: the indices of the
    inner lip contour (``Appearance.lip_inner``); the triangles with all three corners on it (those
    spanning the mouth's opening, textured with the key frames' teeth and tongue) are left out, so the
    opening is compared as a region of its own colour.

    Raises
    ------
    InputError
        The model lacks MediaPipe's lip points, or no triangle holds them.
    """
    outer, inner = _lip_points(model)
    everything = np.vstack([model.rest, model.static_points])
    t = np.asarray(model.triangles if triangles is None else triangles, dtype=np.int64)
    lips = everything[outer]
    centre, width = lips.mean(axis=0), np.ptp(lips[:, 0])
    d = (everything[t].mean(axis=1) - centre)[:, :2] / width
    across, above, below = _MOUTH_REGION
    keep = (np.abs(d[:, 0]) <= across) & (d[:, 1] <= above) & (d[:, 1] >= -below)
    if opening is not None and len(opening):
        keep &= ~np.isin(t, np.asarray(opening, dtype=np.int64)).all(axis=1)
    t = t[keep]
    points = np.unique(t)
    if not np.isin(outer + inner, points).all():
        raise InputError("the speaker model's triangles do not hold its lip contour points")
    at = np.searchsorted(points, np.arange(len(everything)))
    return AnalysisMesh(points, at[t], at[outer], at[inner])


def analysis_mesh(model: SpeakerModel) -> AnalysisMesh:
    """The reduced :class:`AnalysisMesh` of ``model`` (at most 50 triangles; see the module's
    docstring for the choice).

    Raises
    ------
    InputError
        The model lacks MediaPipe's lip points (a model not built by ``faceanim speaker build``).
    """
    outer, inner = _lip_points(model)
    everything = np.vstack([model.rest, model.static_points])
    lips = everything[outer]
    centre = lips.mean(axis=0)
    width = np.ptp(lips[:, 0])
    taken = set(outer + inner)
    ring = []
    for angle in np.linspace(0, 2 * np.pi, _RING, endpoint=False):
        target = centre[:2] + width * np.array([_RING_AXES[0] * np.cos(angle), _RING_AXES[1] * np.sin(angle)])
        distance = np.linalg.norm(everything[:, :2] - target, axis=1)
        distance[list(taken)] = np.inf
        best = int(np.argmin(distance))
        taken.add(best)
        ring.append(best)
    chosen = np.array(outer + inner + ring)
    triangles = Delaunay(everything[chosen, :2]).simplices.astype(np.int64)
    while len(triangles) > MAX_TRIANGLES:  # points that coincide at rest leave a hull of fewer points
        chosen = np.delete(chosen, len(outer) + len(inner) - 1)
        inner = inner[:-1]
        triangles = Delaunay(everything[chosen, :2]).simplices.astype(np.int64)
    return AnalysisMesh(chosen, triangles, np.arange(len(outer)), len(outer) + np.arange(len(inner)))
