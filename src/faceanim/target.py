"""`Target`: a mesh to animate, where its control points sit on it, and its FAPU.

Part of the shared vocabulary (like `Motion`), so it lives at the top of the package: retargeting
decodes onto a Target, the muscles of ``synth`` are placed by its feature points, placement makes one.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

import numpy as np

from .errors import FileFormatError, InputError
from .geometry.mesh import Mesh
from .jsonfile import read_json
from .mpeg4 import Fapu, fapu_from_points, feature_points
from .validation import restore_frozen

__all__ = ["Target", "target_from_json", "target_from_fdp"]


@dataclass(frozen=True, eq=False)
class Target:
    """A mesh with named control points (MPEG-4 feature points by number, ``"8.3"``) on its vertices.

    Immutable and checked on construction, however it is made.

    Parameters
    ----------
    mesh : Mesh
    points : mapping of str to int
        Control-point names to vertex ids of ``mesh``; kept as a read-only mapping
        (:class:`types.MappingProxyType`; ``dict(target.points)`` for a dict).
    fapu : Fapu or None
        The face's FAPU in the mesh's units (:meth:`from_points` measures it when not given, see
        :func:`measure_fapu`); None for a mesh without the face points to measure it from, which
        then cannot be decoded onto.

    Raises
    ------
    TypeError
        ``mesh`` is not a Mesh, ``fapu`` not a Fapu, a name not a string or an id not an integer.
    ValueError
        ``points`` names a vertex the mesh lacks.
    """

    mesh: Mesh
    points: Mapping[str, int]
    fapu: Fapu | None

    def __post_init__(self):
        if not isinstance(self.mesh, Mesh):
            raise TypeError(f"mesh must be a Mesh, got {type(self.mesh).__name__}")
        if self.fapu is not None and not isinstance(self.fapu, Fapu):
            raise TypeError(f"fapu must be a Fapu or None, got {type(self.fapu).__name__}")
        if not isinstance(self.points, Mapping):
            raise TypeError(f"points must map names to vertex ids, got {type(self.points).__name__}")
        V = len(self.mesh.vertices)
        points = {}
        for name, index in self.points.items():
            if not isinstance(name, str):
                raise TypeError(f"points must be named by strings, got {name!r}")
            if isinstance(index, bool) or not isinstance(index, (int, np.integer)):
                raise TypeError(f"points[{name!r}] must be an integer vertex id, got {index!r}")
            if not 0 <= index < V:
                raise ValueError(f"points[{name!r}] must lie in [0, {V}), got {index}")
            points[name] = int(index)
        object.__setattr__(self, "points", MappingProxyType(points))

    def __getstate__(self):
        return {**self.__dict__, "points": dict(self.points)}  # a mappingproxy does not pickle

    def __setstate__(self, state):
        restore_frozen(self, {**state, "points": MappingProxyType(dict(state["points"]))})

    @classmethod
    def from_points(cls, mesh: Mesh, points: dict, fapu: Fapu | None = None, *, source: str = "") -> Target:
        """Check ``points`` (name -> vertex id) against ``mesh`` and measure FAPU if not given."""
        where = f"{source}: " if source else ""
        V = len(mesh.vertices)
        bad = {n: i for n, i in points.items()
               if isinstance(i, bool) or not isinstance(i, (int, np.integer)) or not 0 <= int(i) < V}
        if bad:
            name, index = next(iter(bad.items()))
            raise InputError(f"{where}point {name} names vertex {index}, but the mesh has vertices 0-{V - 1}")
        points = {str(n): int(i) for n, i in points.items()}
        return cls(mesh, points, fapu or measure_fapu(mesh, points, source=source))

    def ids(self, names) -> np.ndarray:
        """``(N,) int64`` vertex ids of the named points; an unknown name raises ``KeyError``."""
        return np.array([self.points[n] for n in names], dtype=np.int64)

    @property
    def mouth_width(self) -> float:
        """The distance between the mouth's corners (8.3 to 8.4) in the mesh's units; 0.0 where the
        target lacks either. FAPU's MW0 is their distance across the face only."""
        if not {"8.3", "8.4"} <= self.points.keys():
            return 0.0
        corners = self.mesh.vertices[self.ids(["8.3", "8.4"])]
        return float(np.linalg.norm(corners[0] - corners[1]))


def measure_fapu(mesh: Mesh, points: dict, *, source: str = "") -> Fapu:
    """FAPU from the target's feature points; pupils (3.5, 3.6), when missing, are taken as the
    midpoints of the eye corners (3.7/3.11 and 3.8/3.12)."""
    p = {n: mesh.vertices[i] for n, i in points.items()}
    for pupil, corners in (("3.5", ("3.7", "3.11")), ("3.6", ("3.8", "3.12"))):
        if pupil not in p and all(c in p for c in corners):
            p[pupil] = 0.5 * (p[corners[0]] + p[corners[1]])
    try:
        return fapu_from_points(p)
    except (KeyError, ValueError) as exc:
        where = f"{source}: " if source else ""
        raise InputError(f"{where}cannot measure FAPU: {str(exc).strip(chr(39))}") from None


def target_from_json(mesh: Mesh, path) -> Target:
    """Control points from a JSON object ``{"8.3": vertex id, ...}`` (or ``{"points": {...}}``).

    Raises
    ------
    InputError
        The file cannot be read, a vertex id is outside ``mesh``, or FAPU cannot be measured.
    FileFormatError
        Not UTF-8 JSON, not such an object, an unknown point name, or an id that is not an integer.
    """
    path = Path(path)
    data = read_json(path)
    data = data.get("points", data) if isinstance(data, dict) else data
    if not isinstance(data, dict) or not data:
        raise FileFormatError(path, 'must map feature-point names to vertex ids, like {"8.3": 1520}')
    unknown = [n for n in data if n not in feature_points().names and not n.startswith("mp")]
    if unknown:
        raise FileFormatError(path, f"unknown feature point {unknown[0]!r} (MPEG-4 names look like '8.3')")
    for name, index in data.items():
        if isinstance(index, bool) or not isinstance(index, int):
            raise FileFormatError(path, f"point {name!r} must name a vertex by its integer id, got {_json(index)}")
    return Target.from_points(mesh, data, source=str(path))


def _json(value) -> str:
    """``value`` as it was written in JSON (``true``, ``2.0``), cut to 40 characters."""
    import json

    text = json.dumps(value)
    return text if len(text) <= 40 else text[:37] + "..."


def target_from_fdp(mesh: Mesh, path) -> Target:
    """Control points and FAPU from an XfaceEd ``.fdp`` XML file.

    Xface models are several submeshes, and an ``.fdp`` gives each point's vertex within the submesh
    it ``affects`` (the face, but also the teeth for 2.1, the eyes for the pupils). ``mesh`` is taken
    to be the submesh that holds most points; points on other submeshes are left out.
    """
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except OSError as exc:
        raise InputError(f"{path}: cannot be read ({exc.strerror})") from None
    except ET.ParseError as exc:
        raise FileFormatError(path, f"is not valid XML ({exc})", exc.position[0]) from None
    except (LookupError, ValueError) as exc:  # an encoding Python does not know, or expat cannot use
        raise FileFormatError(path, f"is not valid XML ({exc})") from None
    if root.tag != "xfdp":
        raise FileFormatError(path, f"is not an XfaceEd FDP file (root element <{root.tag}>, expected <xfdp>)")
    entries = list(root.iter("fdp"))
    submeshes = [fdp.get("affects") for fdp in entries]
    main = max(set(submeshes), key=lambda s: (submeshes.count(s), s or "")) if entries else None
    points = {}
    for fdp in entries:
        if fdp.get("affects") != main:
            continue
        name = fdp.get("name")
        if name is None:
            raise FileFormatError(path, "a feature point has no name (<fdp name=\"8.3\" ...>)")
        if name not in feature_points().names:
            raise FileFormatError(path, f"unknown feature point {name!r} (MPEG-4 names look like '8.3')")
        try:
            points[name] = int(fdp.get("index"))
        except (TypeError, ValueError):
            raise FileFormatError(path, f"feature point {name!r} has no integer index") from None
    if not points:
        raise FileFormatError(path, "names no feature points")
    fapu = None
    element = root.find("head/fapu")
    if element is not None:
        keys = ("IRISD0", "ES0", "ENS0", "MNS0", "MW0")
        try:
            fapu = Fapu(*(float(element.get(k)) for k in keys))
        except (TypeError, ValueError):  # a distance missing, not a number, or not positive and finite
            given = " ".join(f"{k}={element.get(k)!r}" for k in keys)
            raise FileFormatError(path, f"<fapu> must give {', '.join(keys[:-1])} and {keys[-1]} as positive "
                                        f"numbers, got {given}") from None
    return Target.from_points(mesh, points, fapu, source=str(path))
