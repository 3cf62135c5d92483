"""ICT-FaceKit's face model as the rig's source: its neutral head, its 53 expression shapes and its
68 landmark vertices, read from the toolkit's own files.

ICT-FaceKit (MIT, https://github.com/ICT-VGL/ICT-FaceKit) is not shipped inside faceanim (17 MB of
shapes). :func:`find_ict` looks for a folder holding

* ``ict_deltas_full.npz``: ``neutral (26719, 3)``, ``expression_names (53,)``,
  ``expression_deltas (53, 26719, 3)`` (cm, +x the subject's left, +y up, +z forward),
* ``obj/generic_neutral_mesh.obj``: the topology (its ``f`` lines; quads are split in two),
* ``landmarks_multipie68.json``: ``multi_pie_68``, the 68 iBUG / Multi-PIE landmark vertex ids,

given as an argument, else in ``$FACEANIM_ICT_FACEKIT``, else beside a faceanim checkout at
``../shared/data/ict_facekit``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import FileFormatError, InputError
from ..geometry.mesh import Mesh
from ..jsonfile import read_json
from ..validation import as_array

__all__ = ["IctFaceKit", "find_ict", "load_ict", "ENVIRONMENT"]

ENVIRONMENT = "FACEANIM_ICT_FACEKIT"
_SHAPES = "ict_deltas_full.npz"
_TOPOLOGY = Path("obj") / "generic_neutral_mesh.obj"
_LANDMARKS = "landmarks_multipie68.json"
_CHECKOUT = Path(__file__).resolve().parents[3] / ".." / "shared" / "data" / "ict_facekit"


@dataclass(frozen=True, eq=False)
class IctFaceKit:
    """``mesh``: the neutral head (cm); ``expression_names (53,)``; ``expression_deltas (53, V, 3)``
    (cm, read-only); ``landmarks (68,)``: vertex ids of the iBUG / Multi-PIE 68 points."""

    mesh: Mesh
    expression_names: tuple[str, ...]
    expression_deltas: np.ndarray
    landmarks: np.ndarray

    def __post_init__(self):
        V = len(self.mesh.vertices)
        deltas = as_array(self.expression_deltas, "expression_deltas", shape=(len(self.expression_names), V, 3),
                          frozen=True)
        object.__setattr__(self, "expression_deltas", deltas)
        landmarks = as_array(self.landmarks, "landmarks", shape=(68,), dtype=np.int64, frozen=True)
        if landmarks.min() < 0 or landmarks.max() >= V:
            raise ValueError(f"landmarks must be vertex ids in [0, {V}), got range [{landmarks.min()}, "
                             f"{landmarks.max()}]")
        object.__setattr__(self, "landmarks", landmarks)

    def delta(self, names) -> np.ndarray:
        """``(V, 3)``: the sum of the named expression shapes (zeros for none)."""
        total = np.zeros_like(self.mesh.vertices)
        for name in names:
            total += self.expression_deltas[self.expression_names.index(name)]
        return total


def find_ict(folder=None) -> Path:
    """The ICT-FaceKit folder: ``folder``, else ``$FACEANIM_ICT_FACEKIT``, else the checkout's
    ``../shared/data/ict_facekit``; an :class:`~faceanim.errors.InputError` saying where to get it
    when none holds the model."""
    if folder is not None:
        candidates = [("--ict", Path(folder))]
    elif os.environ.get(ENVIRONMENT):
        candidates = [(f"${ENVIRONMENT}", Path(os.environ[ENVIRONMENT]))]
    else:
        candidates = [("", _CHECKOUT)]
    where, path = candidates[0]
    if (path / _SHAPES).is_file():
        return path
    if where:
        raise InputError(f"{where}: {path} holds no {_SHAPES} (an ICT-FaceKit folder: ict_deltas_full.npz, "
                         f"{_TOPOLOGY.as_posix()}, {_LANDMARKS})")
    raise InputError(f"the ARKit rig is made from ICT-FaceKit's shapes (MIT, github.com/ICT-VGL/ICT-FaceKit): give "
                     f"its folder with --ict DIR or ${ENVIRONMENT} (ict_deltas_full.npz, {_TOPOLOGY.as_posix()}, "
                     f"{_LANDMARKS})")


_loaded: dict = {}


def load_ict(folder=None) -> IctFaceKit:
    """ICT-FaceKit from its folder (see :func:`find_ict`); read once per folder and kept."""
    path = find_ict(folder).resolve()
    if path not in _loaded:
        _loaded.clear()
        _loaded[path] = _read(path)
    return _loaded[path]


def _read(path: Path) -> IctFaceKit:
    shapes = path / _SHAPES
    try:
        with np.load(shapes) as data:
            neutral = data["neutral"].astype(np.float64)
            names = tuple(str(n) for n in data["expression_names"])
            deltas = data["expression_deltas"].astype(np.float64)
    except (OSError, KeyError, ValueError) as exc:
        raise FileFormatError(shapes, f"not ICT-FaceKit's shapes ({exc})") from None
    if neutral.ndim != 2 or neutral.shape[1] != 3 or deltas.shape != (len(names), *neutral.shape):
        raise FileFormatError(shapes, f"neutral {neutral.shape} and expression_deltas {deltas.shape} do not match")
    topology = path / _TOPOLOGY
    if not topology.is_file():
        raise InputError(f"{topology}: missing (ICT-FaceKit's neutral mesh gives the shapes' triangles)")
    triangles = []
    with open(topology) as handle:
        for line in handle:
            if line.startswith("f "):
                ids = [int(t.split("/")[0]) - 1 for t in line.split()[1:]]
                triangles += [(ids[0], ids[k], ids[k + 1]) for k in range(1, len(ids) - 1)]
    triangles = np.asarray(triangles, dtype=np.int64)
    if not len(triangles) or triangles.min() < 0 or triangles.max() >= len(neutral):
        raise FileFormatError(topology, f"its faces do not index the {len(neutral)} vertices of {_SHAPES}")
    landmarks = read_json(path / _LANDMARKS).get("multi_pie_68")
    if not isinstance(landmarks, list) or len(landmarks) != 68:
        raise FileFormatError(path / _LANDMARKS, "needs multi_pie_68, a list of 68 vertex ids")
    return IctFaceKit(Mesh(neutral, triangles), names, deltas, np.asarray(landmarks))
