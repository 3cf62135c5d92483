"""The jobs a person runs, composed from the rooms. Each reads its inputs, checks them against
each other, computes, and writes its output completely or not at all."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .errors import FileFormatError, InputError
from .geometry import read_mesh, write_mesh
from .retarget import REGIONS, ControlPairs, region_mask, transfer_expression

__all__ = ["transfer", "read_pairs"]


def read_pairs(path) -> tuple[np.ndarray, np.ndarray]:
    """Read a correspondence file ``{"source": [ids], "target": [ids]}``."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    try:
        data = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise FileFormatError(path, f"is not valid JSON ({exc})", getattr(exc, "lineno", None)) from None
    if not isinstance(data, dict) or not {"source", "target"} <= data.keys():
        raise FileFormatError(path, 'must be an object with "source" and "target" lists of vertex ids')
    lists = []
    for key in ("source", "target"):
        ids = data[key]
        if not isinstance(ids, list) or not all(isinstance(i, int) and not isinstance(i, bool) for i in ids):
            raise FileFormatError(path, f'"{key}" must be a list of integer vertex ids')
        lists.append(np.asarray(ids, dtype=np.int64))
    if len(lists[0]) != len(lists[1]):
        counts = f'"source" has {len(lists[0])} ids but "target" has {len(lists[1])}'
        raise FileFormatError(path, f"{counts}; they must pair up")
    return lists[0], lists[1]


def transfer(source_neutral, source_expression, target, output, *, correspondence, method: str = "clone",
             mask=None, regions: tuple[str, ...] = ()) -> Path:
    """``faceanim transfer``: write ``target`` wearing the source's expression to ``output``.

    Parameters
    ----------
    source_neutral, source_expression, target, output : path
        Mesh files (.obj, .ply, .glb; output .obj, .ply or .glb).
    correspondence : path
        JSON pairs file, see :func:`read_pairs`.
    method : {"clone", "rbf"}
    mask : path, optional
        JSON list of target vertex ids allowed to move.
    regions : tuple of str
        Face regions allowed to move (needs 68 pairs in the iBUG / Multi-PIE order).
    """
    output = Path(output)
    src0, src1, dst = read_mesh(source_neutral), read_mesh(source_expression), read_mesh(target)
    if len(src1.vertices) != len(src0.vertices):
        raise InputError(f"{source_expression}: has {len(src1.vertices)} vertices but {source_neutral} has "
                         f"{len(src0.vertices)}; the source expression must be the same mesh as its neutral")
    source_ids, target_ids = read_pairs(correspondence)
    try:
        pairs = ControlPairs.checked(source_ids, target_ids, len(src0.vertices), len(dst.vertices))
    except ValueError as exc:
        raise InputError(f"{correspondence}: {exc}") from None
    allowed = None
    if mask is not None:
        try:
            ids = json.loads(Path(mask).read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise InputError(f"{mask}: cannot read the vertex mask ({exc})") from None
        if not isinstance(ids, list) or not all(isinstance(i, int) and 0 <= i < len(dst.vertices) for i in ids):
            raise InputError(f"{mask}: must be a JSON list of target vertex ids in [0, {len(dst.vertices)})")
        allowed = np.zeros(len(dst.vertices), dtype=bool)
        allowed[ids] = True
    if regions:
        unknown = [r for r in regions if r not in REGIONS]
        if unknown:
            raise InputError(f"unknown region {unknown[0]!r}; regions are {', '.join(REGIONS)}")
        if len(pairs.target) != 68:
            raise InputError(f"--region needs the 68 pairs of the iBUG / Multi-PIE layout, got {len(pairs.target)}")
        in_region = region_mask(dst.vertices, dst.vertices[pairs.target], regions)
        allowed = in_region if allowed is None else allowed & in_region
    result = transfer_expression(src0, src1, dst, pairs, method=method, mask=allowed)
    write_mesh(output, result)
    return output
