"""Pieces of a mesh told apart: by their labels, or by where they sit (skin, eyeballs, lid layers,
teeth, sockets); eyeball centres."""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph

from ..errors import InputError
from ..geometry.mesh import Mesh
from ..geometry.topology import component_labels
from ..target import Target
from .faceparts import _EYEBALL_POINTS, _ROLE, FaceParts
from .frame import _Frame


def _skin_only(target: Target, where: str) -> FaceParts:
    """The parts of a target without the feature points that place a face (eye corners, mouth
    corners, chin): the pieces holding control points are skin, everything else keeps still, and
    nothing turns with a jaw."""
    mesh = target.mesh
    part = component_labels(mesh)
    on_skin = np.unique(part[[i for n, i in target.points.items() if n not in _EYEBALL_POINTS]])
    if not len(on_skin):
        raise InputError(f"{where}no part of the mesh holds the control points, so its skin cannot be found; "
                         "label its parts with --parts PARTS.json")
    role = np.where(np.isin(part, on_skin), _ROLE["skin"], _ROLE["static"])
    V = len(mesh.vertices)
    return FaceParts(role, np.zeros(V), np.zeros(3), np.eye(3), np.zeros((2, 3)))


def _roles(mesh: Mesh, target: Target, frame: _Frame, hint: np.ndarray, where: str):
    """Vertex roles, and for mouth pieces the kind ("rigid" per piece, "split" per vertex)."""
    V = len(mesh.vertices)
    part = component_labels(mesh)
    on_skin = [i for n, i in target.points.items() if n not in _EYEBALL_POINTS]
    skin_parts = np.unique(part[on_skin])
    if not len(skin_parts):
        raise InputError(f"{where}no part of the mesh holds the control points, so its skin cannot be found; "
                         "label its parts with --parts PARTS.json")
    role = np.full(V, _ROLE["static"], dtype=np.int64)
    kind = np.full(V, "", dtype=object)
    for label in np.unique(part):
        ids = np.flatnonzero(part == label)
        pieces = _by_hint(mesh, ids, hint)
        for named, piece in pieces:
            centre = frame.local(mesh.vertices[piece].mean(axis=0)[None])[0]
            found = named or _role_of_place(mesh, piece, centre, frame, is_skin=label in skin_parts)
            if found == "teeth":
                kind[piece] = "rigid"  # upper or lower (or split, if it straddles the bite): _split_teeth
                role[piece] = _ROLE["upper_teeth"]
            elif found in ("upper_teeth", "lower_teeth"):
                role[piece] = _ROLE[found]
                kind[piece] = "given"
            elif found == "eye" and label in skin_parts:
                role[piece] = _ROLE["skin"]  # an eye cap stitched to the lids must follow them, not turn alone
            elif found == "eye" and not _is_ball(mesh.vertices[piece], frame):
                role[piece] = _ROLE["socket"]  # a flat cap painted as an eye: it must not part from the lids
            elif found == "eye":
                role[piece] = _ROLE["eye_left" if centre[0] > frame.mouth[0] else "eye_right"]
            else:
                role[piece] = _ROLE[found]
    if not (role == _ROLE["skin"]).any():
        raise InputError(f"{where}every part holding control points is labelled as something other than skin; "
                         "label the skin with --parts PARTS.json")
    return role, kind


def _by_hint(mesh: Mesh, ids: np.ndarray, hint: np.ndarray) -> list:
    """A connected piece split by its vertices' labels into connected pieces of one label each:
    ``[(role or "", vertex ids), ...]``."""
    values = hint[ids]
    if len(set(values.tolist())) == 1:
        return [(values[0], ids)]
    e = mesh.edges
    e = e[hint[e[:, 0]] == hint[e[:, 1]]]
    V = len(mesh.vertices)
    graph = sparse.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(V, V))
    labels = csgraph.connected_components(graph, directed=False)[1][ids]
    return [(hint[ids[labels == k][0]], ids[labels == k]) for k in np.unique(labels)]


def _role_of_place(mesh: Mesh, piece: np.ndarray, centre: np.ndarray, frame: _Frame, *, is_skin: bool) -> str:
    """The role of an unlabelled piece from where it sits."""
    if is_skin:
        return "skin"
    for eye in frame.eyes.values():
        if np.linalg.norm(centre - eye) < 0.9 * frame.eye_width:
            local = frame.local(mesh.vertices[piece])
            size = np.ptp(local, axis=0)
            # An eyeball is as deep as it is wide and sits behind the lids; lashes and films are thin.
            round_enough = size.min() > 0.35 * frame.eye_width
            return "eye" if round_enough and centre[2] < eye[2] else "lid_layer"
    if frame.in_mouth(centre):
        return "teeth"
    return "static"


def _is_ball(points: np.ndarray, frame: _Frame) -> bool:
    """Whether points lie on a sphere of an eyeball's size (an eyeball, or its iris): a person's is
    about 1.2 cm across its radius against an eye 3 cm wide from corner to corner."""
    return _sphere(points, 0.6 * frame.eye_width) is not None


def _sphere(points: np.ndarray, largest: float):
    """The centre of the sphere through ``points`` (least squares), or None where they make none of
    radius under ``largest`` (within a fifth of its radius)."""
    if len(points) < 10:
        return None
    A = np.c_[2 * points, np.ones(len(points))]
    solution, *_ = np.linalg.lstsq(A, (points ** 2).sum(axis=1), rcond=None)  # |p|^2 = 2 c.p + r^2 - |c|^2
    centre = solution[:3]
    radius = np.sqrt(max(solution[3] + centre @ centre, 0.0))
    spread = np.abs(np.linalg.norm(points - centre, axis=1) - radius).max()
    return centre if 0 < radius < largest and spread < 0.2 * radius else None


def _eye_centre(mesh: Mesh, ball: np.ndarray, frame: _Frame, side: str) -> np.ndarray:
    """The centre of an eyeball: the sphere through its vertices where they make one, else behind the
    middle of the eye's corners by 0.38 of the eye's width (1.1 cm for a 3 cm eye: an eyeball's radius)."""
    fallback_local = frame.eyes[side] - np.array([0.0, 0.0, 0.38 * frame.eye_width])
    fallback = fallback_local @ frame.axes + frame.origin
    centre = _sphere(mesh.vertices[ball], 0.6 * frame.eye_width)
    return fallback if centre is None else centre
