"""Wavefront OBJ (+MTL and texture), read and written by hand so that vertex order is kept exactly
and every error names its file and line.

Faces with four or more corners are split into a fan of triangles. Vertex normals in the file are
ignored (they are recomputed from the geometry). Materials become part labels; the diffuse texture
(``map_Kd``) of the material that covers most triangles becomes the mesh's texture.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..atomic import atomic_output
from ..errors import FileFormatError
from .mesh import Mesh

__all__ = ["read_obj", "write_obj", "obj_text", "write_material"]


def _resolve(index_text: str, count: int, path, lineno: int, what: str) -> int:
    try:
        index = int(index_text)
    except ValueError:
        raise FileFormatError(path, f"{what} index {index_text!r} is not an integer", lineno) from None
    resolved = index - 1 if index > 0 else count + index
    if index == 0 or not 0 <= resolved < count:
        raise FileFormatError(path, f"{what} index {index} is out of range (the file has {count} so far)", lineno)
    return resolved


def read_obj(path, *, load_texture: bool = True) -> Mesh:
    """Read an OBJ file into a :class:`Mesh`, keeping the order of its ``v`` lines.

    Parameters
    ----------
    path : str or Path
        The ``.obj`` file (plain text; ``.obj.gz`` is also accepted).
    load_texture : bool
        Read the ``map_Kd`` image named by the file's MTL, if any.

    Raises
    ------
    FileFormatError
        On a non-numeric token, an index out of range, a face with fewer than three corners, or a
        file with no vertices or no faces; the message names the file and line.
    """
    path = Path(path)
    opener = _open_gz if path.suffix == ".gz" else open
    positions, uvs, tris, uv_tris, parts = [], [], [], [], []
    part_names: list[str] = []
    part_index = {}
    current_part = None
    mtllibs: list[str] = []
    missing_uv = False
    try:
        with opener(path) as handle:
            for lineno, raw in enumerate(handle, 1):
                line = raw.split("#", 1)[0].strip()
                if not line:
                    continue
                head, _, rest = line.partition(" ")
                if head == "v":
                    fields = rest.split()
                    try:
                        positions.append([float(x) for x in fields[:3]])
                    except ValueError:
                        raise FileFormatError(path, f"vertex has a non-numeric token in {rest!r}", lineno) from None
                    if len(fields) < 3:
                        raise FileFormatError(path, f"vertex needs 3 coordinates, got {len(fields)}", lineno)
                elif head == "vt":
                    fields = rest.split()
                    try:
                        uvs.append([float(x) for x in fields[:2]] + [0.0] * (2 - len(fields[:2])))
                    except ValueError:
                        message = f"texture coordinate has a non-numeric token in {rest!r}"
                        raise FileFormatError(path, message, lineno) from None
                elif head == "f":
                    corners = rest.split()
                    if len(corners) < 3:
                        raise FileFormatError(path, f"face needs at least 3 corners, got {len(corners)}", lineno)
                    vids, tids = [], []
                    for corner in corners:
                        refs = corner.split("/")
                        vids.append(_resolve(refs[0], len(positions), path, lineno, "vertex"))
                        if len(refs) > 1 and refs[1]:
                            tids.append(_resolve(refs[1], len(uvs), path, lineno, "texture coordinate"))
                    if tids and len(tids) != len(vids):
                        raise FileFormatError(path, "face gives texture coordinates for some corners only", lineno)
                    missing_uv |= not tids
                    for k in range(1, len(vids) - 1):
                        tris.append((vids[0], vids[k], vids[k + 1]))
                        uv_tris.append((tids[0], tids[k], tids[k + 1]) if tids else (-1, -1, -1))
                        parts.append(current_part)
                elif head == "usemtl":
                    name = rest.strip()
                    if name not in part_index:
                        part_index[name] = len(part_names)
                        part_names.append(name)
                    current_part = part_index[name]
                elif head == "mtllib":
                    mtllibs.append(rest.strip())
    except UnicodeDecodeError:
        raise FileFormatError(path, "is not a text OBJ file") from None
    if not positions:
        raise FileFormatError(path, "has no vertices")
    if not tris:
        raise FileFormatError(path, "has no faces")

    uv = uv_triangles = None
    if uvs and not all(t[0] < 0 for t in uv_tris):
        uv = np.asarray(uvs, dtype=np.float64)
        uv_triangles = np.asarray(uv_tris, dtype=np.int64)
        if missing_uv:  # corners without UVs point at one extra (0, 0) entry
            uv = np.vstack([uv, [0.0, 0.0]])
            uv_triangles[uv_triangles < 0] = len(uv) - 1
    labels = None
    if part_names:
        unnamed = [i for i, p in enumerate(parts) if p is None]
        if unnamed:
            part_names.append("default")
        labels = np.asarray([len(part_names) - 1 if p is None else p for p in parts], dtype=np.int64)

    texture = None
    if load_texture and uv is not None and mtllibs:
        texture = _read_texture(path, mtllibs, part_names, labels)
    return Mesh(np.asarray(positions), np.asarray(tris, dtype=np.int64), uv=uv, uv_triangles=uv_triangles,
                texture=texture, parts=labels, part_names=tuple(part_names))


def _open_gz(path):
    import gzip

    return gzip.open(path, "rt")


def _read_texture(obj_path: Path, mtllibs, part_names, labels):
    """The map_Kd image of the material covering most triangles, or None."""
    maps = {}
    for lib in mtllibs:
        mtl = obj_path.parent / lib
        if not mtl.exists():
            continue
        material = None
        for raw in mtl.read_text(errors="replace").splitlines():
            fields = raw.split("#", 1)[0].split()
            if len(fields) >= 2 and fields[0] == "newmtl":
                material = fields[1]
            elif len(fields) >= 2 and fields[0] == "map_Kd" and material is not None:
                maps[material] = obj_path.parent / fields[-1]
    if not maps:
        return None
    counts = np.bincount(labels, minlength=len(part_names)) if labels is not None else []
    ranked = sorted(maps, key=lambda m: -counts[part_names.index(m)] if m in part_names else 0)
    image_path = maps[ranked[0]]
    if not image_path.exists():
        return None
    from PIL import Image

    with Image.open(image_path) as image:
        return np.asarray(image.convert("RGB"))


def obj_text(mesh: Mesh, *, material: str | None = None) -> str:
    """``mesh`` as OBJ text; with ``material``, the file names ``<material>.mtl`` and uses its texture."""
    lines = [f"# written by faceanim: {len(mesh.vertices)} vertices, {len(mesh.triangles)} triangles"]
    if material is not None:
        lines.append(f"mtllib {material}.mtl")
    lines.append("\n".join(f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in mesh.vertices))
    if mesh.uv is not None:
        lines.append("\n".join(f"vt {u:.9g} {v:.9g}" for u, v in mesh.uv))
    if material is not None:
        lines.append("usemtl faceanim_texture")
    tri = mesh.triangles + 1
    if mesh.uv is not None:
        uvt = mesh.uv_triangles + 1
        lines.append("\n".join(f"f {a}/{d} {b}/{e} {c}/{f}" for (a, b, c), (d, e, f) in zip(tri, uvt, strict=True)))
    else:
        lines.append("\n".join(f"f {a} {b} {c}" for a, b, c in tri))
    return "\n".join(lines) + "\n"


def write_material(folder, name: str, texture: np.ndarray, *, image: str | None = None) -> None:
    """``<name>.mtl`` and its texture ``image`` (default ``<name>.png``) in ``folder``, for OBJ files that
    say ``mtllib <name>.mtl``. Both carry faceanim's mark (:func:`faceanim.outputs.is_ours`)."""
    from PIL import Image, PngImagePlugin

    from ..outputs import MARK, MTL_HEADER

    folder = Path(folder)
    image = image or f"{name}.png"
    text = PngImagePlugin.PngInfo()
    text.add_text("Software", MARK)
    with atomic_output(folder / image) as tmp:
        Image.fromarray(texture).save(tmp, format="PNG", pnginfo=text)
    with atomic_output(folder / f"{name}.mtl") as tmp:
        tmp.write_text(f"{MTL_HEADER}\nnewmtl faceanim_texture\nKd 1 1 1\nmap_Kd {image}\n")


def write_obj(path, mesh: Mesh, *, force: bool = False) -> None:
    """Write ``mesh`` as OBJ; with a texture, also its material and image beside it, named after it
    (``me.obj``: ``me.mtl`` and ``me_texture.png``, see :func:`faceanim.outputs.side_files`).

    The files are written completely or not at all. A material or image of those names that faceanim
    did not write is not replaced (an :class:`~faceanim.errors.InputError` names it) unless ``force``.
    """
    from ..outputs import check_side_files, side_files

    path = Path(path)
    textured = mesh.texture is not None and mesh.uv is not None
    text = obj_text(mesh, material=path.stem if textured else None)
    if textured:
        check_side_files(path, force=force)
        write_material(path.parent, path.stem, mesh.texture, image=side_files(path)[1].name)
    with atomic_output(path) as tmp:
        tmp.write_text(text)
