"""`faceanim express` and `faceanim aus` end to end: files other tools open, and one-line errors."""

import csv

import numpy as np
import pytest
from conftest import khronos_report, shared

from faceanim.cli import main
from faceanim.geometry import read_mesh
from faceanim.geometry.meshio import glb_extras, read_glb_json
from faceanim.mpeg4 import fap_table
from faceanim.mpeg4.fapfile import read_fap
from faceanim.portrait import avatar_target


@pytest.fixture(scope="module")
def avatar():
    return avatar_target()


def test_express_glb_is_a_still_with_every_au_as_a_slider(tmp_path, avatar, capsys):
    out = tmp_path / "joy.glb"
    assert main(["express", "--emotion", "joy", "-o", str(out)]) == 0
    assert "AUs 6:0.80,12:1.00,25:0.50" in capsys.readouterr().out
    doc = read_glb_json(out)
    mesh = doc["meshes"][0]
    names = mesh["extras"]["targetNames"]
    assert names[0] == "expression" and {"AU1", "AU12", "AU26", "AU30L", "AU46R"} <= set(names)
    assert mesh["weights"][0] == 1.0 and not any(mesh["weights"][1:])  # shows the expression; sliders at rest
    extras = glb_extras(out)
    assert extras["recipe"] == "6:0.80,12:1.00,25:0.50" and int(extras["au_faps"]["AU12"]["12"]) > 0
    report = khronos_report(out)
    assert report["errors"] == 0 and report["warnings"] == 0, report["messages"]


def test_express_obj_and_fap_move_the_lip_corners_up(tmp_path, avatar):
    assert main(["express", "--au", "12:1.0", "-o", str(tmp_path / "smile.obj")]) == 0
    smiled = read_mesh(tmp_path / "smile.obj")
    corner = avatar.points["8.3"]
    assert len(smiled.vertices) == len(avatar.mesh.vertices)
    assert smiled.vertices[corner, 1] - avatar.mesh.vertices[corner, 1] > 0.2  # cm, up
    assert main(["express", "--au", "12:1.0,26:0.5", "--frames", "12", "-o", str(tmp_path / "smile.fap")]) == 0
    stream = read_fap(tmp_path / "smile.fap")
    table = fap_table()
    corner_raise = stream.values[:, table.number("raise_l_cornerlip") - 1]
    jaw = stream.values[:, table.number("open_jaw") - 1]
    assert len(stream) == 12 and corner_raise[0] == 0 and corner_raise[-1] == 0 and corner_raise.max() > 0
    assert jaw.argmax() in range(4, 8) and not stream.out_of_range().any()


def test_express_animation_runs_onset_apex_offset(tmp_path):
    out = tmp_path / "brows.glb"
    assert main(["express", "--au", "1:1,2:1", "--frames", "15", "--fps", "30", "-o", str(out)]) == 0
    doc = read_glb_json(out)
    sampler = doc["animations"][0]["samplers"][0]
    times = doc["accessors"][sampler["input"]]
    assert times["count"] == 15 and abs(times["max"][0] - 14 / 30) < 1e-6
    assert "AU1" in doc["meshes"][0]["extras"]["targetNames"]
    report = khronos_report(out)
    assert report["errors"] == 0 and report["warnings"] == 0, report["messages"]


def test_express_generic_route_reaches_the_target(tmp_path, avatar):
    assert main(["express", "--au", "12:1.0", "--route", "generic", "-o", str(tmp_path / "g.obj")]) == 0
    moved = read_mesh(tmp_path / "g.obj").vertices - avatar.mesh.vertices
    corner = avatar.points["8.3"]
    assert moved[corner, 1] > 0.2 and moved[corner, 0] > 0  # up and outward, on the face's left


@pytest.mark.parametrize("args, message", [
    (["--au", "13:1"], "unknown action unit '13'; valid: 1(L/R)"),
    (["--au", "12:3"], "intensity 3 is outside [0, 2]"),
    (["--emotion", "glee"], "unknown emotion 'glee'; valid: joy"),
    (["--au", "12:1", "--intensity", "2"], "--intensity scales an --emotion"),
    (["--au", "12:1", "--frames", "10"], "an OBJ holds one still face"),
    (["--au", "12:1", "--frames", "1"], "--frames must be a whole number from 3 to 10000, got 1"),
    (["--au", "12:1", "--fps", "0"], "--fps must be a number from 1 to 1000, got 0.0"),
])
def test_express_bad_input_is_one_line_and_writes_nothing(tmp_path, capsys, args, message):
    out = tmp_path / "x.obj"
    assert main(["express", *args, "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_express_refuses_unknown_output_kinds_and_warns_on_exaggeration(tmp_path, capsys):
    assert main(["express", "--au", "12:1", "-o", str(tmp_path / "x.png")]) == 2
    assert "written as .obj, .glb, .fap" in capsys.readouterr().err
    with pytest.warns(UserWarning, match="--intensity for surprise: intensity 1.4 is above 1"):
        assert main(["express", "--emotion", "surprise", "--intensity", "1.4", "-o", str(tmp_path / "s.fap")]) == 0


def test_express_and_aus_refuse_outputs_they_cannot_write(tmp_path, capsys):
    assert main(["express", "--au", "12:1", "-o", str(tmp_path / "missing" / "x.glb")]) == 2
    assert "the folder" in capsys.readouterr().err
    assert main(["aus", "any.mp4", "-o", str(tmp_path / "aus.txt")]) == 2
    assert "-o " + str(tmp_path / "aus.txt") + ": this output is written as .csv" in capsys.readouterr().err
    assert main(["aus", "any.mp4", "-o", str(tmp_path / "missing" / "aus.csv")]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_au_csv_has_openface_columns_and_scale(tmp_path):
    from faceanim.export import write_au_csv

    values = np.array([[0.2, 1.0], [0.5, 0.0], [np.nan, np.nan], [1.7, 0.1]])
    pose = [[0.1, -0.2, 0.0]] * 4
    header = write_au_csv(tmp_path / "a.csv", (1, 12), values, [0.0, 0.04, 0.08, 0.121],
                          success=[True, True, False, True], pose=pose)
    assert header == ["frame", "face_id", "timestamp", "confidence", "success", "pose_Rx", "pose_Ry", "pose_Rz",
                      "AU01_r", "AU12_r", "AU01_c", "AU12_c"]
    rows = (tmp_path / "a.csv").read_text().splitlines()
    assert rows[0] == ", ".join(header)  # OpenFace separates its cells with ", "
    assert rows[1:] == ["1, 0, 0.000, 1.00, 1, 0.100, -0.200, 0.000, 1.00, 5.00, 1, 1",
                        "2, 0, 0.040, 1.00, 1, 0.100, -0.200, 0.000, 2.50, 0.00, 1, 0",
                        "3, 0, 0.080, 0.00, 0, 0.000, 0.000, 0.000, 0.00, 0.00, 0, 0",
                        "4, 0, 0.121, 1.00, 1, 0.100, -0.200, 0.000, 5.00, 0.50, 1, 0"]  # 1.7 reads 5, never more
    with pytest.raises(ValueError, match="must have 4 rows"):
        write_au_csv(tmp_path / "b.csv", (1, 12), values, [0.0, 0.04])


def _read_aus(path):
    rows = list(csv.reader(open(path), skipinitialspace=True))
    header = rows[0]
    return header, np.array([[float(x) for x in row] for row in rows[1:]])


def test_aus_reads_mouth_opening_on_d18(tmp_path):
    """d18, 'mouth wide open': AU26 + AU27 follow the gap between the inner lips."""
    pytest.importorskip("mediapipe", reason="capture needs faceanim[capture]")
    video = shared("videos", "d18.mp4")
    out = tmp_path / "d18.csv"
    assert main(["aus", str(video), "-o", str(out)]) == 0
    header, values = _read_aus(out)
    assert header[:9] == ["frame", "face_id", "timestamp", "confidence", "success", "pose_Rx", "pose_Ry", "pose_Rz",
                          "AU01_r"] and "AU45_r" in header and "AU45_c" in header
    assert len(values) == 216 and values[:, 4].all()
    r = values[:, [i for i, name in enumerate(header) if name.endswith("_r") and name.startswith("AU")]]
    assert r.min() >= 0 and r.max() <= 5.0
    c = values[:, [i for i, name in enumerate(header) if name.endswith("_c")]]
    np.testing.assert_array_equal(c, r >= 1.0)
    assert np.abs(values[:, 5:8]).max() < 1.0  # head angles in radians, a face towards the camera
    opening = values[:, header.index("AU26_r")] + values[:, header.index("AU27_r")]
    from faceanim.pipeline import capture_motion

    motion = capture_motion(video)
    upper, lower = motion.index(["2.2", "2.3"])
    gap = (motion.displacements[:, upper, 1] - motion.displacements[:, lower, 1])
    assert np.corrcoef(opening, gap)[0, 1] > 0.8
    assert opening.max() > 2.0 and opening[:10].max() < 0.5


def test_aus_reads_the_smile_on_d0(tmp_path):
    """d0, smiles: from the first frames at rest (``--neutral 0:5``; the automatic neutral picks the
    long smile itself), AU12 rises from near 0 to well over FACS B."""
    pytest.importorskip("mediapipe", reason="capture needs faceanim[capture]")
    video = shared("videos", "d0.mp4")
    out = tmp_path / "d0.csv"
    assert main(["aus", str(video), "--neutral", "0:5", "-o", str(out)]) == 0
    header, values = _read_aus(out)
    smile = values[:, header.index("AU12_r")]
    assert smile[:10].max() < 0.5 and np.median(smile[30:60]) > 1.5
    assert np.median(smile[30:60]) > np.median(values[30:60, header.index("AU15_r")]) + 1.0


def test_generic_route_onto_a_whole_head():
    """ICT-FaceKit's whole head (scalp, neck, ears: most of it far from the face-only generic face) takes
    the generic route: the registration judges its fit from the generic face lying on the head, and AU 12
    lifts the mouth's corners."""
    shared("ict_facekit", "ict_deltas_full.npz")
    from ict_scenario import load_ict

    from faceanim.expressions import generic_carrier
    from faceanim.mpeg4.multipie import MULTIPIE68_OF_FEATURE_POINT
    from faceanim.synth.expression import expression_field
    from faceanim.target import Target

    model = load_ict()
    head = Target.from_points(model.mesh(model.neutral),
                              {name: int(model.landmarks[i]) for name, i in MULTIPIE68_OF_FEATURE_POINT.items()})
    generic, carry = generic_carrier(head)
    assert carry.registration.fit < 0.01 * np.ptp(head.mesh.vertices[:, 0])
    moved = carry(expression_field(generic, {"12": 1.0}))
    left, right = head.points["8.3"], head.points["8.4"]
    up = 1 if head.mesh.vertices[head.points["2.1"], 1] < head.mesh.vertices[head.points["4.1"], 1] else -1
    assert up * moved[left, 1] > 0 and up * moved[right, 1] > 0
