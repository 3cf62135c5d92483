"""`Animation`: a mesh and its vertex positions per frame."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..validation import as_array
from .mesh import Mesh

__all__ = ["Animation"]


@dataclass(frozen=True, eq=False)
class Animation:
    """``mesh`` (its own vertices are the rest pose), ``positions (T, V, 3)`` float64 and ``fps``."""

    mesh: Mesh
    positions: np.ndarray
    fps: float

    def __post_init__(self):
        positions = as_array(self.positions, "positions", shape=("T", len(self.mesh.vertices), 3), min_length=1)
        if not np.isfinite(self.fps) or self.fps <= 0:
            raise ValueError(f"fps must be positive, got {self.fps}")
        object.__setattr__(self, "positions", positions)
        object.__setattr__(self, "fps", float(self.fps))

    def __len__(self) -> int:
        return len(self.positions)
