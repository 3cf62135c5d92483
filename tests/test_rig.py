"""The ARKit-52 rig (issue 16, part 3): names, the ICT mapping, exact shapes when the target is ICT
itself (in metres, its vertices shuffled), bad targets refused in one line, and the .glb as
Blender opens it. The rig's registration runs once, on ICT's face region (about 10 s), for the file."""

import json
import os
import shutil
import subprocess

import numpy as np
import pytest
from conftest import SHARED, shared

from faceanim.cli import main
from faceanim.rig import ARKIT_NAMES, EMPTY_IN_ICT, ICT_SHAPES, arkit_of_ict

FACE = 9409  # ICT's face region: vertices 0-9408


def test_the_52_arkit_names_and_how_ict_makes_them():
    assert len(ARKIT_NAMES) == len(set(ARKIT_NAMES)) == 52
    assert ARKIT_NAMES[:3] == ("eyeBlinkLeft", "eyeLookDownLeft", "eyeLookInLeft") and ARKIT_NAMES[-1] == "tongueOut"
    used = [n for names in ICT_SHAPES.values() for n in names]
    assert len(used) == len(set(used)) == 53  # every ICT shape used once
    assert ICT_SHAPES["browInnerUp"] == ("browInnerUp_L", "browInnerUp_R")
    assert ICT_SHAPES["cheekPuff"] == ("cheekPuff_L", "cheekPuff_R")
    assert ICT_SHAPES["jawLeft"] == ("jawLeft",) and ICT_SHAPES["mouthRight"] == ("mouthRight",)
    assert EMPTY_IN_ICT == ("tongueOut",) and ICT_SHAPES["tongueOut"] == ()
    for name, parts in ICT_SHAPES.items():
        if len(parts) == 1:
            assert arkit_of_ict(parts[0]) == name
    if (SHARED / "ict_facekit" / "ict_deltas_full.npz").exists():
        with np.load(SHARED / "ict_facekit" / "ict_deltas_full.npz") as data:
            assert sorted(used) == sorted(str(n) for n in data["expression_names"])


def _small_ict(folder):
    """ICT-FaceKit cut to its face region, as a folder ``load_ict`` reads (the registration is then quick)."""
    from faceanim.rig.ictface import load_ict

    full = load_ict(shared("ict_facekit"))
    folder.mkdir()
    (folder / "obj").mkdir()
    np.savez(folder / "ict_deltas_full.npz", neutral=full.mesh.vertices[:FACE],
             expression_names=np.asarray(full.expression_names), expression_deltas=full.expression_deltas[:, :FACE])
    tris = full.mesh.triangles[(full.mesh.triangles < FACE).all(axis=1)]
    faces = "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in tris)
    (folder / "obj" / "generic_neutral_mesh.obj").write_text(faces)
    shutil.copy(shared("ict_facekit", "landmarks_multipie68.json"), folder / "landmarks_multipie68.json")
    return full


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """The rig made by ``faceanim rig`` on ICT's face region in metres, its vertices shuffled, the 68
    iBUG points given (by MediaPipe index) with the MPEG-4 points."""
    from faceanim.geometry import Mesh, write_mesh
    from faceanim.landmarks import IBUG68_LANDMARK
    from faceanim.mpeg4.multipie import MULTIPIE68_OF_FEATURE_POINT
    from faceanim.rigging import make_rig

    folder = tmp_path_factory.mktemp("rig")
    full = _small_ict(folder / "ict")
    order = np.random.default_rng(4).permutation(FACE)  # new vertex i is ICT's vertex order[i]
    new_of = np.argsort(order)
    small = full.mesh.triangles[(full.mesh.triangles < FACE).all(axis=1)]
    vertices = 0.01 * full.mesh.vertices[order]
    write_mesh(folder / "face.obj", Mesh(vertices, new_of[small]))
    marks = full.landmarks
    points = {f"mp{m}": int(new_of[v]) for m, v in zip(IBUG68_LANDMARK, marks, strict=True)}
    points.update({n: int(new_of[marks[i]]) for n, i in MULTIPIE68_OF_FEATURE_POINT.items()})
    (folder / "points.json").write_text(json.dumps(points))
    rigged = make_rig(folder / "face.obj", folder / "rigged.glb", points=folder / "points.json", ict=folder / "ict")
    expected = 0.01 * np.stack([full.delta(ICT_SHAPES[n])[order] for n in ARKIT_NAMES])
    return folder, rigged, expected


def test_a_target_that_is_ict_gets_icts_own_shapes(made):
    """ICT registered onto itself is the identity: every shape is ICT's, in the target's metres, on
    the target's own vertex order."""
    _, rigged, expected = made
    assert rigged.names == ARKIT_NAMES and rigged.layout == "ibug68"
    assert rigged.shapes.shape == expected.shape == (52, FACE, 3)
    assert not rigged.shapes.flags.writeable
    size = np.linalg.norm(expected.reshape(52, -1), axis=1)
    error = np.linalg.norm((rigged.shapes - expected).reshape(52, -1), axis=1)
    scored = size > 0
    assert (size == 0).tolist() == [n in EMPTY_IN_ICT for n in ARKIT_NAMES]
    assert np.abs(rigged.shapes[~scored]).max() == 0  # tongueOut: empty
    relative = dict(zip(ARKIT_NAMES, np.round(error / np.where(scored, size, 1.0), 4), strict=True))
    assert np.median(error[scored] / size[scored]) < 1e-3, relative  # measured 7e-5
    assert (error[scored] / size[scored]).max() < 0.02, relative  # measured 0.006


def test_the_glb_carries_52_named_targets_in_metres_and_its_points(made):
    from faceanim.geometry import read_mesh
    from faceanim.geometry.meshio import glb_extras, read_glb_json

    folder, rigged, _ = made
    gltf = read_glb_json(folder / "rigged.glb")
    (mesh,) = gltf["meshes"]
    assert mesh["extras"]["targetNames"] == list(ARKIT_NAMES)
    assert len(mesh["primitives"][0]["targets"]) == 52 and mesh["weights"] == [0.0] * 52
    extras = glb_extras(folder / "rigged.glb")
    assert extras["arkit"]["empty"] == ["tongueOut"] and extras["metres_per_unit"] == 1.0
    assert extras["points"] == json.loads((folder / "points.json").read_text())
    back = read_mesh(folder / "rigged.glb")
    assert np.allclose(back.vertices, rigged.target.mesh.vertices, atol=1e-7)  # its own vertices, in order


def test_cli_writes_the_rig_and_refuses_bad_targets_in_one_line(made, tmp_path, capsys):
    from conftest import grid_mesh

    from faceanim.geometry import write_mesh

    folder, _, _ = made
    ict = ["--ict", str(folder / "ict")]
    out = tmp_path / "again.glb"
    # The same mesh again: the registration comes from the in-process cache.
    assert main(["rig", str(folder / "face.obj"), "--points", str(folder / "points.json"), *ict, "-o", str(out)]) == 0
    assert "52 ARKit shapes" in capsys.readouterr().out and out.exists()
    write_mesh(tmp_path / "flat.obj", grid_mesh(8, 10.0))
    given = json.loads((folder / "points.json").read_text())
    few = {n: i for n, i in given.items() if not n.startswith("mp") and n != "9.3"}  # FAPU, but no nose tip
    (tmp_path / "few.json").write_text(json.dumps(few))
    bad = tmp_path / "bad.glb"
    for args, message in (
            ([str(tmp_path / "missing.obj")], "missing.obj"),
            ([str(folder / "face.obj"), "--ict", str(tmp_path)], "holds no ict_deltas_full.npz"),
            ([str(folder / "face.obj"), "--points", str(tmp_path / "few.json"), *ict], "missing 9.3"),
            ([str(tmp_path / "flat.obj"), *ict], "found no face")):
        assert main(["rig", *args, "-o", str(bad)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and message in err[0], err
        assert not bad.exists()
    assert main(["rig", str(folder / "face.obj"), *ict, "-o", str(tmp_path / "rig.obj")]) == 2
    assert "written as .glb" in capsys.readouterr().err


_BLENDER_SCRIPT = """
import json, sys
import bpy, numpy
if not hasattr(numpy, "bool"):
    numpy.bool = bool
glb, report, key = sys.argv[sys.argv.index("--") + 1:][:3]
for obj in list(bpy.data.objects):
    bpy.data.objects.remove(obj)
bpy.ops.import_scene.gltf(filepath=glb)
(obj,) = [o for o in bpy.context.scene.objects if o.type == "MESH"]
blocks = obj.data.shape_keys.key_blocks
rest = [tuple(v.co) for v in obj.data.vertices]
blocks[key].value = 1.0
mesh = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).to_mesh()
posed = [tuple(v.co) for v in mesh.vertices]
json.dump({"keys": [k.name for k in blocks], "rest": rest, "posed": posed,
           "slider": [blocks[key].slider_min, blocks[key].slider_max]}, open(report, "w"))
"""


def test_blender_opens_52_shape_keys_and_a_key_at_1_is_the_shape(made, tmp_path):
    blender = shutil.which("blender")
    if blender is None:
        pytest.skip("needs Blender (Debian's blender package) to check the import")
    folder, rigged, _ = made
    script, report = tmp_path / "check.py", tmp_path / "blender.json"
    script.write_text(_BLENDER_SCRIPT)
    env = {**os.environ, "PATH": os.pathsep.join(["/usr/bin", "/bin", os.environ.get("PATH", "")])}
    run = subprocess.run([blender, "--background", "--factory-startup", "--python", str(script), "--",
                          str(folder / "rigged.glb"), str(report), "jawOpen"],
                         capture_output=True, text=True, timeout=300, env=env)
    assert report.exists(), run.stdout[-2000:] + run.stderr[-2000:]
    found = json.loads(report.read_text())
    assert found["keys"] == ["Basis", *ARKIT_NAMES] and found["slider"] == [0.0, 1.0]
    to_blender = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]])  # glTF's +y up is Blender's +z up
    rest = rigged.target.mesh.vertices @ to_blender.T  # metres: the target is in metres
    shape = rigged.shapes[ARKIT_NAMES.index("jawOpen")] @ to_blender.T
    assert np.allclose(found["rest"], rest, atol=1e-6)
    assert np.allclose(found["posed"], rest + shape, atol=1e-6)
