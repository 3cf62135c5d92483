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
    the lining of an opening as a separate piece (a mouth socket, or an eye cap that is no ball):
    it hangs from its rim, which rides on the lips or the lids.
``static``
    anything else that holds no control point (hair, a hat): keeps still with the skull.

Parts are known from the labels a file carries (OBJ materials or groups, the part names a faceanim
``.glb`` keeps), from a ``--parts PARTS.json`` file, or found from the geometry: connected
components, and where each sits against the eyes, the lip line and the chin. All positions are
measured in the face's own frame and in FAPU-relative terms, so nothing depends on the mesh's unit.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph
from scipy.sparse.linalg import spsolve

from .errors import FileFormatError, InputError
from .geometry.mesh import Mesh
from .geometry.surface import cotangent_laplacian
from .geometry.topology import component_labels, submesh
from .mpeg4.jaw import jaw_hinge
from .target import Target

__all__ = ["ROLES", "FaceParts", "face_parts", "read_parts_file", "face_axes", "INNER_LIP_POINTS"]

ROLES = ("skin", "upper_teeth", "lower_teeth", "eye_left", "eye_right", "lid_layer", "socket", "static")
_ROLE = {name: k for k, name in enumerate(ROLES)}

# Words in part names (OBJ materials, groups) and the role they imply; the first match wins, so the
# lid layers' names ("EyeLashes", "EyeOcclusion") are tried before the eyeballs' ("Eye...").
_NAME_WORDS = (
    (("lash", "occlusion", "lacrimal", "tear", "blend", "lid", "brow"), "lid_layer"),
    (("teeth", "tooth", "gum", "tongue", "palate"), "teeth"),
    (("sclera", "iris", "cornea", "pupil", "eyeball", "eye"), "eye"),
    (("mouth", "socket", "oral"), "socket"),
)
# Points on the eyeballs, not the skin (placement puts the irises on the eyeball where there is one).
_EYEBALL_POINTS = frozenset({"3.5", "3.6", *(f"mp{i}" for i in range(468, 478))})
# The lips' control points: MPEG-4's and MediaPipe's (inner rims as automatic placement names them).
_UPPER_LIP = ("2.2", "2.6", "2.7", "8.1", "8.5", "8.6",
              *(f"mp{i}" for i in (191, 80, 81, 82, 13, 312, 311, 310, 415, 0, 37, 39, 40, 267, 269, 270)))
_LOWER_LIP = ("2.3", "2.8", "2.9", "8.2", "8.7", "8.8",
              *(f"mp{i}" for i in (95, 88, 178, 87, 14, 317, 402, 318, 324, 17, 84, 181, 314, 405)))
# Control points on the lips' inner rims, where lips meet teeth.
INNER_LIP_POINTS = ("2.2", "2.3", "2.4", "2.5", "2.6", "2.7", "2.8", "2.9",
                    *(f"mp{i}" for i in (13, 14, 78, 308, 82, 87, 312, 317, 80, 88, 310, 318)))
_FRAME_POINTS = ("3.7", "3.8", "3.11", "3.12", "8.3", "8.4", "2.1")


@dataclass(frozen=True, eq=False)
class FaceParts:
    """What each vertex of a target is and how it follows the jaw.

    Attributes
    ----------
    role : (V,) int64
        Index into :data:`ROLES` for every vertex.
    jaw_weight : (V,) float64
        How much of the jaw's turn a vertex follows, in [0, 1]: 1 on the chin and the lower teeth,
        0 on the upper lip, the skull and the upper teeth.
    hinge : (3,) float64
        A point on the jaw's axis (model units).
    axes : (3, 3) float64
        Rows: the face's +x (its left, also the jaw's axis), +y (up) and +z (out of the face).
    eye_centres : (2, 3) float64
        Left and right eyeball centres.
    """

    role: np.ndarray
    jaw_weight: np.ndarray
    hinge: np.ndarray
    axes: np.ndarray
    eye_centres: np.ndarray

    def __post_init__(self):
        for name in ("role", "jaw_weight", "hinge", "axes", "eye_centres"):
            array = np.array(getattr(self, name))
            array.flags.writeable = False
            object.__setattr__(self, name, array)

    def mask(self, *roles: str) -> np.ndarray:
        """``(V,) bool``: the vertices with any of ``roles``."""
        unknown = [r for r in roles if r not in _ROLE]
        if unknown:
            raise ValueError(f"unknown role {unknown[0]!r}; roles are {', '.join(ROLES)}")
        return np.isin(self.role, [_ROLE[r] for r in roles])

    def counts(self) -> dict:
        """Vertices per role (roles with none left out)."""
        found = np.bincount(self.role, minlength=len(ROLES))
        return {name: int(n) for name, n in zip(ROLES, found, strict=True) if n}


def face_axes(points: dict) -> np.ndarray:
    """Rows +x (the face's left), +y (up), +z (out of the face) from feature-point positions."""
    missing = [n for n in _FRAME_POINTS if n not in points]
    if missing:
        raise InputError(f"the target lacks feature point{'s' if len(missing) > 1 else ''} {', '.join(missing)}, "
                         "which place its parts")
    x = (points["3.7"] + points["3.11"]) - (points["3.8"] + points["3.12"])
    y = 0.25 * (points["3.7"] + points["3.8"] + points["3.11"] + points["3.12"]) - 0.5 * (points["8.3"] + points["8.4"])
    size = np.linalg.norm(y)
    x_length = np.linalg.norm(x)
    if not np.isfinite(size) or x_length <= 1e-6 * max(size, 1e-300):
        raise InputError("the target's eyes have no width (feature points 3.7/3.11 and 3.8/3.12 coincide); "
                         "its parts cannot be placed")
    x /= x_length
    y -= (y @ x) * x
    if np.linalg.norm(y) <= 1e-6 * x_length:
        raise InputError("the target's mouth (8.3/8.4) lies level with its eyes; its parts cannot be placed")
    y /= np.linalg.norm(y)
    return np.stack([x, y, np.cross(x, y)])


def read_parts_file(path) -> dict:
    """Read ``PARTS.json``: ``{"role": [part name or [first, last] vertex range, ...], ...}``.

    Roles are those of :data:`ROLES` plus ``"teeth"`` (upper or lower found from the bite) and
    ``"eye"`` (left or right found from the side); part names are the mesh's materials or groups.
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except OSError as exc:
        raise InputError(f"{path}: cannot be read ({exc.strerror})") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise FileFormatError(path, f"is not valid JSON ({exc})", getattr(exc, "lineno", None)) from None
    allowed = (*ROLES, "teeth", "eye")
    if not isinstance(data, dict) or not data:
        raise FileFormatError(path, 'must map roles to part names or vertex ranges, like {"teeth": ["M_Teeth"]}')
    for role, entries in data.items():
        if role not in allowed:
            raise FileFormatError(path, f"unknown role {role!r}; roles are {', '.join(allowed)}")
        if not isinstance(entries, list) or not all(_is_entry(e) for e in entries):
            raise FileFormatError(path, f"{role!r} must be a list of part names or [first, last] vertex ranges")
    return data


def _is_entry(entry) -> bool:
    if isinstance(entry, str):
        return True
    return (isinstance(entry, list) and len(entry) == 2 and all(isinstance(i, int) and not isinstance(i, bool)
                                                                   and 0 <= i < 2**53 for i in entry))


def face_parts(target: Target, *, labels: dict | None = None, source: str = "") -> FaceParts:
    """The parts of ``target``: from ``labels`` (see :func:`read_parts_file`), else the part names the
    mesh carries, else its geometry.

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
        depth = frame.local(mesh.vertices[split])[:, 2] - frame.hinge_local[2]
        jaw[split] *= _smoothstep(depth / (0.2 * frame.mouth_width))
    skin = role == _ROLE["skin"]
    jaw[skin] = _skin_jaw_weight(mesh, skin, frame, target)
    socket = role == _ROLE["socket"]
    jaw[socket] = frame.below_bite(mesh.vertices[socket])
    return FaceParts(role, np.clip(jaw, 0.0, 1.0), frame.hinge, axes, eye_centres)


def _smoothstep(s) -> np.ndarray:
    """0 below 0, 1 above 1, and the cubic with level ends between."""
    s = np.clip(s, 0.0, 1.0)
    return s * s * (3 - 2 * s)


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


class _Frame:
    """Face-frame coordinates and the levels parts are told apart by (FAPU-relative)."""

    def __init__(self, axes: np.ndarray, at: dict, target: Target):
        self.axes = axes
        self.hinge = _turning_centre(at, target, axes)
        self.origin = at["2.1"]
        self.local_points = {n: self.local(p[None])[0] for n, p in at.items()}
        p = self.local_points
        self.chin = p["2.1"]
        self.mouth = 0.5 * (p["8.3"] + p["8.4"])
        self.mouth_width = float(np.linalg.norm(p["8.3"] - p["8.4"]))
        self.eye_width = 0.5 * float(np.linalg.norm(p["3.7"] - p["3.11"]) + np.linalg.norm(p["3.8"] - p["3.12"]))
        self.hinge_local = self.local(self.hinge[None])[0]
        # Where upper and lower teeth meet, y = bite[0] + bite[1] * z: the lip line until the teeth say
        # otherwise (the bite rises towards the back of the mouth).
        self.bite = (float(self.mouth[1]), 0.0)
        self.eyes = {"eye_left": 0.5 * (p["3.7"] + p["3.11"]), "eye_right": 0.5 * (p["3.8"] + p["3.12"])}

    def move_centre(self, local: np.ndarray) -> None:
        """Put the jaw's turning centre at ``local`` (face frame)."""
        self.hinge_local = np.asarray(local, dtype=np.float64)
        self.hinge = self.hinge_local @ self.axes + self.origin

    def local(self, points: np.ndarray) -> np.ndarray:
        return (np.asarray(points) - self.origin) @ self.axes.T

    def below_bite(self, points: np.ndarray) -> np.ndarray:
        """1 below the bite, 0 above, a smooth step of a tenth of the mouth's width between."""
        local = self.local(points)
        y = local[:, 1] - self.bite[1] * local[:, 2]
        band = 0.1 * self.mouth_width
        return _smoothstep((self.bite[0] + 0.5 * band - y) / band)

    def in_mouth(self, centre: np.ndarray) -> bool:
        """Whether a point (face frame) lies behind the lips, between the chin and the nose."""
        top = self.local_points["9.15"][1] if "9.15" in self.local_points else self.mouth[1] + 0.4 * self.mouth_width
        return (abs(centre[0] - self.mouth[0]) < 0.8 * self.mouth_width and self.chin[1] - 0.1 * self.mouth_width
                < centre[1] < top and centre[2] < self.mouth[2] + 0.1 * self.mouth_width)


def _turning_centre(at: dict, target: Target, axes: np.ndarray) -> np.ndarray:
    """Where the jaw turns about as it opens: not the condyles (the MPEG-4 hinge of
    :func:`~faceanim.mpeg4.jaw.jaw_hinge`, level with the nose's base) but below them, level with the
    jaw's corners (2.13/2.14; halfway to the chin without them). The condyles slide forward as the jaw
    opens, so the opening turns about a centre low on the ramus; about the condyles, the jaw's lower
    border would swing back by centimetres where it hardly moves. Where the lower teeth are known,
    :func:`_centre_behind_the_teeth` moves it behind them."""
    hinge = jaw_hinge(at, target.fapu)
    corners = [at[n] for n in ("2.13", "2.14") if n in at]
    low = np.mean(corners, axis=0) @ axes[1] if corners else (hinge @ axes[1] + at["2.1"] @ axes[1]) / 2
    return hinge + (low - hinge @ axes[1]) * axes[1]


def _vertex_hints(mesh: Mesh, labels: dict | None, where: str) -> np.ndarray:
    """``(V,)`` object array: the role each vertex's labels imply ("" where none), skin winning on a rim.

    Part names (the file's materials or groups) label whole parts; ``labels`` (a parts file) name parts
    or vertex ranges, and a range wins over a name, being the more particular."""
    V = len(mesh.vertices)
    hint = np.full(V, "", dtype=object)
    names = mesh.part_names if mesh.parts is not None else ()
    ranges = []
    if labels is not None:
        by_name = {}
        for role, entries in labels.items():
            for entry in entries:
                if isinstance(entry, str):
                    if entry not in names:
                        known = ", ".join(names) or "none"
                        raise InputError(f"{where}the parts file names part {entry!r}, which the mesh lacks "
                                         f"(its parts: {known})")
                    by_name[entry] = role
                    continue
                first, last = entry
                if first > last:
                    raise InputError(f"{where}the parts file's range [{first}, {last}] runs backwards; "
                                     "give it as [first, last]")
                if last >= V:
                    raise InputError(f"{where}the parts file's range [{first}, {last}] is outside the mesh's "
                                     f"vertices 0-{V - 1}")
                ranges.append((first, last, role))
        per_part = [by_name.get(n, "") for n in names]
    else:
        per_part = [_role_of_name(n) for n in names]
    if names and any(per_part):
        tri_hint = np.array(per_part, dtype=object)[mesh.parts]
        labelled = (tri_hint != "") & (tri_hint != "skin")
        for corner in range(3):
            hint[mesh.triangles[labelled, corner]] = tri_hint[labelled]
        hint[np.unique(mesh.triangles[~labelled])] = ""  # a rim shared with the skin (an eye cap stitched to the lids)
    for first, last, role in ranges:
        hint[first:last + 1] = role
    return hint


def _role_of_name(name: str) -> str:
    lower = name.lower()
    for words, role in _NAME_WORDS:
        if any(w in lower for w in words):
            return role
    return ""


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


def _centre_behind_the_teeth(mesh: Mesh, lower: np.ndarray, frame: _Frame):
    """Where the lower teeth are known, the jaw's turning centre behind the last of them, level with
    the bite there (face frame), or None to keep it: the ramus rises behind the molars, and a centre
    in front of them would lift the back molars as the jaw opens. Feature points placed on a
    silhouette (the jaw's corners) say little about depth."""
    if not lower.any():
        return None
    local = frame.local(mesh.vertices[lower])
    back = local[:, 2].min() - 0.25 * frame.mouth_width
    if back >= frame.hinge_local[2]:
        return None
    return np.array([frame.hinge_local[0], frame.bite[0] + frame.bite[1] * local[:, 2].min(), back])


def _teeth_pieces(mesh: Mesh, kind: np.ndarray, frame: _Frame):
    """The whole pieces of teeth found by place or name (vertex ids each) and their centres (face frame)."""
    part = component_labels(mesh)
    mouth = np.flatnonzero(kind == "rigid")
    pieces = [mouth[part[mouth] == k] for k in np.unique(part[mouth])]
    centres = np.array([frame.local(mesh.vertices[p].mean(axis=0)[None])[0] for p in pieces]).reshape(-1, 3)
    return pieces, centres


def _fitted_bite(centres: np.ndarray, frame: _Frame):
    """The bite line through the teeth pieces' centres, or None where they are one set (all at one height)."""
    if len(centres) >= 2 and np.ptp(centres[:, 1]) > 0.1 * frame.mouth_width:
        return _bite_line(centres[:, 2], centres[:, 1])
    return None


def _split_teeth(mesh: Mesh, role: np.ndarray, kind: np.ndarray, jaw: np.ndarray, frame: _Frame, pieces,
                 centres, *, fitted: bool) -> None:
    """Teeth, gums and tongue to the skull or the jaw (``role``, ``jaw`` filled in): whole pieces by
    their centres against ``frame.bite`` (``fitted`` through them), pieces that straddle the bite
    vertex by vertex, a set of teeth alone by whether it reaches above the lips' meeting."""
    given = np.flatnonzero(kind == "given")
    jaw[given] = role[given] == _ROLE["lower_teeth"]
    band = 0.1 * frame.mouth_width
    for piece, centre in zip(pieces, centres, strict=True):
        local = frame.local(mesh.vertices[piece])
        above = local[:, 1] - frame.bite[1] * local[:, 2] - frame.bite[0]
        if min((above > band).mean(), (above < -band).mean()) > 0.25:
            weight = frame.below_bite(mesh.vertices[piece])  # gums and tongue in one piece
            kind[piece] = "split"
            jaw[piece] = weight
            role[piece] = np.where(weight >= 0.5, _ROLE["lower_teeth"], _ROLE["upper_teeth"])
            continue
        if fitted:
            lower = centre[1] < frame.bite[0] + frame.bite[1] * centre[2]
        else:  # one set of teeth alone: upper if it reaches above the lips' meeting (the skull holds it)
            lower = local[:, 1].max() < frame.bite[0]
        role[piece] = _ROLE["lower_teeth" if lower else "upper_teeth"]
        jaw[piece] = float(lower)


def _bite_line(z: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """The line ``y = a + b z`` between the upper and the lower pieces (centres ``(z, y)``): two
    groups by height (Otsu), then a line fitted through each and their mean taken as the boundary,
    regrouping until stable (a back molar of the lower arch sits higher than a front tooth of the
    upper one, so no single height splits them)."""
    order = np.sort(y)
    spread = [k * order[:k].var() + (len(order) - k) * order[k:].var() for k in range(1, len(order))]
    k = int(np.argmin(spread)) + 1
    a, b = 0.5 * (order[k - 1] + order[k]), 0.0
    for _ in range(10):
        upper = y > a + b * z
        if upper.sum() < 2 or (~upper).sum() < 2:
            break
        lines = [np.polyfit(z[group], y[group], 1) if np.ptp(z[group]) > 0 else (0.0, y[group].mean())
                 for group in (upper, ~upper)]
        a, b = 0.5 * (lines[0][1] + lines[1][1]), 0.5 * (lines[0][0] + lines[1][0])
        if np.array_equal(upper, y > a + b * z):
            break
    return float(a), float(b)


def _skin_jaw_weight(mesh: Mesh, skin: np.ndarray, frame: _Frame, target: Target) -> np.ndarray:
    """``(S,)`` the jaw's share of each skin vertex: harmonic along the skin between the chin (1) and
    the upper lip, the ears and the neck (0)."""
    ids = np.flatnonzero(skin)
    sub, index_of = submesh(mesh, skin)
    tris = sub.triangles
    local = frame.local(mesh.vertices[ids])
    x, y, z = local.T
    chin, mouth, hinge = frame.chin, frame.mouth, frame.hinge_local
    w = frame.mouth_width
    depth = chin[2] - hinge[2]
    # The jaw line runs from the chin back to below the hinge; the neck lies under it. The line the
    # jaw's skin ends at above runs from the lip line at the mouth back to the hinge.
    corners = [frame.local_points[n] for n in ("2.13", "2.14") if n in frame.local_points]
    gonion = np.mean(corners, axis=0) if corners else chin + 0.45 * (hinge - chin)
    slope = (gonion[1] - chin[1]) / max(chin[2] - gonion[2], 0.1 * w)
    under_jaw = chin[1] + slope * (chin[2] - z) - y
    back = np.clip((mouth[2] - z) / (mouth[2] - hinge[2]), 0.0, 1.0)
    above = y - (mouth[1] + (hinge[1] - mouth[1]) * back)
    # Beside the mouth the jaw's full share starts a band below that line; on the lower lip, at it.
    # In the middle the lips themselves are pinned (below); the jaw's full share starts under the lower lip.
    lip_bottom = frame.local_points["8.2"][1] if "8.2" in frame.local_points else mouth[1] - 0.1 * w
    band = np.maximum(0.3 * w * _smoothstep(np.abs(x - mouth[0]) / (0.5 * w)), mouth[1] - lip_bottom)
    fixed = np.full(len(ids), np.nan)
    fixed[(above < -band) & (under_jaw < 0.02 * w) & (z > hinge[2] + 0.25 * depth)] = 1.0
    fixed[above > 0.1 * w] = 0.0  # the upper lip and everything above
    fixed[z < hinge[2]] = 0.0  # the ears and the back of the head
    fixed[under_jaw > 0.8 * w] = 0.0  # the neck, well below the jaw line: the skin between stretches
    # The lips meet at the lip line, so height cannot tell them apart there; their control points can.
    for names, value in ((_UPPER_LIP, 0.0), (_LOWER_LIP, 1.0)):
        pinned = index_of[[target.points[n] for n in names if n in target.points]]
        fixed[pinned[pinned >= 0]] = value
    if not (fixed == 1).any():
        return np.zeros(len(ids))
    if not len(tris):
        return np.nan_to_num(fixed)
    L, _ = cotangent_laplacian(sub)
    # Vertices in no skin triangle, and skin islands with no fixed vertex, hold 0.
    used = np.zeros(len(ids), dtype=bool)
    used[np.unique(tris)] = True
    fixed[~used] = 0.0
    labels = component_labels(sub)
    for k in np.unique(labels):
        island = labels == k
        if np.isnan(fixed[island]).all():
            fixed[island] = 0.0
    free = np.isnan(fixed)
    out = np.nan_to_num(fixed)
    if free.any():
        L = sparse.csr_matrix(L)
        A = L[free][:, free]
        b = -L[free][:, ~free] @ out[~free]
        out[free] = spsolve(A.tocsc(), b)
    return np.clip(out, 0.0, 1.0)


def _eye_centre(mesh: Mesh, ball: np.ndarray, frame: _Frame, side: str) -> np.ndarray:
    """The centre of an eyeball: the sphere through its vertices where they make one, else behind the
    middle of the eye's corners by 0.38 of the eye's width (1.1 cm for a 3 cm eye: an eyeball's radius)."""
    fallback_local = frame.eyes[side] - np.array([0.0, 0.0, 0.38 * frame.eye_width])
    fallback = fallback_local @ frame.axes + frame.origin
    centre = _sphere(mesh.vertices[ball], 0.6 * frame.eye_width)
    return fallback if centre is None else centre
