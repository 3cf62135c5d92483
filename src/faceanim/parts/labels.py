"""Parts named in files: words in part names (OBJ materials, groups), and ``PARTS.json``."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import FileFormatError, InputError
from ..geometry.mesh import Mesh
from ..jsonfile import read_json
from .faceparts import ROLES

__all__ = ["read_parts_file"]

# Words in part names (OBJ materials, groups) and the role they imply; the first match wins, so the
# lid layers' names ("EyeLashes", "EyeOcclusion") are tried before the eyeballs' ("Eye...").
_NAME_WORDS = (
    (("lash", "occlusion", "lacrimal", "tear", "blend", "lid", "brow"), "lid_layer"),
    (("teeth", "tooth", "gum", "tongue", "palate"), "teeth"),
    (("sclera", "iris", "cornea", "pupil", "eyeball", "eye"), "eye"),
    (("mouth", "socket", "oral"), "socket"),
)


def read_parts_file(path) -> dict:
    """Read ``PARTS.json``: ``{"role": [part name or [first, last] vertex range, ...], ...}``.

    Roles are those of :data:`ROLES` plus ``"teeth"`` (upper or lower found from the bite) and
    ``"eye"`` (left or right found from the side); part names are the mesh's materials or groups.
    """
    path = Path(path)
    data = read_json(path)
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
