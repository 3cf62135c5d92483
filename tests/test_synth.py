"""Vector muscles, FACS action units, emotions and the AU fitter, on the generic face (package data)
and, where the shared data is present, on ICT-FaceKit's FACS shapes."""

import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import shared

from faceanim.errors import InputError
from faceanim.expressions import au_fap_table, envelope, expression_motion
from faceanim.generic import generic_target
from faceanim.motion import motion_to_faps
from faceanim.mpeg4 import fap_table
from faceanim.synth import MuscleFace, expression_field, synthesise
from faceanim.synth.emotions import EMOTIONS, emotion_recipe
from faceanim.synth.expression import crossings
from faceanim.synth.facs import ACTION_UNITS, MOVERS, muscle_activations, parse_recipe, recipe_text
from faceanim.synth.fitting import AuFitter, bilateral
from faceanim.synth.muscles import LinearMuscle, Sphincter
from faceanim.target import Target

REQUIRED = (1, 2, 4, 5, 6, 7, 9, 10, 12, 14, 15, 16, 17, 18, 20, 22, 23, 24, 25, 26, 27, 43, 45, 46)


@pytest.fixture(scope="module")
def face():
    return MuscleFace(generic_target())


def _mirror_index(vertices):
    """Index of each vertex's mirror image (x -> -x) on a symmetric mesh."""
    from scipy.spatial import cKDTree

    mirrored = vertices * [-1, 1, 1]
    distance, index = cKDTree(vertices).query(mirrored)
    return index, distance


def test_every_required_action_unit_exists_and_moves_the_face(face):
    for number in REQUIRED:
        au = ACTION_UNITS[number]
        code = f"{number}L" if au.needs_side else str(number)
        field = expression_field(face, {code: 1.0})
        assert np.linalg.norm(field, axis=1).max() > 0.05, f"AU{number} does not move the face"


def test_linear_muscle_pulls_toward_its_origin_inside_its_zone_only(face):
    muscle = LinearMuscle((("3.7", 1.0),), (("8.3", 1.0),), 0.2, origin_offset=(0.1, -0.5, -0.3), zone=40, end=1.5)
    field = muscle.displacement(face, 1.0, "L")
    origin, insertion = muscle.points(face, "L")
    v = face.mesh.vertices
    length = np.linalg.norm(insertion - origin)
    r = v - origin
    D = np.linalg.norm(r, axis=1)
    angle = np.degrees(np.arccos(np.clip(r @ (insertion - origin) / (D * length), -1, 1)))
    moving = np.linalg.norm(field, axis=1) > 1e-9
    assert moving.any()
    assert (angle[moving] < 40).all() and (D[moving] < 1.5 * length).all()  # nothing outside the zone moves
    assert ((field[moving] * -r[moving]).sum(axis=1) > 0).all()            # everything moves toward the origin
    assert np.allclose(muscle.displacement(face, 0.5, "L"), 0.5 * field)   # linear in contraction


def test_sphincter_draws_inside_its_ellipsoid_toward_the_centre_and_leaves_the_outside(face):
    ring = Sphincter((("8.1", 0.5), ("8.2", 0.5)), (0.5, 0.3, 0.3), gain_x=0.3, gain_y=0.3, inner=0.5)
    field = ring.displacement(face, 1.0, "L")
    centre = 0.5 * (face.point("8.1") + face.point("8.2"))
    q = face.local(face.mesh.vertices - centre)
    rho = np.linalg.norm(q / (np.array([0.5, 0.3, 0.3]) * face.unit), axis=1)
    assert np.abs(field[rho >= 1.0]).max() == 0
    inside = (rho < 0.9) & (np.linalg.norm(q[:, :2], axis=1) > 0.05)
    inward = (face.local(field[inside])[:, :2] * -q[inside, :2]).sum(axis=1)
    assert (inward > 0).all()


def test_bilateral_action_units_are_mirror_symmetric_and_sides_are_mirror_images(face):
    mirror, distance = _mirror_index(face.mesh.vertices)
    assert distance.max() < 1e-3  # the canonical face is symmetric
    flip = np.array([-1.0, 1.0, 1.0])
    for code in ("1", "4", "12", "15", "26", "45", "63"):
        field = expression_field(face, {code: 1.0})
        assert np.abs(field[mirror] * flip - field).max() < 1e-6, code
    left, right = (expression_field(face, {c: 1.0}) for c in ("12L", "12R"))
    assert np.allclose(left[mirror] * flip, right, atol=1e-9)
    assert np.allclose(left + right, expression_field(face, {"12": 1.0}), atol=1e-9)
    gaze_left, gaze_right = (expression_field(face, {c: 1.0}) for c in ("61", "62"))
    assert np.abs(gaze_left).max() > 0 and np.allclose(gaze_left[mirror] * flip, gaze_right, atol=1e-9)


def test_gaze_turns_the_avatars_eyes_and_nothing_else_off_the_skin():
    from faceanim.portrait import avatar_target

    target = avatar_target()
    eyes = MuscleFace(target)
    for code, axis in (("61", 0), ("63", 1)):
        field = expression_field(eyes, {code: 1.0})
        for pupil in ("3.5", "3.6"):
            assert eyes.local(field[target.points[pupil]])[axis] > 0.3  # cm: toward the face's left / up
    balls = np.concatenate([eyes.eyeball_vertices(s) for s in ("L", "R")])
    teeth = np.setdiff1d(np.flatnonzero(~eyes.skin), balls)
    assert len(teeth) and np.abs(expression_field(eyes, {"61": 1.0})[teeth]).max() == 0


def test_jaw_turns_the_chin_about_its_hinge_and_keeps_the_upper_face_still(face):
    field = expression_field(face, {"26": 1.0})
    chin, eye, brow, upper_lip = (face.target.points[n] for n in ("2.1", "3.7", "4.3", "8.1"))
    mover = MOVERS["jaw_open"][0]
    hinge = mover.hinge(face, "L")
    v = face.mesh.vertices
    assert np.isclose(np.linalg.norm(v[chin] + field[chin] - hinge), np.linalg.norm(v[chin] - hinge))
    drop = face.local(field[chin])
    assert drop[1] < -0.3 and drop[2] < 0  # cm: the chin goes down and back
    assert np.abs(field[[eye, brow]]).max() == 0
    assert np.linalg.norm(field[upper_lip]) < 0.05 * np.linalg.norm(field[chin])


def test_blink_closes_the_lid_exactly_and_exaggeration_never_crosses(face):
    field = expression_field(face, {"45": 1.0})
    up = face.axes[1]
    for upper, lower in (("3.1", "3.3"), ("3.2", "3.4")):
        i, j = face.target.points[upper], face.target.points[lower]
        gap = (face.mesh.vertices[i] + field[i] - face.mesh.vertices[j] - field[j]) @ up
        assert abs(gap) < 0.02 * face.unit  # the lid margins meet
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for number, au in ACTION_UNITS.items():
            code = f"{number}L" if au.needs_side else str(number)
            made, _ = synthesise(face, {code: 2.0})
            assert crossings(face, made) == [], f"AU{code} at 2 pushes a lid or lip through its partner"
        for name in EMOTIONS:
            made, _ = synthesise(face, emotion_recipe(name, 2.0))
            assert crossings(face, made) == [], name
    raw = expression_field(face, {"45": 2.0})
    assert crossings(face, raw)  # the guard has work to do: without it the lid would cross
    with pytest.warns(UserWarning, match="exaggeration limited"):
        _, made = synthesise(face, {"45": 2.0})
    assert 1.0 <= made["45"] < 2.0


def test_expression_motion_speaks_mpeg4(face):
    """An AU's FAPs have the signs MPEG-4 gives its movement (faps.csv directions)."""
    table = fap_table()
    codes = ("12", "26", "1", "45", "15")
    fields = np.stack([expression_field(face, {c: 1.0}) for c in codes])
    stream = motion_to_faps(expression_motion(face, fields, 25.0))

    def fap(frame, name):
        return stream.values[frame, table.number(name) - 1]

    assert fap(0, "raise_l_cornerlip") > 0 and fap(0, "raise_r_cornerlip") > 0 and fap(0, "stretch_l_cornerlip") > 0
    assert fap(1, "open_jaw") > 0
    assert fap(2, "raise_l_i_eyebrow") > 0 and fap(2, "raise_r_i_eyebrow") > 0
    assert fap(3, "close_t_l_eyelid") > 0 and fap(3, "close_t_r_eyelid") > 0
    assert fap(4, "raise_l_cornerlip") < 0
    faps = au_fap_table(face, codes, fields)
    assert int(faps["AU26"]["3"]) > 0 and "48" not in faps["AU12"]


def test_recipes_parse_letters_sides_and_reject_bad_input():
    assert parse_recipe("AU06:0.8, 12L:C,12L:0.1") == {"6": 0.8, "12L": 0.6}
    assert parse_recipe({"26": 0.5}) == {"26": 0.5}
    assert recipe_text({"6": 0.8, "12": 1.0}) == "6:0.80,12:1.00"
    with pytest.raises(InputError, match=r"unknown action unit '13'; valid: 1\(L/R\), 2"):
        parse_recipe("13:1")
    with pytest.raises(InputError, match="outside"):
        parse_recipe("12:2.5")
    with pytest.raises(InputError, match="outside"):
        parse_recipe("12:-0.1")
    with pytest.warns(UserWarning, match="above 1"):
        parse_recipe("12:1.5")
    with pytest.raises(InputError, match="needs a side: 30L or 30R"):
        parse_recipe("30:1")
    with pytest.raises(InputError, match="no left/right variants"):
        parse_recipe("17L:1")
    with pytest.raises(InputError, match="neither a number nor a FACS letter"):
        parse_recipe("12:high")
    with pytest.raises(InputError, match="recipe is empty"):
        parse_recipe(" , ")
    activations = muscle_activations({"12L": 0.5, "6": 1.0})
    assert activations[("zygomatic_major", "L")] == 0.5 and ("zygomatic_major", "R") not in activations
    assert activations[("oculi_orbital", "L")] == activations[("oculi_orbital", "R")] == 1.0


def test_emotions_have_sources_and_scale():
    assert set(EMOTIONS) == {"joy", "sadness", "anger", "fear", "disgust", "surprise"}
    for emotion in EMOTIONS.values():
        assert "EMFACS" in emotion.source and parse_recipe(emotion.recipe) == emotion.recipe
    assert emotion_recipe("JOY", 0.5) == {"6": 0.4, "12": 0.5, "25": 0.25}
    with pytest.raises(InputError, match="unknown emotion 'glee'; valid: joy, sadness"):
        emotion_recipe("glee")
    with pytest.raises(InputError, match="outside"):
        emotion_recipe("joy", 3)


def test_a_target_without_the_needed_feature_points_names_them():
    target = generic_target()
    points = {n: i for n, i in target.points.items() if n not in ("8.3", "2.1")}
    with pytest.raises(InputError, match="lacks feature points 8.3, 2.1"):
        MuscleFace(Target(target.mesh, points, target.fapu))
    points = {n: i for n, i in target.points.items() if n not in ("9.1",)}
    face = MuscleFace(Target(target.mesh, points, target.fapu))
    with pytest.raises(InputError, match="lacks feature point 9.1, which a muscle needs"):
        expression_field(face, {"9": 1.0})


def test_fitter_reads_back_single_action_units_and_their_rise(face):
    names = list(face.target.points)
    fitter = AuFitter(face, names)
    ids = face.target.ids(names)
    number_of = np.array([int(c.rstrip("LR")) for c in fitter.codes])
    for code in ("1", "2", "4", "9", "12", "15", "17", "20", "45"):
        x = fitter(np.stack([expression_field(face, {code: w})[ids] for w in (0.3, 0.8)]))
        assert (number_of[x.argmax(axis=1)] == int(code)).all(), code
        named = x[:, number_of == int(code)].max(axis=1)
        assert named[1] > named[0] > 0, code
    numbers, table = bilateral(fitter.codes, x)
    assert table.shape == (2, len(numbers)) and 45 in numbers and 46 not in numbers


def test_fitter_reads_a_streamed_motion_chunk_by_chunk_as_it_reads_the_whole(face):
    """read_motion reads a long motion a chunk at a time (aus held every frame's points twice): the
    result is the fit of each frame, NaN where there is no face."""
    from faceanim.motion import CHUNK, Motion

    names = list(face.target.points)
    fitter = AuFitter(face, names)
    ids = face.target.ids(names)
    T = CHUNK + 3  # two chunks
    weights = np.linspace(0, 1, T)
    d = np.stack([expression_field(face, {"12": 1.0})[ids]] * T) * weights[:, None, None]
    valid = np.ones(T, bool)
    valid[[1, CHUNK + 1]] = False
    neutral = face.target.mesh.vertices[ids]
    pose = np.tile(np.eye(4), (T, 1, 1))
    held = Motion(names, neutral, np.where(valid[:, None, None], d, np.nan), pose, 25.0, face.target.fapu,
                  valid=valid)
    streamed = Motion.streamed(names, neutral, lambda a, b: held.displacements[a:b], pose, 25.0, face.target.fapu,
                               valid=valid)
    got = fitter.read_motion(streamed)
    np.testing.assert_array_equal(got, fitter.read_motion(held))
    assert np.isnan(got[[1, CHUNK + 1]]).all() and np.isfinite(got[valid]).all()
    every = [0, 2, CHUNK, CHUNK + 2]
    np.testing.assert_allclose(got[every], fitter(d[every]), atol=1e-12)


def test_envelope_rises_holds_and_falls():
    w = envelope(21)
    assert w[0] == 0 and w[-1] == 0 and w.max() == 1 and np.all(w[7:14] == 1)
    assert np.all(np.diff(w[:8]) >= 0) and np.all(np.diff(w[13:]) <= 0)


@pytest.fixture(scope="module")
def ict():
    shared("ict_facekit", "ict_deltas_full.npz")
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import facs_ict
    from ict_scenario import load_ict

    return facs_ict, load_ict()


def test_muscle_action_units_point_the_way_ict_facekit_does(ict):
    """Every AU of ICT-FaceKit's FACS table, made by the muscles on the ICT neutral, has a cosine of at
    least 0.5 with ICT's own shape(s) for it (the benchmark's target; its median is higher)."""
    facs_ict, model = ict
    cos = facs_ict.direction(model, [facs_ict.ict_face(model, model.neutral)])
    low = {code: round(v[0], 2) for code, v in cos.items() if v[0] < 0.5}
    assert not low, low
    assert np.median([v[0] for v in cos.values()]) >= 0.7
