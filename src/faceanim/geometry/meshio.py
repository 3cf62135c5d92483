"""Read and write meshes by file extension: OBJ by hand (see :mod:`.obj`), PLY and glTF/GLB through
trimesh.

PLY keeps one UV per vertex, so a mesh with UV seams is written to PLY without UVs (its vertex order
is kept). A GLB written here stores each vertex's original index in the custom attribute ``_SOURCE_VERTEX``,
so reading it back restores the exact vertex order and welds the copies made at UV seams. A glTF
from elsewhere is read as it is laid out (one vertex per distinct position and UV).

A ``.glb`` written by :func:`faceanim.export.write_glb` is in metres, as glTF says, and records the
model's own unit in its mesh's ``extras["faceanim"]["metres_per_unit"]``; reading divides it out, so
the mesh comes back in the units it was written from (to float32 precision), not in metres. Its part
labels (``extras["faceanim"]["parts"]``: ``part_names`` and ``part_runs``, run-length encoded
``[label, count]`` pairs in triangle order) come back as :attr:`Mesh.parts` and :attr:`Mesh.part_names`.
Other ``.glb`` files are read in metres, without parts.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from ..atomic import atomic_output
from ..errors import FileFormatError, InputError
from .mesh import Mesh
from .obj import read_obj, write_obj

__all__ = ["read_mesh", "write_mesh", "read_glb_json", "glb_extras", "MESH_SUFFIXES", "SOURCE_VERTEX_ATTRIBUTE",
           "UNIT_EXTRA", "PARTS_EXTRA"]

SOURCE_VERTEX_ATTRIBUTE = "_SOURCE_VERTEX"
UNIT_EXTRA = "metres_per_unit"  # the keys of a faceanim .glb's extras["faceanim"] that read_mesh uses
PARTS_EXTRA = "parts"


def _suffix(path: Path) -> str:
    suffixes = [s.lower() for s in path.suffixes]
    if len(suffixes) >= 2 and suffixes[-1] == ".gz":
        return "".join(suffixes[-2:])
    return path.suffix.lower()


def _read_with_trimesh(path: Path) -> Mesh:
    import trimesh

    try:
        loaded = trimesh.load(path, process=False, maintain_order=True)
    except Exception as exc:  # trimesh raises many types for broken files
        raise FileFormatError(path, f"cannot be read as a mesh ({type(exc).__name__}: {exc})") from None
    if isinstance(loaded, trimesh.Scene):
        geometries = list(loaded.dump()) if loaded.geometry else []
        if not geometries:
            raise FileFormatError(path, "holds no triangle mesh")
        loaded = geometries[0] if len(geometries) == 1 else trimesh.util.concatenate(geometries)
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise FileFormatError(path, "holds no triangle mesh")
    vertices = np.asarray(loaded.vertices, dtype=np.float64)
    triangles = np.asarray(loaded.faces, dtype=np.int64)
    uv = texture = None
    visual = loaded.visual
    has_uv = getattr(visual, "kind", None) == "texture" and getattr(visual, "uv", None) is not None
    if has_uv and len(visual.uv) == len(vertices):
        uv = np.asarray(visual.uv, dtype=np.float64)
        image = getattr(getattr(visual, "material", None), "baseColorTexture", None) or getattr(
            getattr(visual, "material", None), "image", None)
        if image is not None:
            texture = np.asarray(image.convert("RGB"))
    source = loaded.vertex_attributes.get(SOURCE_VERTEX_ATTRIBUTE) if hasattr(loaded, "vertex_attributes") else None
    if source is not None and len(source) == len(vertices):
        return _weld(path, vertices, triangles, uv, texture, np.asarray(source).ravel())
    return Mesh(vertices, triangles, uv=uv, texture=texture)


def _weld(path, vertices, triangles, uv, texture, source) -> Mesh:
    """Undo :meth:`Mesh.split_at_seams` using the stored original index of each vertex."""
    source = np.rint(source).astype(np.int64)
    count = int(source.max()) + 1
    if source.min() < 0 or len(np.unique(source)) != count:
        raise FileFormatError(path, f"attribute {SOURCE_VERTEX_ATTRIBUTE} is not a valid vertex map")
    welded = np.zeros((count, 3))
    welded[source] = vertices
    return Mesh(welded, source[triangles], uv=uv, uv_triangles=triangles if uv is not None else None,
                texture=texture)


def _read_glb(path: Path) -> Mesh:
    """A ``.glb`` through trimesh; for one written by faceanim, in the model's own units and with its parts."""
    mesh = _read_with_trimesh(path)
    extras = glb_extras(path)
    changes = {}
    if UNIT_EXTRA in extras:
        unit = extras[UNIT_EXTRA]
        if isinstance(unit, bool) or not isinstance(unit, (int, float)) or not np.isfinite(unit) or unit <= 0:
            raise FileFormatError(path, f"extras faceanim.{UNIT_EXTRA} must be a positive number, got {unit!r}")
        changes["vertices"] = mesh.vertices / unit
    if PARTS_EXTRA in extras:
        changes["parts"], changes["part_names"] = _parts_of_runs(path, extras[PARTS_EXTRA], len(mesh.triangles))
    return replace(mesh, **changes) if changes else mesh


def _parts_of_runs(path: Path, stored, count: int) -> tuple[np.ndarray, tuple[str, ...]]:
    """Per-triangle labels ``(F,)`` and part names from ``{"part_names": [...], "part_runs": [[label, n], ...]}``."""
    try:
        names = tuple(str(n) for n in stored["part_names"])
        runs = np.asarray(stored["part_runs"], dtype=np.int64).reshape(-1, 2)
    except (KeyError, TypeError, ValueError):
        raise FileFormatError(path, f"extras faceanim.{PARTS_EXTRA} must hold part_names and part_runs "
                                    "([label, count] pairs)") from None
    labels, lengths = runs[:, 0], runs[:, 1]
    if (lengths < 1).any() or lengths.sum() != count or (labels < 0).any() or (labels >= len(names)).any():
        raise FileFormatError(path, f"extras faceanim.{PARTS_EXTRA} does not label its {count} triangles with its "
                                    f"{len(names)} part names")
    return np.repeat(labels, lengths), names


def _write_with_trimesh(path: Path, mesh: Mesh, file_type: str) -> None:
    import trimesh

    split = mesh.split_at_seams()
    if file_type == "ply" and len(split.vertices) != len(mesh.vertices):
        # PLY holds one UV per vertex; rather than reorder vertices at seams, keep the order and drop UVs.
        split = type(mesh)(mesh.vertices, mesh.triangles).split_at_seams()
    visual = None
    if split.uv is not None:
        from PIL import Image

        image = Image.fromarray(mesh.texture) if mesh.texture is not None else None
        material = trimesh.visual.material.PBRMaterial(baseColorTexture=image, baseColorFactor=[255, 255, 255, 255])
        visual = trimesh.visual.TextureVisuals(uv=split.uv, material=material)
    tm = trimesh.Trimesh(split.vertices, split.triangles, visual=visual, process=False)
    if file_type == "glb":
        tm.vertex_attributes[SOURCE_VERTEX_ATTRIBUTE] = split.source_vertex.astype(np.float32)
    data = tm.export(file_type=file_type)
    with atomic_output(path) as tmp:
        tmp.write_bytes(data if isinstance(data, bytes) else data.encode())


_READERS = {
    ".obj": read_obj,
    ".obj.gz": read_obj,
    ".ply": _read_with_trimesh,
    ".glb": _read_glb,
    ".gltf": _read_with_trimesh,
}
_WRITERS = {
    ".obj": write_obj,
    ".ply": lambda path, mesh: _write_with_trimesh(path, mesh, "ply"),
    ".glb": lambda path, mesh: _write_with_trimesh(path, mesh, "glb"),
}
MESH_SUFFIXES = tuple(sorted(_READERS))


def read_mesh(path) -> Mesh:
    """Read a mesh file (.obj, .obj.gz, .ply, .glb, .gltf), chosen by its extension.

    Raises
    ------
    InputError
        The file is missing, or its extension is not a mesh format.
    FileFormatError
        The file does not follow its format (message names the file, and the line for OBJ).
    """
    path = Path(path)
    reader = _READERS.get(_suffix(path))
    if reader is None:
        raise InputError(f"{path}: unknown mesh format {_suffix(path)!r}; use one of {', '.join(MESH_SUFFIXES)}")
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    if path.stat().st_size == 0:
        raise FileFormatError(path, "is empty")
    try:
        return reader(path)
    except FileFormatError:
        raise
    except ValueError as exc:  # the Mesh itself refused the data (non-finite vertices, bad indices)
        raise FileFormatError(path, str(exc)) from None


def write_mesh(path, mesh: Mesh, *, force: bool = False) -> None:
    """Write ``mesh`` to .obj, .ply or .glb, chosen by the extension; complete or not at all.

    A textured ``.obj`` brings its material and image beside it (``me.mtl``, ``me_texture.png``); a
    file of either name that faceanim did not write is refused unless ``force`` (see :func:`write_obj`)."""
    path = Path(path)
    writer = _WRITERS.get(_suffix(path))
    if writer is None:
        choices = ", ".join(sorted(_WRITERS))
        raise InputError(f"{path}: cannot write mesh format {_suffix(path)!r}; use one of {choices}")
    if writer is write_obj:
        write_obj(path, mesh, force=force)
    else:
        writer(path, mesh)


def read_glb_json(path) -> dict:
    """The JSON chunk of a ``.glb`` file (its scene description, without the binary buffer).

    Raises
    ------
    InputError
        The file cannot be read.
    FileFormatError
        No glTF header, a JSON chunk cut short, not JSON (or nested too deeply), or not a JSON object.
    """
    import json

    path = Path(path)
    try:
        with open(path, "rb") as handle:
            header = handle.read(20)
            if len(header) < 20 or header[:4] != b"glTF" or header[16:20] != b"JSON":
                raise FileFormatError(path, "is not a binary glTF (.glb) file")
            length = int.from_bytes(header[12:16], "little")
            chunk = handle.read(length)
    except OSError as exc:
        raise InputError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    if len(chunk) < length:
        raise FileFormatError(path, f"is cut short (its JSON chunk declares {length} bytes; {len(chunk)} follow)")
    try:
        document = json.loads(chunk)
    except (ValueError, RecursionError) as exc:  # JSONDecodeError, UnicodeDecodeError, a 5,000-digit number
        raise FileFormatError(path, f"has a broken JSON chunk ({str(exc).split(';')[0]})") from None
    if not isinstance(document, dict):
        raise FileFormatError(path, f"its JSON chunk is not an object (it is a {type(document).__name__})")
    return document


def glb_extras(path) -> dict:
    """What faceanim stored in a ``.glb`` (the first mesh's ``extras["faceanim"]``); ``{}`` for other
    files and formats, and where the document has no such object."""
    path = Path(path)
    if _suffix(path) != ".glb":
        return {}
    meshes = read_glb_json(path).get("meshes")
    first = meshes[0] if isinstance(meshes, list) and meshes else None
    extras = first.get("extras") if isinstance(first, dict) else None
    found = extras.get("faceanim") if isinstance(extras, dict) else None
    return found if isinstance(found, dict) else {}
