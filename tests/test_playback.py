"""Real glTF clients play faceanim's files as written. Blender 3.4 (headless) and three.js (the viewer's
own copy, in headless Chromium) play each file's animation; the vertex positions they show at chosen
times, between keys included, must match the file's own (rest + sum of w(t) * target, with glTF's
LINEAR interpolation) within 1% of the motion (its largest displacement). Each file also passes the
Khronos validator. Tests skip, saying why, where Blender, Chromium, Node.js or the shared data are
absent.

To check another kind of file, add a maker to ``FILES``: a function of a folder that writes a ``.glb``
there and returns its path (it runs once per module).
"""

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from conftest import khronos_report, shared
from test_gltf import animated_grid, read_animation

from faceanim.cli import main
from faceanim.export import morphs_from_animation, write_glb
from faceanim.geometry import Mesh
from faceanim.geometry.animation import Animation

ROOT = Path(__file__).resolve().parents[1]
TOLERANCE = 0.01  # of the motion's size


def signed_grid(folder: Path) -> Path:
    """A 20 cm grid whose bump swings up and down and whose rows shear both ways: signed SVD modes,
    the case Blender's importer clamped to a still face."""
    grid = animated_grid(frames=30)
    cm = Animation(Mesh(grid.mesh.vertices * 20, grid.mesh.triangles), grid.positions * 20, grid.fps)
    path = folder / "signed_grid.glb"
    write_glb(path, cm.mesh, morphs_from_animation(cm), metres_per_unit=0.01)
    return path


def decode_joy(folder: Path) -> Path:
    """``faceanim decode joy.fap`` onto the default avatar (108 frames at 25 fps)."""
    pytest.importorskip("mediapipe", reason="needs faceanim[capture] to make the default avatar")
    path = folder / "joy.glb"
    assert main(["decode", str(shared("xface", "Faps", "joy.fap")), "-o", str(path)]) == 0
    return path


def express_surprise(folder: Path) -> Path:
    """``faceanim express --emotion surprise --frames 30``: onset, apex, offset, with every AU as a slider."""
    pytest.importorskip("mediapipe", reason="needs faceanim[capture] to make the default avatar")
    path = folder / "surprise.glb"
    assert main(["express", "--emotion", "surprise", "--frames", "30", "-o", str(path)]) == 0
    return path


def animate_d18(folder: Path) -> Path:
    """``faceanim animate d18.mp4`` onto the ICT head (216 frames at 30 fps; teeth, eyes, lashes)."""
    pytest.importorskip("mediapipe", reason="needs faceanim[capture] to track the video")
    path = folder / "d18.glb"
    mesh = shared("ict_facekit", "obj", "generic_neutral_mesh.obj")
    assert main(["animate", str(shared("videos", "d18.mp4")), "--target", str(mesh), "-o", str(path)]) == 0
    return path


def demo(folder: Path) -> Path:
    """``faceanim demo``: the avatar filmed performing, captured and retargeted."""
    pytest.importorskip("mediapipe", reason="needs faceanim[capture] for the demo")
    assert main(["demo", "-o", str(folder / "demo")]) == 0
    return folder / "demo" / "demo.glb"


FILES = {"signed grid": signed_grid, "decode joy.fap": decode_joy, "express surprise": express_surprise,
         "animate d18 onto ICT": animate_d18, "demo": demo}


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """Makes each file of ``FILES`` once per module, when a test first asks for it."""
    folder = tmp_path_factory.mktemp("playback")
    done = {}

    def make(name: str) -> Path:
        if name not in done:
            done[name] = FILES[name](folder)
        return done[name]

    return make


def expected(path: Path):
    """Sample times (s), the file's positions at them ``(N, S, 3)`` (metres, glTF axes), the motion's
    size (m), and the file's own data (see :func:`test_gltf.read_animation`)."""
    data = rest, targets, keys, weights, _, _ = read_animation(path)
    keyed = rest + np.einsum("tk,kvc->tvc", weights, targets)
    moved = np.linalg.norm(keyed - rest, axis=2).max(axis=1)
    peak, step, end = int(moved.argmax()), keys[1] - keys[0], keys[-1]
    times = np.unique(np.clip([0.0, keys[peak], keys[peak] + 0.4 * step, 0.23 * end, 0.5 * end + 0.3 * step,
                               0.81 * end, end], 0.0, end))
    at = np.stack([np.interp(times, keys, w) for w in weights.T], axis=1)  # glTF LINEAR interpolation
    return times, rest + np.einsum("tk,kvc->tvc", at, targets), float(moved.max()), data


def run_tool(command, report: Path) -> None:
    run = subprocess.run(command, capture_output=True, text=True, timeout=300,
                         env={**os.environ, "PATH": os.pathsep.join(["/usr/bin", "/bin", os.environ.get("PATH", "")])})
    assert report.exists(), run.stdout[-2000:] + run.stderr[-2000:]


@pytest.mark.parametrize("name", FILES)
def test_file_passes_the_khronos_validator_with_weights_in_range(name, made):
    path = made(name)
    report = khronos_report(path)
    assert report["errors"] == 0 and report["warnings"] == 0, report["messages"]
    *_, weights, _, extras = read_animation(path)
    assert weights.min() >= 0 and weights.max() <= 1
    assert extras["metres_per_unit"] == 0.01  # every face here is modelled in centimetres


@pytest.mark.parametrize("name", FILES)
def test_blender_plays_the_file_as_written(name, made, tmp_path):
    # Blender's Python finds its standard library through PATH (see test_blender.py), hence run_tool's PATH.
    blender = shutil.which("blender")
    if blender is None:
        pytest.skip("needs Blender (Debian's blender package) to play the file")
    path = made(name)
    times, positions, motion, (_, _, keys, weights, triangles, _) = expected(path)
    (tmp_path / "times.json").write_text(json.dumps(times.tolist()))
    out = tmp_path / "blender.npz"
    run_tool([blender, "--background", "--factory-startup", "--python", str(ROOT / "tools" / "blender_playback.py"),
              "--", str(path), str(tmp_path / "times.json"), str(out)], out)
    found = np.load(out)
    report = json.loads(str(found["report"]))
    used = np.unique(triangles)  # the importer keeps the vertices the triangles use, in the file's order
    assert report["vertices"] == len(used)
    shown = found["positions"][..., [0, 2, 1]] * [1, 1, -1]  # Blender's (x, y, z) is glTF's (x, -z, y)
    error = np.linalg.norm(shown - positions[:, used], axis=2).max()
    print(f"{name}: Blender's largest error {100 * error / motion:.2g}% of the motion ({motion * 100:.2f} cm)")
    assert error <= TOLERANCE * motion, f"{100 * error / motion:.1f}% of the motion"
    names = json.loads(path.read_bytes()[20:20 + int.from_bytes(path.read_bytes()[12:16], "little")])
    names = names["meshes"][0]["extras"]["targetNames"]
    assert list(report["keys"]) == names and report["animated_keys"] == len(names)
    for k, key in enumerate(names):  # every slider admits the weights its key is given
        low, high = report["keys"][key]
        assert low <= weights[:, k].min() and weights[:, k].max() <= high, key
    # The importer keys the clip at time * scene fps from frame 0 and leaves the scene's range at its
    # default, 1 to 250: the timeline starts one frame (1/24 s) into the clip and must reach its end.
    assert report["frame_start"] <= keys[0] * report["fps"] + 1
    assert report["frame_end"] >= keys[-1] * report["fps"]


@pytest.mark.parametrize("name", FILES)
def test_threejs_plays_the_file_as_written(name, made, tmp_path):
    chromium = os.environ.get("CHROMIUM", "/usr/bin/chromium")
    if shutil.which("node") is None or not (ROOT / "tools" / "node" / "node_modules" / "playwright-core").exists():
        pytest.skip("needs Node.js and playwright-core (scripts/setup.sh installs it into tools/node)")
    if not Path(chromium).exists():
        pytest.skip(f"needs Chromium at {chromium} (set CHROMIUM to another)")
    path = made(name)
    times, positions, motion, (_, _, keys, weights, _, _) = expected(path)
    (tmp_path / "times.json").write_text(json.dumps(times.tolist()))
    out = tmp_path / "three.json"
    run_tool(["node", str(ROOT / "tools" / "threejs_playback.js"), str(path), str(tmp_path / "times.json"), str(out)],
             out)
    found = json.loads(out.read_text())
    assert found["errors"] == []
    assert found["duration"] == pytest.approx(keys[-1], abs=1e-6) and found["vertices"] == positions.shape[1]
    influences = np.array(found["influences"])
    assert influences.shape == (len(times), weights.shape[1])
    assert influences.min() >= 0 and influences.max() <= 1
    shown = np.array(found["positions"]).reshape(positions.shape)
    error = np.linalg.norm(shown - positions, axis=2).max()
    print(f"{name}: three.js's largest error {100 * error / motion:.2g}% of the motion ({motion * 100:.2f} cm)")
    assert error <= TOLERANCE * motion, f"{100 * error / motion:.1f}% of the motion"
