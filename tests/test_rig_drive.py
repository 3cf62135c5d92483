"""Driving a named rig: the per-frame solve, names in many spellings, the written animation, the CSV
routes and the errors. The rig here is MediaPipe's canonical face (the generic target, its points
named) with a few localised shapes under ARKit names and one under no rig name."""

import json
import shutil
import types

import numpy as np
import pytest
from scipy.optimize import lsq_linear

from faceanim.cli import main
from faceanim.driving import read_au_csv, solve_capture
from faceanim.errors import FileFormatError, InputError
from faceanim.export import MorphSet, write_glb
from faceanim.inputs import load_target
from faceanim.motion import Motion
from faceanim.rig.arkit import ARKIT_NAMES
from faceanim.rig.drive import FACS_ARKIT, canonical_name, weights_by_name
from faceanim.rig.livelink import POSE_COLUMNS, Take, write_livelink_csv
from faceanim.rig.rigfile import read_rig
from faceanim.rig.solve import RigSolver, box_qp

NAMES = ("jawOpen", "mouthSmile_L", "mouthSmile_R", "eyeBlinkLeft", "eyeBlinkRight", "browInnerUp", "mouthFunnel",
         "cheekPuff", "custom")
DRIVEN = len(NAMES) - 1  # "custom" has no rig name


def _shapes(vertices, count, rng):
    """``count`` smooth localised displacements (cm), each a bump about a random vertex."""
    shapes = []
    for _ in range(count):
        centre = vertices[rng.integers(len(vertices))]
        fall = np.exp(-((vertices - centre) ** 2).sum(1) / (2 * 2.0 ** 2))
        shapes.append(fall[:, None] * rng.normal(size=3) * 0.8)
    return np.stack(shapes)


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    """(path, target, shapes (S, V, 3)) of a rig .glb written as faceanim writes one (points carried, cm)."""
    from faceanim.generic import generic_target

    target = generic_target()
    shapes = _shapes(target.mesh.vertices, len(NAMES), np.random.default_rng(1))
    path = tmp_path_factory.mktemp("rig") / "rig.glb"
    write_glb(path, target.mesh, MorphSet(shapes, NAMES), extras={"points": dict(target.points)}, metres_per_unit=0.01)
    return path, load_target(path), shapes


def _curves(frames, count, seed=0):
    """Smooth weights in [0, 1] that reach both bounds."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 6, frames)[:, None]
    return np.clip(np.sin(t * rng.uniform(0.5, 2, count) + rng.uniform(0, 6, count)) * 1.2, 0, 1)


def _capture(target, shapes, weights):
    """A capture whose motion is the target's points moved by ``weights`` of ``shapes`` (no video)."""
    names = tuple(target.points)
    ids = target.ids(names)
    moved = np.einsum("ts,svc->tvc", weights, shapes[:, ids])
    motion = Motion(names, target.mesh.vertices[ids], moved, np.tile(np.eye(4), (len(weights), 1, 1)), 25.0,
                    target.fapu)
    return types.SimpleNamespace(motion=motion, blendshapes=None, blendshape_names=())


# ---- the solve


def test_box_qp_finds_the_bounded_least_squares_optimum():
    rng = np.random.default_rng(0)
    for _ in range(50):
        A = rng.normal(size=(60, 12)) * rng.uniform(0.1, 2, 12)
        b = rng.normal(size=60) * 3
        H, g = A.T @ A + 1e-6 * np.eye(12), A.T @ b
        found = box_qp(H, g, rng.uniform(0, 1, 12))
        R = np.linalg.cholesky(H).T
        best = lsq_linear(R, np.linalg.solve(R.T, g), bounds=(0, 1), method="bvls").x
        np.testing.assert_allclose(found, best, atol=1e-8)


def test_a_rig_driven_by_its_own_weights_is_solved_back_exactly(rig):
    _, target, shapes = rig
    weights = _curves(150, DRIVEN)
    ids = target.ids(list(target.points))
    observed = np.einsum("ts,svc->tvc", weights, shapes[:DRIVEN, ids])
    solved = RigSolver(shapes[:DRIVEN, ids], ridge=0.0, temporal=0.0)(observed)
    np.testing.assert_allclose(solved, weights, atol=1e-9)


def test_the_video_solve_recovers_the_weights_through_the_file(rig):
    # The default ridge and temporal terms are small: the weights come back within a few hundredths.
    path, target, shapes = rig
    weights = np.hstack([_curves(150, DRIVEN, seed=3), np.zeros((150, 1))])
    solved = solve_capture(read_rig(path), target, _capture(target, shapes, weights))
    assert solved.shape == (150, DRIVEN)
    assert np.abs(solved - weights[:, :DRIVEN]).max() < 0.03


def test_weights_stay_in_the_unit_interval_whatever_the_motion(rig):
    path, target, shapes = rig
    wild = np.random.default_rng(5).normal(scale=3.0, size=(40, len(NAMES)))  # far outside [0, 1], both ways
    solved = solve_capture(read_rig(path), target, _capture(target, shapes, wild))
    assert solved.min() >= 0.0 and solved.max() <= 1.0
    assert (solved == 0.0).any() and (solved == 1.0).any()


def test_frames_without_a_face_hold_the_last_weights(rig):
    _, target, shapes = rig
    ids = target.ids(list(target.points))
    observed = np.einsum("ts,svc->tvc", _curves(20, DRIVEN), shapes[:DRIVEN, ids])
    observed[5:9] = np.nan
    solved = RigSolver(shapes[:DRIVEN, ids])(observed)
    assert np.isfinite(solved).all() and (solved[5:9] == solved[4]).all()


def test_a_prior_pulls_only_the_shapes_it_is_given_for(rig):
    _, target, shapes = rig
    ids = target.ids(list(target.points))
    observed = np.zeros((10, len(ids), 3))  # the face at rest, the scores say the left eye is shut
    prior = np.full((10, DRIVEN), np.nan)
    prior[:, 3] = 1.0
    strength = np.zeros(DRIVEN)
    strength[3] = 100.0
    lid = (shapes[3, ids] ** 2).sum(1) > 0.01 * (shapes[3, ids] ** 2).sum(1).max()
    solved = RigSolver(shapes[:DRIVEN, ids], prior_strength=strength, point_weights=~lid)(observed, prior)
    assert solved[-1, 3] > 0.95 and np.delete(solved[-1], 3).max() < 0.05
    fought = RigSolver(shapes[:DRIVEN, ids], prior_strength=strength)(observed, prior)  # every point counted
    assert np.delete(fought[-1], 3).max() > 0.05


# ---- names


def test_names_are_read_in_the_spellings_tools_use():
    spellings = {"JawOpen": "jawOpen", "jaw_open": "jawOpen", "eyeBlink_L": "eyeBlinkLeft",
                 "blendShape1.mouthSmileRight": "mouthSmileRight", "ARKit_browDownLeft": "browDownLeft",
                 "browInnerUp_R": "browInnerUpRight", "AU01": "AU1", "au_12": "AU12", "AU12L": "AU12L",
                 "AU30_R": "AU30R", "shape00": None, "expression": None, "mouth_L": None}
    assert {n: canonical_name(n) for n in spellings} == spellings


def test_weights_cross_between_arkit_and_au_names_through_the_table():
    smile = np.array([0.2, 0.8])
    by_au = weights_by_name(["mouthSmileLeft", "mouthSmileRight", "jawOpen"], aus={"12L": smile}, length=2)
    np.testing.assert_allclose(by_au, [[0.2, 0, 0], [0.8, 0, 0]])
    by_arkit = weights_by_name(["AU12", "AU12R", "AU1"], arkit={"mouthSmileLeft": np.array([1.0]),
                                                                "mouthSmileRight": np.array([0.5])}, length=1)
    np.testing.assert_allclose(by_arkit, [[0.75, 0.5, 0.0]])
    assert all(s in ARKIT_NAMES for shapes in FACS_ARKIT.values() for s in shapes)


# ---- the written file


def _document(path):
    data = path.read_bytes()
    return json.loads(data[20:20 + int.from_bytes(data[12:16], "little")])


def _animated_weights(path):
    import pygltflib

    gltf = pygltflib.GLTF2().load(str(path))
    blob = gltf.binary_blob()
    (animation,) = gltf.animations
    (channel,) = animation.channels
    sampler = animation.samplers[channel.sampler]

    def read(index):
        accessor = gltf.accessors[index]
        view = gltf.bufferViews[accessor.bufferView]
        return np.frombuffer(blob, np.float32, accessor.count, view.byteOffset + (accessor.byteOffset or 0))

    times = read(sampler.input)
    return channel, times, read(sampler.output).reshape(len(times), -1)


def _livelink(path, weights, fps=25.0):
    times = np.arange(len(weights)) / fps
    write_livelink_csv(path, Take(times, weights, np.zeros((len(weights), len(POSE_COLUMNS))), fps))


def test_a_live_link_take_drives_the_rig_by_name_and_the_file_keeps_the_rig(rig, tmp_path, capsys):
    path, _, _ = rig
    weights = np.zeros((30, len(ARKIT_NAMES)))
    weights[:, ARKIT_NAMES.index("jawOpen")] = np.linspace(0, 1, 30)
    weights[:, ARKIT_NAMES.index("mouthSmileLeft")] = 0.25
    weights[:, ARKIT_NAMES.index("browInnerUp")] = np.linspace(1, 0, 30)
    weights[:, ARKIT_NAMES.index("tongueOut")] = 1.0  # the rig has no such target: dropped
    take = tmp_path / "take.csv"
    _livelink(take, weights)
    out = tmp_path / "out.glb"
    assert main(["animate", str(take), "--target", str(path), "-o", str(out)]) == 0
    assert "8 named morph targets" in capsys.readouterr().out
    channel, times, animated = _animated_weights(out)
    assert channel.target.path == "weights" and channel.target.node == 0
    np.testing.assert_allclose(times, np.arange(30) / 25.0, atol=1e-5)
    expected = np.zeros((30, len(NAMES)))
    for k, name in enumerate(NAMES[:DRIVEN]):
        expected[:, k] = weights[:, ARKIT_NAMES.index(canonical_name(name).replace("InnerUpLeft", "InnerUp"))]
    np.testing.assert_allclose(animated, expected, atol=1e-6)  # "custom" keeps 0
    before, after = _document(path), _document(out)
    assert after["meshes"] == before["meshes"]  # the mesh, its targets' names and its extras as they were
    assert [a["bufferView"] for a in after["accessors"][:len(before["accessors"])]] == [
        a["bufferView"] for a in before["accessors"]]
    import pygltflib

    old_blob = pygltflib.GLTF2().load(str(path)).binary_blob()
    assert pygltflib.GLTF2().load(str(out)).binary_blob()[:len(old_blob)] == old_blob  # the rig's data untouched


def test_the_written_animation_plays_in_blender(rig, tmp_path):
    from test_playback import ROOT, run_tool

    blender = shutil.which("blender")
    if blender is None:
        pytest.skip("needs Blender (Debian's blender package) to play the file")
    path, _, shapes = rig
    weights = np.zeros((25, len(ARKIT_NAMES)))
    weights[:, ARKIT_NAMES.index("jawOpen")] = np.linspace(0, 1, 25)
    weights[:, ARKIT_NAMES.index("eyeBlinkLeft")] = np.linspace(1, 0, 25) ** 2
    take, out = tmp_path / "take.csv", tmp_path / "out.glb"
    _livelink(take, weights)
    assert main(["animate", str(take), "--target", str(path), "-o", str(out)]) == 0
    times = np.array([0.0, 0.3, 0.5 + 0.4 / 25, 0.96])
    (tmp_path / "times.json").write_text(json.dumps(times.tolist()))
    found_path = tmp_path / "blender.npz"
    run_tool([blender, "--background", "--factory-startup", "--python", str(ROOT / "tools" / "blender_playback.py"),
              "--", str(out), str(tmp_path / "times.json"), str(found_path)], found_path)
    found = np.load(found_path)
    report = json.loads(str(found["report"]))
    assert list(report["keys"]) == list(NAMES)
    from test_gltf import read_animation

    rest, targets, keys, animated, triangles, _ = read_animation(out)
    at = np.stack([np.interp(times, keys, w) for w in animated.T], axis=1)
    assert at[2, 0] == pytest.approx(np.interp(times[2], np.arange(25) / 25, weights[:, 17]), abs=1e-5)
    positions = rest + np.einsum("tk,kvc->tvc", at, targets)
    used = np.unique(triangles)
    shown = found["positions"][..., [0, 2, 1]] * [1, 1, -1]  # Blender's (x, y, z) is glTF's (x, -z, y)
    motion = np.linalg.norm(positions - rest, axis=2).max()
    assert np.linalg.norm(shown - positions[:, used], axis=2).max() <= 0.01 * motion


def test_an_au_csv_drives_au_and_arkit_names(tmp_path):
    from faceanim.generic import generic_target

    target = generic_target()
    shapes = _shapes(target.mesh.vertices, 3, np.random.default_rng(2))
    rig_path = tmp_path / "au.glb"
    write_glb(rig_path, target.mesh, MorphSet(shapes, ("AU12", "AU01", "mouthSmileLeft")), metres_per_unit=0.01)
    csv = tmp_path / "openface.csv"
    csv.write_text("frame, timestamp, success, AU01_r, AU12_r, AU45_r\n"
                   "1, 0.000, 1, 0.0, 5.0, 0.0\n2, 0.040, 1, 2.5, 2.5, 0.0\n3, 0.080, 0, 0.0, 0.0, 0.0\n")
    aus, fps = read_au_csv(csv)
    assert fps == pytest.approx(25.0) and aus["12"].tolist()[:2] == [1.0, 0.5]
    out = tmp_path / "out.glb"
    assert main(["animate", str(csv), "--target", str(rig_path), "-o", str(out)]) == 0
    _, _, animated = _animated_weights(out)
    np.testing.assert_allclose(animated, [[1.0, 0.0, 1.0], [0.5, 0.5, 0.5], [0.5, 0.5, 0.5]], atol=1e-6)


@pytest.mark.filterwarnings("ignore:AU12")  # 1.5 is asked for: the weight is clipped to 1
def test_express_frames_on_an_au_rig_plays_the_recipe_on_its_sliders(tmp_path):
    from faceanim.expressions import envelope
    from faceanim.generic import generic_target

    target = generic_target()
    shapes = _shapes(target.mesh.vertices, 3, np.random.default_rng(4))
    rig_path = tmp_path / "au.glb"
    write_glb(rig_path, target.mesh, MorphSet(shapes, ("AU6", "AU12", "AU4")), metres_per_unit=0.01)
    out = tmp_path / "joy.glb"
    assert main(["express", "--au", "6:0.8,12:1.5", "--target", str(rig_path), "--frames", "20", "-o", str(out)]) == 0
    _, times, animated = _animated_weights(out)
    assert len(times) == 20
    shape = envelope(20)
    np.testing.assert_allclose(animated, np.stack([0.8 * shape, np.minimum(1.5 * shape, 1), 0 * shape], 1), atol=1e-6)


# ---- errors: one line, exit 2, nothing written


def test_a_rig_with_no_recognisable_names_is_refused_naming_what_is_expected(tmp_path, capsys):
    from faceanim.geometry import Mesh

    mesh = Mesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]]), np.array([[0, 1, 2]]))
    plain = tmp_path / "plain.glb"
    write_glb(plain, mesh, MorphSet(np.ones((2, 3, 3)), ("shape00", "smile big")))
    take = tmp_path / "take.csv"
    _livelink(take, np.zeros((3, len(ARKIT_NAMES))))
    out = tmp_path / "out.glb"
    assert main(["animate", str(take), "--target", str(plain), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(plain) in err and "jawOpen" in err and "AU12" in err
    assert not out.exists() and list(tmp_path.iterdir()) == sorted([plain, take]) or not out.exists()
    with pytest.raises(InputError, match="shape00"):
        read_rig(plain)


@pytest.mark.parametrize("change, words", [
    (lambda text: text.replace("JawOpen", "JawOpn"), "JawOpn"),
    (lambda text: text.replace(",0.000000,", ",1.500000,", 1), "1.5"),
])
def test_a_bad_live_link_take_is_one_line(rig, tmp_path, capsys, change, words):
    path, _, _ = rig
    take = tmp_path / "take.csv"
    _livelink(take, np.zeros((3, len(ARKIT_NAMES))))
    take.write_text(change(take.read_text()))
    out = tmp_path / "out.glb"
    assert main(["animate", str(take), "--target", str(path), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(take) in err and words in err, err
    assert not out.exists()


def test_a_bad_au_csv_is_refused_naming_the_line(tmp_path):
    csv = tmp_path / "openface.csv"
    csv.write_text("frame, AU12_r\n1, 0.5\n2, 6.0\n")
    with pytest.raises(FileFormatError, match=r"openface.csv:3: AU12_r is 6"):
        read_au_csv(csv)
    csv.write_text("frame, confidence\n1, 0.5\n")
    with pytest.raises(FileFormatError, match="no AU column"):
        read_au_csv(csv)


def test_options_the_rig_route_cannot_honour_are_refused_before_work(rig, tmp_path):
    from faceanim import pipeline

    path, _, _ = rig
    take = tmp_path / "take.csv"
    _livelink(take, np.zeros((3, len(ARKIT_NAMES))))
    with pytest.raises(InputError, match="--head-motion"):
        pipeline.animate(take, tmp_path / "out.glb", target_mesh=path, head_motion=True)
    with pytest.raises(InputError, match="--preview"):  # a wrong suffix, before any work
        pipeline.animate(take, tmp_path / "out.glb", target_mesh=path, preview=tmp_path / "p.avi")
    assert not (tmp_path / "out.glb").exists()
    with pytest.raises(InputError, match="give --target"):
        pipeline.animate(take, tmp_path / "out.glb")


def test_a_video_drives_the_rig_with_the_scores_fused(rig, tmp_path):
    # The generic face's points carry the tracker's names: the video's motion reaches the rig's shapes,
    # and the blink targets follow the Face Landmarker's scores.
    pytest.importorskip("mediapipe", reason="needs faceanim[capture] to track the video")
    from conftest import shared

    from faceanim.mpeg4.fapfile import read_fap

    video = shared("videos", "d18.mp4")
    path, _, _ = rig
    out, fap = tmp_path / "d18_rig.glb", tmp_path / "d18.fap"
    assert main(["animate", str(video), "--target", str(path), "-o", str(out), "--fap", str(fap)]) == 0
    channel, times, animated = _animated_weights(out)
    assert channel.target.path == "weights" and len(times) == len(read_fap(fap))
    assert animated.min() >= 0 and animated.max() <= 1
    assert (animated[:, -1] == 0).all()  # "custom": no rig name, no curve
    assert animated[:, :DRIVEN].max(axis=0).min() >= 0 and animated[:, 3:5].max() > 0  # blinks were read


def test_the_written_file_passes_the_khronos_validator(rig, tmp_path):
    from conftest import khronos_report

    path, _, _ = rig
    weights = np.zeros((10, len(ARKIT_NAMES)))
    weights[:, ARKIT_NAMES.index("jawOpen")] = np.linspace(0, 1, 10)
    take, out = tmp_path / "take.csv", tmp_path / "out.glb"
    _livelink(take, weights)
    assert main(["animate", str(take), "--target", str(path), "-o", str(out)]) == 0
    report = khronos_report(out)
    assert report["errors"] == 0 and report["warnings"] == 0, report["messages"]


def test_driving_an_animated_rig_replaces_its_weight_curves(rig, tmp_path):
    path, _, _ = rig
    first, second = np.zeros((10, len(ARKIT_NAMES))), np.zeros((6, len(ARKIT_NAMES)))
    first[:, ARKIT_NAMES.index("jawOpen")] = 1.0
    second[:, ARKIT_NAMES.index("mouthFunnel")] = 0.5
    for name, weights in (("first", first), ("second", second)):
        _livelink(tmp_path / f"{name}.csv", weights)
    once, twice = tmp_path / "once.glb", tmp_path / "twice.glb"
    assert main(["animate", str(tmp_path / "first.csv"), "--target", str(path), "-o", str(once)]) == 0
    assert main(["animate", str(tmp_path / "second.csv"), "--target", str(once), "-o", str(twice)]) == 0
    _, times, animated = _animated_weights(twice)  # one animation: the second take's
    assert len(times) == 6 and animated[:, 0].max() == 0 and animated[:, 6].min() == pytest.approx(0.5)


def test_the_preview_and_obj_files_show_the_rig_moved_by_its_weights(rig, tmp_path):
    from faceanim.geometry import read_mesh

    path, target, shapes = rig
    weights = np.zeros((8, len(ARKIT_NAMES)))
    weights[:, ARKIT_NAMES.index("jawOpen")] = np.linspace(0, 1, 8)
    take, out, frames = tmp_path / "take.csv", tmp_path / "out.glb", tmp_path / "frames"
    _livelink(take, weights)
    assert main(["animate", str(take), "--target", str(path), "-o", str(out), "--obj-sequence", str(frames),
                 "--preview", str(tmp_path / "p.mp4")]) == 0
    assert (tmp_path / "p.mp4").stat().st_size > 0
    files = sorted(frames.glob("*.obj"))
    assert len(files) == 8
    last = read_mesh(files[-1]).vertices
    np.testing.assert_allclose(last, target.mesh.vertices + shapes[0], atol=1e-5)


def test_sided_au_columns_are_sides_and_lower_case_r_is_openfaces_intensity(tmp_path):
    sided = tmp_path / "sided.csv"
    sided.write_text("frame,AU12_L,AU12_R\n1,0.2,0.9\n2,0.3,0.8\n")
    curves, _ = read_au_csv(sided)
    np.testing.assert_allclose(curves["12L"], [0.2, 0.3])
    np.testing.assert_allclose(curves["12R"], [0.9, 0.8])  # a right side, not an intensity on 0-5
    openface = tmp_path / "openface.csv"
    openface.write_text("frame, AU12_r, AU12_c\n1, 2.5, 1\n2, 5.0, 1\n")
    curves, _ = read_au_csv(openface)
    np.testing.assert_allclose(curves["12"], [0.5, 1.0])
