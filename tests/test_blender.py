"""The exported glTF opens in Blender with its shape keys and their animation (Debian's blender,
headless; skipped where it is absent)."""

import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest
from test_gltf import animated_grid

from faceanim.export import morphs_from_animation, write_glb
from faceanim.geometry import Mesh

ROOT = Path(__file__).resolve().parents[1]


def blender_import(glb: Path, tmp_path: Path) -> dict:
    blender = shutil.which("blender")
    if blender is None:
        pytest.skip("needs Blender (Debian's blender package) to check the import")
    report = tmp_path / "blender.json"
    # Blender's embedded Python finds its standard library through PATH; a Python other than the
    # system's first on PATH (pyenv, a venv) would hand it a library without Debian's numpy.
    env = {**os.environ, "PATH": os.pathsep.join(["/usr/bin", "/bin", os.environ.get("PATH", "")])}
    run = subprocess.run([blender, "--background", "--factory-startup", "--python",
                          str(ROOT / "tools" / "blender_import_check.py"), "--", str(glb), str(report)],
                         capture_output=True, text=True, timeout=300, env=env)
    assert report.exists(), run.stdout[-2000:] + run.stderr[-2000:]
    return json.loads(report.read_text())


def test_blender_imports_shape_keys_and_their_animation(tmp_path):
    import numpy as np

    animation = animated_grid(frames=30)
    mesh = animation.mesh
    textured = Mesh(mesh.vertices, mesh.triangles, uv=mesh.vertices[:, :2],
                    texture=np.full((8, 8, 3), 200, np.uint8))
    morphs = morphs_from_animation(type(animation)(textured, animation.positions, animation.fps))
    write_glb(tmp_path / "grid.glb", textured, morphs)
    found = blender_import(tmp_path / "grid.glb", tmp_path)
    assert found["meshes"] == 1
    (obj,) = found["objects"]
    assert obj["vertices"] == len(mesh.vertices)
    assert obj["shape_keys"][1:] == list(morphs.names)  # Blender adds its "Basis" first
    assert obj["animated_keys"] == len(morphs.names)
    start, end = obj["frame_range"]
    assert end - start == pytest.approx((30 - 1) / animation.fps * 24, abs=1.0)  # Blender's 24 fps timeline
    assert obj["textured"]
