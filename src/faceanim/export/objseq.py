"""An animation as a numbered sequence of OBJ files (the form Blender's and Maya's sequence importers,
MeshLab and most research code read), sharing one material and texture."""

from __future__ import annotations

from pathlib import Path

from ..atomic import atomic_folder
from ..errors import InputError
from ..geometry.animation import Animation
from ..geometry.obj import obj_text, write_material

__all__ = ["write_obj_sequence", "check_sequence_folder"]


def write_obj_sequence(folder, animation: Animation, *, stem: str = "frame") -> list[Path]:
    """Write ``<stem>_00000.obj`` ... into ``folder`` (created; it must not exist or be empty), with
    ``face.mtl`` and ``face.png`` when the mesh is textured. Returns the OBJ paths.

    The folder appears complete or not at all (:func:`~faceanim.atomic.atomic_folder`): the frames are
    written into a hidden folder beside it, which is renamed into place at the end (at the end of the
    job, inside an :func:`~faceanim.atomic.output_group`).
    """
    folder = check_sequence_folder(folder)
    mesh = animation.mesh
    textured = mesh.texture is not None and mesh.uv is not None
    digits = max(5, len(str(len(animation) - 1)))
    names = [f"{stem}_{t:0{digits}d}.obj" for t in range(len(animation))]
    with atomic_folder(folder) as work:
        if textured:
            write_material(work, "face", mesh.texture)
        for name, positions in zip(names, animation.frames(), strict=True):
            (work / name).write_text(obj_text(mesh.with_vertices(positions), material="face" if textured else None))
    return [folder / name for name in names]


def check_sequence_folder(folder) -> Path:
    """``folder`` as a Path, if an OBJ sequence can be written there (new or empty, in an existing folder)."""
    folder = Path(folder)
    if folder.exists() and (not folder.is_dir() or any(folder.iterdir())):
        raise InputError(f"{folder}: exists and is not an empty folder; the OBJ sequence needs a new one")
    if not folder.parent.exists():
        raise InputError(f"{folder}: the folder {folder.parent} does not exist")
    return folder
