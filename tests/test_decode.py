import json
import re

import numpy as np
import pytest
from conftest import grid_mesh, shared

from faceanim.errors import FileFormatError, InputError
from faceanim.geometry import Mesh
from faceanim.motion import Motion, motion_to_faps
from faceanim.mpeg4 import FAP_COUNT, Fapu, fap_table
from faceanim.mpeg4.fapfile import read_fap
from faceanim.mpeg4.fapstream import FapStream, held
from faceanim.retarget.decode import animate_faps, fap_displacements
from faceanim.target import Target, target_from_fdp, target_from_json

TABLE = fap_table()


def stream_of(frames: dict, count=3):
    values = np.zeros((count, FAP_COUNT))
    mask = np.zeros((count, FAP_COUNT), bool)
    for (t, fap), value in frames.items():
        j = TABLE.number(fap) - 1
        values[t, j], mask[t, j] = value, True
    return FapStream(values, mask, 25.0)


def face_grid():
    """A 9x9 grid carrying the feature points FAPU needs and a few more."""
    mesh = grid_mesh(9, size=8.0)
    at = {"2.1": 4, "2.3": 13, "2.2": 22, "8.3": 24, "8.4": 20, "9.15": 40, "3.1": 61, "3.3": 52, "3.2": 55,
          "3.4": 46, "3.5": 60, "3.6": 56}
    return Target(mesh, at, Fapu(irisd0=1.0, es0=4.0, ens0=2.0, mns0=2.0, mw0=4.0))


def test_known_displacements_and_the_jaw_carrying_the_lower_lip():
    target = face_grid()
    names, d = fap_displacements(stream_of({(1, "open_jaw"): 512, (1, "stretch_l_cornerlip_o"): 256}), target)
    moved = dict(zip(names, d[1], strict=True))
    # open_jaw 512 = half of MNS0 (2): the chin falls exactly 1, turning about the hinge, so also backwards
    assert moved["2.1"][1] == pytest.approx(-1.0) and moved["2.1"][2] < 0 and moved["2.1"][0] == 0
    # the lower lip rides with the jaw: down about as far (same turn, another arm) and backwards too
    assert moved["2.3"][1] == pytest.approx(-1.0, rel=0.2) and moved["2.3"][2] < 0
    np.testing.assert_allclose(moved["8.3"], [1.0, 0, 0])    # 256/1024 of MW0 = 4 -> 1 to the face's left
    assert np.abs(d[0]).max() == 0


def test_absent_faps_keep_their_last_value():
    s = stream_of({(0, "open_jaw"): 100, (2, "open_jaw"): 300}, count=4)
    np.testing.assert_array_equal(held(s)[:, 2], [100, 100, 300, 300])


def test_animation_moves_the_points_exactly_and_head_yaw_turns_left():
    target = face_grid()
    s = stream_of({(1, "open_jaw"): 512, (2, "head_yaw"): 10000})
    still = animate_faps(s, target)
    assert (still.positions[1, 4] - target.mesh.vertices[4])[1] == pytest.approx(-1.0)  # the chin's FAP drop
    np.testing.assert_allclose(still.positions[1, 60], target.mesh.vertices[60], atol=1e-9)  # an unmoved point
    turned = animate_faps(s, target, head_motion=True, pivot=np.zeros(3))
    yaw = np.array([[np.cos(0.1), 0, np.sin(0.1)], [0, 1, 0], [-np.sin(0.1), 0, np.cos(0.1)]])
    np.testing.assert_allclose(turned.positions[2], still.positions[2] @ yaw.T, atol=1e-9)
    assert turned.positions[2, 8, 2] < still.positions[2, 8, 2]  # the face's left side (+x) turns away (-z)


def test_joy_fap_on_the_ict_face_raises_and_widens_the_lip_corners():
    shared("ict_facekit", "ict_deltas_full.npz")
    from ict_scenario import load_ict

    from faceanim.mpeg4.multipie import MULTIPIE68_OF_FEATURE_POINT

    model = load_ict()
    mesh = model.mesh(model.neutral)
    target = Target.from_points(mesh, {n: int(model.landmarks[i]) for n, i in MULTIPIE68_OF_FEATURE_POINT.items()})
    stream = read_fap(shared("xface", "Faps", "joy.fap"))
    animation = animate_faps(stream, target)
    for corner, side in (("8.3", "l"), ("8.4", "r")):
        raised = stream.values[:, TABLE.number(f"raise_{side}_cornerlip_o") - 1] > 50
        widened = stream.values[:, TABLE.number(f"stretch_{side}_cornerlip_o") - 1] > 50
        d = animation.positions[:, target.points[corner]] - mesh.vertices[target.points[corner]]
        outward = 1 if side == "l" else -1
        assert raised.sum() > 10 and (d[raised, 1] > 0.05).all()
        assert widened.sum() > 10 and (outward * d[widened, 0] > 0.05).all()


def test_target_files(tmp_path):
    mesh = grid_mesh(9, size=8.0)
    points = {"2.1": 4, "2.2": 22, "8.3": 24, "8.4": 20, "9.15": 40, "3.1": 61, "3.3": 52, "3.2": 55, "3.4": 46,
              "3.7": 62, "3.11": 59, "3.8": 57, "3.12": 54}
    (tmp_path / "t.json").write_text(json.dumps(points))
    target = target_from_json(mesh, tmp_path / "t.json")
    assert target.points["8.3"] == 24 and target.fapu.mw0 == pytest.approx(4.0)  # pupils from eye corners
    (tmp_path / "bad.json").write_text(json.dumps({"8.3": 999}))
    with pytest.raises(InputError, match="bad.json: point 8.3 names vertex 999, but the mesh has vertices 0-80"):
        target_from_json(mesh, tmp_path / "bad.json")
    (tmp_path / "name.json").write_text(json.dumps({"lip": 3}))
    with pytest.raises(FileFormatError, match="unknown feature point 'lip'"):
        target_from_json(mesh, tmp_path / "name.json")
    (tmp_path / "few.json").write_text(json.dumps({"8.3": 3}))
    with pytest.raises(InputError, match="few.json: cannot measure FAPU: FAPU needs feature points 2.2"):
        target_from_json(mesh, tmp_path / "few.json")
    (tmp_path / "broken.json").write_text('{"8.3": 3,\n')
    with pytest.raises(FileFormatError, match="broken.json:2: is not valid JSON"):
        target_from_json(mesh, tmp_path / "broken.json")


def test_xface_fdp():
    path = shared("xface", "Faces", "alice", "alice.fdp")
    big = Mesh(np.random.default_rng(0).normal(size=(6000, 3)), [[0, 1, 2]])
    target = target_from_fdp(big, path)
    assert len(target.points) == 32 and target.points["2.1"] == 2395  # the face submesh; teeth and eyes left out
    assert (target.fapu.irisd0, target.fapu.es0, target.fapu.mns0) == (16, 69, 30)
    with pytest.raises(InputError, match=r"alice.fdp: point 2.1 names vertex 2395, but the mesh has vertices 0-99"):
        target_from_fdp(Mesh(np.zeros((100, 3)) + np.arange(100)[:, None], [[0, 1, 2]]), path)


def test_automatic_placement_on_the_ict_face():
    shared("ict_facekit", "ict_deltas_full.npz")
    pytest.importorskip("moderngl", reason="placement renders the mesh: needs faceanim[render]")
    pytest.importorskip("mediapipe", reason="placement tracks the render: needs faceanim[capture]")
    from ict_scenario import load_ict

    from faceanim.retarget.placement import auto_target

    model = load_ict()
    mesh = model.mesh(model.neutral)
    target = auto_target(mesh)
    truth = model.neutral[model.landmarks]
    # the points land on the face they name (nose tip on the nose tip, mouth corners at the corners)
    for point, landmark in (("9.3", 30), ("8.3", 54), ("8.4", 48), ("3.7", 45), ("3.12", 36)):
        assert np.linalg.norm(mesh.vertices[target.points[point]] - truth[landmark]) < 0.8, point
    assert mesh.vertices[target.points["8.3"], 0] > 0 > mesh.vertices[target.points["8.4"], 0]  # face's own left
    # the mouth is closed: the inner-lip middles fall on one line, yet each lands on its own lip, at ICT's
    # own inner-lip landmark vertices (62 upper, 66 lower): on them with FaceMesh's points; the Face
    # Landmarker's upper one lands on the next vertex up the upper lip's inner face, 0.29 cm away
    for point, landmark in (("2.2", 62), ("2.3", 66)):
        assert np.linalg.norm(mesh.vertices[target.points[point]] - truth[landmark]) < 0.3, point
    assert mesh.vertices[target.points["2.2"], 1] > mesh.vertices[target.points["2.3"], 1]  # upper above lower
    normals = mesh.vertex_normals
    assert normals[target.points["2.6"], 1] < 0 < normals[target.points["2.8"], 1]  # upper faces down, lower up
    # the pupils sit on the eye's own parts (ICT's eye films and eyeballs, vertices 21451 on), not on the lids
    assert all(target.points[p] >= 21451 for p in ("3.5", "3.6"))
    # the outer eye corners hide behind the lashes: cast through the skin alone, both land on the lid's
    # corner, not on the upper lid in front of it
    for point, landmark in (("3.7", 45), ("3.12", 36)):
        assert np.linalg.norm(mesh.vertices[target.points[point]] - truth[landmark]) < 0.35, point
    assert 4.0 < target.fapu.mw0 < 6.5 and 5.0 < target.fapu.es0 < 7.5


def test_automatic_placement_refuses_a_mesh_without_a_face():
    pytest.importorskip("moderngl", reason="placement renders the mesh: needs faceanim[render]")
    pytest.importorskip("mediapipe", reason="placement tracks the render: needs faceanim[capture]")
    from test_project import bumpy_sphere

    from faceanim.retarget.placement import auto_target

    with pytest.raises(InputError, match="automatic placement found no face on the rendered mesh"):
        auto_target(bumpy_sphere())


def test_placement_refuses_an_asymmetric_result():
    from faceanim.capture.metric import canonical_face
    from faceanim.retarget.placement import _check_symmetry

    points = canonical_face().vertices.copy()
    _check_symmetry(points)  # MediaPipe's own face is symmetric: accepted
    points[[263, 362, 291, 300, 280, 386, 374]] += [2.5, 0, 0]  # the face's left side pushed out
    with pytest.raises(InputError, match="automatic placement found an asymmetric face"):
        _check_symmetry(points)


def test_placement_accepts_an_outline_point_cast_deep():
    """The outline by the ear lies along the line of sight: a pixel's slip casts it centimetres back (and
    some millimetres out), as on ICT identities whose eyes and lips were placed well; that is no asymmetry."""
    from faceanim.capture.metric import canonical_face
    from faceanim.retarget.placement import _check_symmetry

    points = canonical_face().vertices.copy()
    points[454] += [0.6, 0.0, -3.5]
    _check_symmetry(points)


def test_a_degenerate_non_manifold_target_still_animates():
    """A sliver triangle (zero area), a vertex only in it, and a fin triangle given twice (three
    triangles on one edge): the surface interpolation stays finite and the jaw still opens."""
    base = grid_mesh(9, size=8.0)
    points = {"2.1": 4, "2.2": 22, "8.3": 24, "8.4": 20, "9.15": 40, "3.1": 61, "3.3": 52, "3.2": 55, "3.4": 46,
              "3.7": 62, "3.11": 59, "3.8": 57, "3.12": 54}
    v = np.vstack([base.vertices, 0.5 * (base.vertices[0] + base.vertices[1]), base.vertices[10] + [0, 0, 1]])
    t = np.vstack([base.triangles, [[0, 1, 81], [0, 10, 82], [0, 10, 82]]])
    target = Target.from_points(Mesh(v, t), points)
    values = np.zeros((3, 68))
    values[:, 2] = [0, 300, 600]  # open_jaw
    mask = np.zeros((3, 68), bool)
    mask[:, 2] = True
    animation = animate_faps(FapStream(values, mask, 25.0), target)
    assert np.isfinite(animation.positions).all()
    drop = animation.positions[:, 4, 1] - v[4, 1]  # the chin (2.1)
    assert drop[0] == pytest.approx(0, abs=1e-9) and drop[2] < drop[1] < 0


def test_outline_points_take_the_depth_mediapipe_predicts():
    from faceanim.render.camera import front_camera
    from faceanim.retarget.placement import _surface_points

    camera = front_camera(np.array([[-1.0, -1, 0], [1, 1, 0]]), 64, 64)
    rng = np.random.default_rng(0)
    pixels = rng.uniform(8, 56, size=(40, 2))
    relative = rng.uniform(-2, 2, size=40)
    truth = 10.0 + 0.25 * relative  # a face whose depths MediaPipe's z predicts exactly
    depth = np.full((64, 64), np.inf)
    cols, rows = np.round(pixels[:, 0] - 0.5).astype(int), np.round(pixels[:, 1] - 0.5).astype(int)
    depth[rows, cols] = truth
    depth[rows[0], cols[0]] = np.inf  # off the silhouette: nothing behind the pixel
    depth[rows[1], cols[1]] = 25.0  # past the outline: the ear or the neck behind it
    points = _surface_points(pixels, relative, depth, camera)
    np.testing.assert_allclose(points, camera.unproject(pixels, truth), atol=1e-9)


def test_a_jaw_turned_about_its_hinge_encodes_without_thrust_and_decodes_back():
    target = face_grid()
    at = {n: target.mesh.vertices[i] for n, i in target.points.items()}
    # by the decoder's rule the hinge is level with 9.15 and 1.2 MW0 behind the chin (no jaw corners here)
    hinge = np.array([at["2.1"][0], at["9.15"][1], at["2.1"][2] - 1.2 * target.fapu.mw0])
    names = tuple(target.points)
    neutral = np.array([at[n] for n in names])
    d = np.zeros((3, len(names), 3))
    for t, turn in ((1, 0.15), (2, 0.6)):  # a small opening, and one wider than an exact rotation reaches
        for name in ("2.1", "2.3"):
            r = at[name] - hinge
            d[t, names.index(name)] = turn * np.array([0, -r[2], r[1]])  # down and back, first order
    motion = Motion(names, neutral, d, np.tile(np.eye(4), (3, 1, 1)), 25.0, target.fapu)
    stream = motion_to_faps(motion)
    drops = -d[1:, names.index("2.1"), 1]
    np.testing.assert_allclose(stream.values[1:, TABLE.number("open_jaw") - 1], drops / target.fapu.mns0 * 1024)
    # the swing that open_jaw implies is the whole of the chin's backward move and of the lip's motion
    np.testing.assert_allclose(stream.values[1:, TABLE.number("thrust_jaw") - 1], 0, atol=1e-6)
    np.testing.assert_allclose(stream.values[1:, TABLE.number("raise_b_midlip") - 1], 0, atol=1e-6)
    decoded_names, decoded = fap_displacements(stream, target)
    for name in ("2.1", "2.3"):
        np.testing.assert_allclose(decoded[:, decoded_names.index(name)], d[:, names.index(name)], atol=1e-9)


def test_the_jaw_swings_from_behind_the_chin_even_when_its_corners_are_placed_in_front():
    target = face_grid()
    points = dict(target.points)
    points["2.13"] = points["2.14"] = points["2.2"]  # on a flat grid: level with the chin, not behind it
    odd = Target(target.mesh, points, target.fapu)
    names, d = fap_displacements(stream_of({(1, "open_jaw"): 1024}), odd)
    chin = d[1, names.index("2.1")]
    assert chin[1] == pytest.approx(-target.fapu.mns0) and chin[2] < 0  # down by the FAP, and backwards


@pytest.mark.parametrize("vertices, says", [
    ("v 0 0 0\nv 0 0 0\nv 0 0 0\n", "span 0 in one direction and 0 across it"),  # a point
    ("v 0 0 0\nv 1 0 0\nv 2 0 0\n", "span 2 in one direction and 0 across it"),  # a line
    ("v 0 0 0\nv 1e308 0 0\nv 0 1e308 0\n", "coordinates as large as 1e\\+308"),  # squares overflow
])
def test_a_target_no_face_can_be_is_refused_naming_its_file(tmp_path, capsys, vertices, says):
    """Such meshes used to reach the placement's camera: "world_to_camera must be finite", naming nothing."""
    from faceanim.cli import main

    mesh = tmp_path / "odd.obj"
    mesh.write_text(vertices + "f 1 2 3\n")
    fap = tmp_path / "f.fap"
    mask = np.zeros((2, FAP_COUNT), dtype=bool)
    mask[:, 2] = True
    from faceanim.mpeg4.fapfile import write_fap

    write_fap(fap, FapStream(np.zeros((2, FAP_COUNT)), mask, 25.0))
    assert main(["decode", str(fap), "--target", str(mesh), "-o", str(tmp_path / "o.glb")]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and re.search(f"{re.escape(str(mesh))}: .*{says}", error), error
    assert not (tmp_path / "o.glb").exists()
