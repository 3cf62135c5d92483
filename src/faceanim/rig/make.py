"""The 52 ARKit shapes made on any target face by carrying ICT-FaceKit's expressions across.

ICT's neutral head is registered onto the target densely (a thin-plate warp through the control
pairs, then non-rigid ICP with the face's contours matched as curves;
:mod:`~faceanim.retarget.correspondence`); each target vertex lands on the registered ICT surface and
takes the displacement there (:class:`~faceanim.retarget.DenseTransfer`). The displacements keep ICT's
sizes, in the target's unit: ICT's centimetres times the power of ten nearest the scale that best maps
ICT's control points onto the target's (a target in metres gets shapes in metres). They are not scaled
to the target's face size nor turned: ICT adds the same expression shapes to every identity, and a
similarity fitted between two different faces turns and scales them by the faces' difference in shape
(on the tuning draw of ``benchmarks/rig_ict.py``, median error 0.20 -> 0.27). Axes are the house's:
+y up, +z out of the face, as automatic placement needs.

The control pairs are the 68 iBUG / Multi-PIE points, on the target MediaPipe's points of that layout
(``mp<i>`` through :data:`~faceanim.landmarks.IBUG68_LANDMARK`). Where the target's points
were placed by MediaPipe (all 468 face points present: automatic placement, or a faceanim ``.glb``
that carries them), ICT's are placed by MediaPipe too (:func:`~faceanim.retarget.placement.place_landmarks`
on ICT's neutral head), so both sides carry the tracker's own bias: on the tuning draw of
``benchmarks/rig_ict.py`` this takes the median error from 0.31 (ICT's own landmark vertices against
placed target points) to 0.20. Where only the 68 are named (a JSON file written by hand), they are
taken as exact and paired with ICT's own landmark vertices. A target that only names MPEG-4 feature
points (a JSON or ``.fdp`` file) is paired through the thesis' 16 points, which the 68 layout also
marks.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..geometry.align import weighted_procrustes
from ..landmarks import IBUG68_LANDMARK
from ..mpeg4.multipie import MULTIPIE68_OF_FEATURE_POINT, THESIS_16
from ..retarget.transfer import ControlPairs, DenseTransfer
from ..target import Target
from ..validation import as_array
from .arkit import ARKIT_NAMES, ICT_SHAPES
from .ictface import IctFaceKit

__all__ = ["ArkitRig", "make_arkit_rig", "control_pairs"]


@dataclass(frozen=True, eq=False)
class ArkitRig:
    """The 52 ARKit shapes on a target.

    ``target``: the face (its mesh's vertices, in its own order and units, are the rest);
    ``names (52,)``: :data:`~faceanim.rig.arkit.ARKIT_NAMES`; ``shapes (52, V, 3)``: each shape's
    displacement at weight 1 (model units, read-only); ``layout``: the control pairs used
    (``ibug68`` or ``thesis16``); ``fit``, ``landmark_error``: the registration's residuals (relative
    to ICT's size, see :class:`~faceanim.geometry.nicp.NicpOptions`).
    """

    target: Target
    names: tuple[str, ...]
    shapes: np.ndarray
    layout: str
    fit: float
    landmark_error: float

    def __post_init__(self):
        shapes = as_array(self.shapes, "shapes", shape=(len(self.names), len(self.target.mesh.vertices), 3),
                          frozen=True)
        object.__setattr__(self, "shapes", shapes)
        object.__setattr__(self, "names", tuple(self.names))


def control_pairs(ict: IctFaceKit, target: Target) -> tuple[np.ndarray, np.ndarray, str]:
    """ICT vertex ids, the target's vertex ids of the same points, and their layout (``ibug68`` or
    ``thesis16``); an :class:`~faceanim.errors.InputError` naming what is missing when the target
    has neither."""
    named = [f"mp{i}" for i in IBUG68_LANDMARK]
    if all(n in target.points for n in named):
        placed = all(f"mp{i}" in target.points for i in range(_MEDIAPIPE_FACE_POINTS))
        return (_placed_on_ict(ict) if placed else ict.landmarks.copy()), target.ids(named), "ibug68"
    if all(n in target.points for n in THESIS_16):
        source = ict.landmarks[[MULTIPIE68_OF_FEATURE_POINT[n] for n in THESIS_16]]
        return source, target.ids(THESIS_16), "thesis16"
    missing = [n for n in THESIS_16 if n not in target.points]
    raise InputError(f"the rig needs the target's face points: MediaPipe's (placed automatically when no --points "
                     f"is given) or the MPEG-4 feature points {', '.join(THESIS_16)}; missing {', '.join(missing)}")


_MEDIAPIPE_FACE_POINTS = 468  # MediaPipe's face mesh without the irises
_placements: dict = {}


def _placed_on_ict(ict: IctFaceKit) -> np.ndarray:
    """ICT vertex ids of the 68 layout as MediaPipe places it on ICT's neutral head (kept per model)."""
    from ..retarget.placement import place_landmarks

    key = id(ict)
    if key not in _placements or _placements[key][0] is not ict:
        _placements.clear()
        _placements[key] = (ict, place_landmarks(ict.mesh)[np.asarray(IBUG68_LANDMARK)])
    return _placements[key][1].copy()


def make_arkit_rig(target: Target, ict: IctFaceKit) -> ArkitRig:
    """The 52 ARKit shapes on ``target``, carried from ``ict`` (see the module's notes).

    Raises
    ------
    InputError
        The target lacks the control points, or the registration did not converge (the message gives
        the residuals reached).
    """
    source_ids, target_ids, layout = control_pairs(ict, target)
    # Not ControlPairs.checked: on a coarse mesh two points may snap to one vertex, which the registration
    # takes (two landmarks pulled to one place) and the layout's contours need in their places.
    pairs = ControlPairs(source_ids, target_ids)
    dense = DenseTransfer(ict.mesh, target.mesh, pairs, contours=layout)
    similarity = weighted_procrustes(ict.mesh.vertices[source_ids], target.mesh.vertices[target_ids])
    unit = 10.0 ** np.round(np.log10(np.cbrt(np.linalg.det(similarity[:3, :3]))))  # target units per ICT cm
    deltas = unit * np.stack([ict.delta(ICT_SHAPES[name]) for name in ARKIT_NAMES], axis=1)  # (Vs, 52, 3)
    carried = dense.matrix @ deltas.reshape(len(deltas), -1)
    shapes = np.ascontiguousarray(np.asarray(carried).reshape(len(target.mesh.vertices), len(ARKIT_NAMES), 3)
                                  .transpose(1, 0, 2))
    reg = dense.registration
    return ArkitRig(target, ARKIT_NAMES, shapes, layout, float(reg.fit), float(reg.landmark_error))
