"""Wavefront OBJ (+MTL and texture), read and written by hand so that vertex order is kept exactly
and every error names its file and line.

Faces with four or more corners are split into a fan of triangles. Vertex normals in the file are
ignored (they are recomputed from the geometry). Materials become part labels; the diffuse texture
(``map_Kd``) of the material that covers most triangles becomes the mesh's texture.

Reading is strict about what it uses and tolerant of the rest: coordinates must be finite numbers,
indices must point at earlier lines; a ``.obj.gz`` must be a complete gzip file of UTF-8 text. A
material library or texture that does not exist is left out (the mesh comes back untextured), but one
that exists and cannot be read, is not an image, or is larger than :data:`MAX_TEXTURE_SIDE` pixels a
side or PIL's ``Image.MAX_IMAGE_PIXELS`` in all is refused, naming the MTL and the image.
"""

from __future__ import annotations

import math
import struct
import warnings
import zlib
from pathlib import Path

import numpy as np

from ..atomic import atomic_output
from ..errors import FileFormatError, InputError
from .mesh import Mesh

__all__ = ["read_obj", "write_obj", "obj_text", "write_material", "MAX_TEXTURE_SIDE"]

MAX_TEXTURE_SIDE = 16384  # pixels; a larger map_Kd image is refused


def _resolve(index_text: str, count: int, path, lineno: int, what: str) -> int:
    try:
        index = int(index_text)
    except ValueError:
        raise FileFormatError(path, f"{what} index {index_text!r} is not an integer", lineno) from None
    resolved = index - 1 if index > 0 else count + index
    if index == 0 or not 0 <= resolved < count:
        raise FileFormatError(path, f"{what} index {index} is out of range (the file has {count} so far)", lineno)
    return resolved


def _coordinates(fields: list[str], count: int, path, lineno: int, what: str) -> list[float]:
    """The first ``count`` of ``fields`` as finite floats (missing ones are the caller's to check)."""
    try:
        values = [float(x) for x in fields[:count]]
    except ValueError:
        raise FileFormatError(path, f"{what} has a non-numeric token in {' '.join(fields)!r}", lineno) from None
    if not all(math.isfinite(v) for v in values):
        raise FileFormatError(path, f"{what} has a non-finite coordinate in {' '.join(fields)!r}", lineno)
    return values


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
    InputError
        The file (or its MTL) exists but cannot be read.
    FileFormatError
        On a non-numeric or non-finite token, an index out of range, a face with fewer than three
        corners, a file with no vertices or no faces, text that is not UTF-8, a broken or cut-short
        gzip file; the message names the file and line. A texture that is not an image or is too
        large (see the module's notes): the message names the MTL and the image.
    """
    path = Path(path)
    gzipped = path.suffix.lower() == ".gz"  # as read_mesh dispatches: FACE.OBJ.GZ is gzip too
    positions, uvs, tris, uv_tris, parts = [], [], [], [], []
    part_names: list[str] = []
    part_index = {}
    current_part = None
    mtllibs: list[str] = []
    missing_uv = False
    try:
        with _open_gz(path) if gzipped else open(path, encoding="utf-8-sig") as handle:
            for lineno, raw in enumerate(handle, 1):
                line = raw.split("#", 1)[0].strip()
                if not line:
                    continue
                head, _, rest = line.replace("\t", " ").partition(" ")
                rest = rest.strip()
                if head == "v":
                    fields = rest.split()
                    positions.append(_coordinates(fields, 3, path, lineno, "vertex"))
                    if len(fields) < 3:
                        raise FileFormatError(path, f"vertex needs 3 coordinates, got {len(fields)}", lineno)
                elif head == "vt":
                    fields = rest.split()
                    uv = _coordinates(fields, 2, path, lineno, "texture coordinate")
                    uvs.append(uv + [0.0] * (2 - len(uv)))
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
                    name = rest
                    if name not in part_index:
                        part_index[name] = len(part_names)
                        part_names.append(name)
                    current_part = part_index[name]
                elif head == "mtllib" and rest:
                    mtllibs.append(rest)
    except UnicodeDecodeError:
        raise FileFormatError(path, "is not a text OBJ file (not UTF-8)") from None
    except EOFError:
        raise FileFormatError(path, "is not a complete gzip file (it ends early)") from None
    except (zlib.error, OSError) as exc:  # gzip.BadGzipFile is an OSError
        if gzipped and not isinstance(exc, FileNotFoundError | PermissionError | IsADirectoryError):
            raise FileFormatError(path, f"is not a readable gzip file ({exc})") from None
        raise InputError(f"{path}: cannot be read ({getattr(exc, 'strerror', None) or exc})") from None
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
    try:
        return Mesh(np.asarray(positions), np.asarray(tris, dtype=np.int64), uv=uv, uv_triangles=uv_triangles,
                    texture=texture, parts=labels, part_names=tuple(part_names))
    except ValueError as exc:  # the Mesh's own checks, should the reader's above miss one
        raise FileFormatError(path, str(exc)) from None


def _open_gz(path: Path):
    """``path`` as UTF-8 text through gzip; a file that does not start like gzip is refused at once."""
    import gzip

    with open(path, "rb") as handle:
        magic = handle.read(2)
    if magic != b"\x1f\x8b":
        raise FileFormatError(path, "is not a gzip file (it does not start with the gzip signature)")
    return gzip.open(path, "rt", encoding="utf-8-sig")


def _is_file(path: Path) -> bool:
    """Whether ``path`` is a regular file; False for names no file can have (too long, NUL bytes)."""
    try:
        return path.is_file()
    except OSError:
        return False


def _read_texture(obj_path: Path, mtllibs, part_names, labels):
    """The map_Kd image of the material covering most triangles, or None where the OBJ's MTL files
    or that image do not exist. A map_Kd path is taken relative to its MTL file."""
    maps = {}
    for lib in mtllibs:
        mtl = obj_path.parent / lib
        if not _is_file(mtl):
            continue
        try:
            text = mtl.read_text(encoding="utf-8", errors="replace")
        except OSError as exc:
            raise InputError(f"{mtl}: cannot be read ({exc.strerror or exc})") from None
        material = None
        for raw in text.splitlines():
            fields = raw.split("#", 1)[0].split()
            if len(fields) >= 2 and fields[0] == "newmtl":
                material = fields[1]
            elif len(fields) >= 2 and fields[0] == "map_Kd" and material is not None:
                maps[material] = (mtl, mtl.parent / fields[-1])
    if not maps:
        return None
    counts = np.bincount(labels, minlength=len(part_names)) if labels is not None else []
    ranked = sorted(maps, key=lambda m: -counts[part_names.index(m)] if m in part_names else 0)
    mtl, image_path = maps[ranked[0]]
    if not _is_file(image_path):
        return None
    return _read_image(mtl, image_path)


def _read_image(mtl: Path, image_path: Path) -> np.ndarray:
    """``(H, W, 3) uint8``: the texture ``image_path`` named by ``mtl``, refused (naming both) if it is
    not an image, cannot be decoded, or is larger than :data:`MAX_TEXTURE_SIDE` a side or PIL's
    ``Image.MAX_IMAGE_PIXELS`` in all."""
    from PIL import Image

    try:
        with warnings.catch_warnings():  # above MAX_IMAGE_PIXELS PIL warns; the size is refused below
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            image = Image.open(image_path)
    except Image.DecompressionBombError as exc:
        raise FileFormatError(mtl, f"texture {image_path} is too large ({str(exc).split(',')[0]})") from None
    except OSError as exc:  # PIL's UnidentifiedImageError is an OSError
        raise FileFormatError(mtl, f"texture {image_path} is not an image ({exc})") from None
    with image:
        width, height = image.size
        most = Image.MAX_IMAGE_PIXELS or math.inf
        if max(width, height) > MAX_TEXTURE_SIDE or width * height > most:
            raise FileFormatError(mtl, f"texture {image_path} is {width} x {height} pixels; textures may be at most "
                                       f"{MAX_TEXTURE_SIDE} pixels a side and {most:,} pixels in all")
        try:
            return np.asarray(image.convert("RGB"))
        except (OSError, SyntaxError, ValueError, EOFError, struct.error, zlib.error) as exc:
            # PIL reports broken image data in all of these ways, depending on the format
            message = f"texture {image_path} cannot be decoded ({type(exc).__name__}: {exc})"
            raise FileFormatError(mtl, message) from None


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
