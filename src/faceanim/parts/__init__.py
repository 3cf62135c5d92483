"""The parts of a face target, told apart by how each must move.

A head model is more than its skin: teeth, gums and tongue behind the lips, eyeballs behind the lids,
lashes and tear films on the lids. Interpolating control-point motion over all of it tears what must
stay whole (a lower incisor stretched between the jaw and the skull) and leaves behind what must
follow (teeth that stay put while the chin drops 2 cm). Each vertex therefore gets a *role*:

``skin``
    deformed: a turn about the jaw hinge weighted by :attr:`FaceParts.jaw_weight` (1 on the chin,
    fading through the cheeks to 0 at the upper lip, the ears and the neck), with the tracked
    residual spread on top by surface interpolation.
``upper_teeth`` / ``lower_teeth``
    rigid with the skull / with the jaw (teeth, gums, tongue, palate; a piece straddling the bite,
    like one mesh of both gums and the tongue, is split vertex by vertex, with a short blend).
``eye_left`` / ``eye_right``
    eyeballs: turn about their centres with the gaze.
``lid_layer``
    lashes, eye-occlusion and tear layers: ride on the nearest skin.
``socket``
    the lining of an opening as a separate piece (a mouth socket, or an eye cap that is no ball), or
    the inside of a mouth whose skin runs on past the lips, cut off at their inner rims
    (:mod:`faceanim.parts.mouth`): it hangs from its rim, which rides on the lips or the lids, and
    deep inside it is held by the gums (turned with the jaw below the bite).
``static``
    anything else that holds no control point (hair, a hat): keeps still with the skull.

Parts are known from the labels a file carries (OBJ materials or groups, the part names a faceanim
``.glb`` keeps), from a ``--parts PARTS.json`` file, or found from the geometry: connected
components, and where each sits against the eyes, the lip line and the chin (and, for a mouth's inside,
the loop through the lips' inner rims; not when a parts file is given). All positions are
measured in the face's own frame and in FAPU-relative terms, so nothing depends on the mesh's unit.
"""

from __future__ import annotations

import numpy as np

from ..target import Target
from .faceparts import _ROLE, INNER_LIP_POINTS, ROLES, FaceParts
from .frame import _FRAME_POINTS, _Frame, _smoothstep, face_axes
from .jaw import _skin_jaw_weight
from .labels import _vertex_hints, read_parts_file
from .mouth import mouth_inside
from .pieces import _eye_centre, _roles, _skin_only
from .teeth import _centre_behind_the_teeth, _fitted_bite, _split_teeth, _teeth_pieces

__all__ = ["ROLES", "FaceParts", "face_parts", "read_parts_file", "face_axes", "INNER_LIP_POINTS"]


def face_parts(target: Target, *, labels: dict | None = None, source: str = "") -> FaceParts:
    """The parts of ``target``: from ``labels`` (see :func:`read_parts_file`), else the part names the
    mesh carries, else its geometry. Without ``labels``, skin cut off behind the lips' inner rims is the
    mouth's inside, a socket (:func:`~faceanim.parts.mouth.mouth_inside`); with them, what they call skin stays skin.

    Raises
    ------
    InputError
        The parts cannot be told apart (no skin holds the control points, labels name parts the mesh
        lacks); the message says what is missing and how to label it.
    """
    mesh = target.mesh
    where = f"{source}: " if source else ""
    at = {n: mesh.vertices[i] for n, i in target.points.items()}
    if any(n not in at for n in _FRAME_POINTS):
        return _skin_only(target, where)
    axes = face_axes(at)
    frame = _Frame(axes, at, target)
    hint = _vertex_hints(mesh, labels, where)
    role, kind = _roles(mesh, target, frame, hint, where)
    if labels is None:  # a parts file is the user's word on what is skin
        role[mouth_inside(mesh, role == _ROLE["skin"], target, axes[2], frame.mouth_width)] = _ROLE["socket"]
    eye_centres = np.stack([_eye_centre(mesh, role == _ROLE[side], frame, side) for side in ("eye_left", "eye_right")])
    jaw = np.zeros(len(mesh.vertices))
    # The frame's bite and turning centre start from the feature points; the teeth, where there are
    # any, say better, in this order (the centre sits level with the bite).
    pieces, centres = _teeth_pieces(mesh, kind, frame)
    bite = _fitted_bite(centres, frame)
    if bite is not None:
        frame.bite = bite
    _split_teeth(mesh, role, kind, jaw, frame, pieces, centres, fitted=bite is not None)
    centre = _centre_behind_the_teeth(mesh, (role == _ROLE["lower_teeth"]) & np.isin(kind, ("rigid", "given")), frame)
    if centre is not None:
        frame.move_centre(centre)
    split = kind == "split"
    if split.any():  # the tongue's root, behind the turning centre, hangs from the skull, not the jaw
        jaw[split] *= _in_front_of_centre(mesh.vertices[split], frame)
    skin = role == _ROLE["skin"]
    jaw[skin] = _skin_jaw_weight(mesh, skin, frame, target)
    socket = role == _ROLE["socket"]
    # A socket's floor goes with the jaw, as far back as the turning centre (a bag that runs on into the
    # throat hangs from the skull there, as the tongue's root does).
    jaw[socket] = frame.below_bite(mesh.vertices[socket]) * _in_front_of_centre(mesh.vertices[socket], frame)
    return FaceParts(role, np.clip(jaw, 0.0, 1.0), frame.hinge, axes, eye_centres)


def _in_front_of_centre(points: np.ndarray, frame: _Frame) -> np.ndarray:
    """``(N,)`` 1 in front of the jaw's turning centre, 0 behind it, a smooth step of a fifth of the
    mouth's width between."""
    depth = frame.local(points)[:, 2] - frame.hinge_local[2]
    return _smoothstep(depth / (0.2 * frame.mouth_width))
