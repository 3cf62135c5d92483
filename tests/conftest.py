import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"
sys.path.insert(0, str(ROOT / "benchmarks"))  # the ICT scenario is shared with the benchmark


def shared(*parts) -> Path:
    """A file under ../shared/data, or skip the test saying which path is missing."""
    path = SHARED.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"needs {path} (the shared data folder beside the checkout)")
    return path


def grid_mesh(n=6, size=1.0):
    """An n x n vertex grid in the z=0 plane, facing +z."""
    from faceanim.geometry import Mesh

    x, y = np.meshgrid(np.linspace(0, size, n), np.linspace(0, size, n))
    v = np.stack([x.ravel(), y.ravel(), np.zeros(n * n)], axis=1)
    tris = []
    for i in range(n - 1):
        for j in range(n - 1):
            a = i * n + j
            tris += [(a, a + 1, a + n + 1), (a, a + n + 1, a + n)]
    return Mesh(v, np.array(tris))
