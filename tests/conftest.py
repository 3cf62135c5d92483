import json
import shutil
import subprocess
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


def khronos_report(path) -> dict:
    """The Khronos glTF validator's report on ``path``, or skip where Node.js or the validator is missing."""
    if shutil.which("node") is None or not (ROOT / "tools" / "node" / "node_modules" / "gltf-validator").exists():
        pytest.skip("needs Node.js and the glTF validator (scripts/setup.sh installs it into tools/node)")
    out = subprocess.run(["node", str(ROOT / "tools" / "validate_gltf.js"), str(path)], capture_output=True,
                         text=True, check=True)
    return json.loads(out.stdout)
