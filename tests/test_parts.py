"""Parts of a head told apart, and moved as parts: rigid teeth, a turning jaw, eyeballs, lid layers."""

import json

import numpy as np
import pytest
from conftest import shared
from scipy.spatial import cKDTree

from faceanim.errors import FileFormatError, InputError
from faceanim.geometry import read_mesh
from faceanim.geometry.quality import rigid_residual, turned_over
from faceanim.geometry.topology import component_labels, open_edges
from faceanim.mpeg4 import fap_table
from faceanim.mpeg4.fapstream import FapStream
from faceanim.parts import face_parts, read_parts_file
from faceanim.retarget.deform import PartsDeformer
from faceanim.retarget.gaze import eye_rotations

# ICT-FaceKit's vertex ranges (its README): the upper teeth are its first 16 teeth, the lower the next 16.
ICT_UPPER_TEETH, ICT_LOWER_TEETH = slice(17039, 19247), slice(19247, 21451)
ICT_EYES = slice(21451, 23021), slice(23021, 24591)
ICT_LID_LAYERS = slice(24591, 26719)
ICT_FACE = slice(0, 9409)


@pytest.fixture(scope="module")
def ict():
    from faceanim.retarget.placement import auto_target

    target = auto_target(read_mesh(shared("ict_facekit", "obj", "generic_neutral_mesh.obj")))
    return target, face_parts(target)


@pytest.fixture(scope="module")
def ict_lined(ict):
    """ICT's parts with its mouth's inside kept as skin, one surface with the lips (as on a head whose
    bag is not cut off at the lips' inner rims): the lips' lining then reaches the teeth, which is what
    the teeth's contact is for. As ICT's own parts are found, the inside is a socket (faceanim.parts.mouth)."""
    from unittest import mock

    target, _ = ict
    with mock.patch("faceanim.parts.mouth_inside", lambda mesh, *_: np.zeros(len(mesh.vertices), dtype=bool)):
        return target, face_parts(target)


def test_ict_parts_follow_its_own_part_table(ict):
    _, parts = ict
    assert (parts.role[ICT_UPPER_TEETH] == 1).all() and (parts.role[ICT_LOWER_TEETH] == 2).all()
    assert (parts.jaw_weight[ICT_UPPER_TEETH] == 0).all() and (parts.jaw_weight[ICT_LOWER_TEETH] == 1).all()
    assert parts.mask("eye_left")[ICT_EYES[0]].all() and parts.mask("eye_right")[ICT_EYES[1]].all()
    assert parts.mask("lid_layer")[ICT_LID_LAYERS].all()
    # The face is skin but for its mouth's inside, cut off behind the lips' inner rims (faceanim.parts.mouth).
    face = np.zeros(len(parts.role), dtype=bool)
    face[ICT_FACE] = True
    assert parts.mask("skin", "socket")[face].all() and 0 < parts.mask("socket")[face].sum() < 0.1 * face.sum()
    # The eyeballs are spheres: their centres are fitted, each behind its own eye, mirrored.
    left, right = parts.eye_centres
    assert left[0] > 0 > right[0] and abs(left[0] + right[0]) < 0.05 and abs(left[1] - right[1]) < 0.05


def test_ict_jaw_weight_is_full_on_the_chin_and_nothing_above_the_lips(ict):
    target, parts = ict
    w = parts.jaw_weight
    assert w[target.points["2.10"]] > 0.9 and w[target.points["2.3"]] > 0.9  # chin boss, lower lip middle
    # The chin's lowest point sits on the jaw line, where the weight, eased, starts to fall towards the neck.
    assert w[target.points["2.1"]] > 0.8
    for still in ("2.2", "9.15", "3.7", "4.1", "10.9", "10.10"):  # upper lip, nose, eye, brow, ears
        if still in target.points:
            assert w[target.points[still]] < 0.05, still


def test_an_eased_weight_keeps_the_held_vertices_and_rounds_the_kinks_of_a_harmonic_one():
    """A strip whose weight is 1 on its left third, 0 on its right third and harmonic (a straight ramp)
    between: the ramp meets each flat part with a kink. Eased, the held column keeps its values,
    every weight stays in [0, 1], a constant stays constant, and the sharpest bend (the largest
    second difference along the strip) falls to under half."""
    from conftest import grid_mesh

    from faceanim.geometry.surface import cotangent_laplacian
    from faceanim.parts.jaw import _eased

    mesh = grid_mesh(n=31, size=3.0)
    x = mesh.vertices[:, 0]
    ramp = np.clip(2.0 - x, 0.0, 1.0)  # 1 up to x = 1, 0 from x = 2
    L, mass = cotangent_laplacian(mesh)
    held = np.isclose(x, 3.0)
    eased = _eased(ramp, L, mass, held, 0.3 ** 2)
    np.testing.assert_array_equal(eased[held], ramp[held])
    assert eased.min() >= -1e-12 and eased.max() <= 1 + 1e-12
    np.testing.assert_allclose(_eased(np.full(len(x), 0.7), L, mass, held, 0.3 ** 2), 0.7)
    row = np.isclose(mesh.vertices[:, 1], 1.5)
    order = np.argsort(x[row])

    def sharpest(w):
        return np.abs(np.diff(w[row][order], 2)).max()

    assert sharpest(eased) < 0.5 * sharpest(ramp), (sharpest(eased), sharpest(ramp))


def test_the_ict_jaw_weight_is_eased_away_from_the_lips_and_harmonic_on_them(ict):
    """Within LIPS_HELD mouth widths of the lips' control points the weight is the harmonic one (the
    upper lip takes no jaw weight from the corners), and the weight bends less over the cheeks and
    jaw than the harmonic one does."""
    from scipy.spatial import cKDTree

    from faceanim.geometry.surface import cotangent_laplacian
    from faceanim.geometry.topology import submesh
    from faceanim.parts import jaw as jaw_module
    from faceanim.parts.faceparts import _LOWER_LIP, _UPPER_LIP

    target, parts = ict
    skin = parts.mask("skin")
    eased = parts.jaw_weight[skin]
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(jaw_module, "EASED_OVER", 0.0)
        harmonic = face_parts(target).jaw_weight[skin]
    rest = target.mesh.vertices[skin]
    width = np.linalg.norm(np.subtract(*target.mesh.vertices[target.ids(["8.3", "8.4"])]))
    lips = target.mesh.vertices[target.ids([n for n in _UPPER_LIP + _LOWER_LIP if n in target.points])]
    near = cKDTree(lips).query(rest)[0] < jaw_module.LIPS_HELD * width
    np.testing.assert_allclose(eased[near], harmonic[near], atol=1e-9)
    assert not np.allclose(eased[~near], harmonic[~near])
    L, _ = cotangent_laplacian(submesh(target.mesh, skin)[0])
    away = ~near
    assert np.abs(L @ eased)[away].sum() < 0.7 * np.abs(L @ harmonic)[away].sum()


def test_the_jaw_turns_the_lower_teeth_rigidly_and_controls_land_exactly(ict):
    target, parts = ict
    names = [n for n in target.points if not n.startswith("mp")]
    ids = np.unique(target.ids(names))
    deformer = PartsDeformer(target, parts, ids, relax=False)
    rng = np.random.default_rng(4)
    displacements = deformer.jaw_turn([0.0, 0.25, 0.4])[:, ids] * parts.jaw_weight[ids][None, :, None]
    displacements += rng.normal(scale=0.05, size=displacements.shape) * parts.mask("skin")[ids][None, :, None]
    positions = deformer(displacements, [0.0, 0.25, 0.4], fit_weights=False)
    rest = target.mesh.vertices
    spread = deformer.in_spread  # the skin's controls that lie on a skin triangle
    np.testing.assert_allclose(positions[:, ids[spread]], rest[ids[spread]] + displacements[:, spread], atol=1e-8)
    for t in (1, 2):
        lower, upper = positions[t, ICT_LOWER_TEETH], positions[t, ICT_UPPER_TEETH]
        assert rigid_residual(rest[ICT_LOWER_TEETH], lower[None])[0] < 1e-9
        np.testing.assert_allclose(upper, rest[ICT_UPPER_TEETH], atol=1e-12)
    chin = target.points["2.1"]
    incisors = np.flatnonzero(parts.mask("lower_teeth"))
    front = incisors[np.argsort(-rest[incisors, 2])[:50]]
    ratio = np.linalg.norm(positions[2, front] - rest[front], axis=1).mean() / np.linalg.norm(
        positions[2, chin] - rest[chin])
    assert 0.5 < ratio < 1.2


def test_eyeballs_turn_about_their_centres_with_the_gaze_faps(ict):
    target, parts = ict
    table = fap_table()
    values = np.zeros((2, 68))
    mask = np.zeros((2, 68), dtype=bool)
    for name in ("yaw_l_eyeball", "yaw_r_eyeball"):
        values[1, table.number(name) - 1] = 20000  # 0.2 rad towards the face's left
        mask[:, table.number(name) - 1] = True
    eyes = eye_rotations(FapStream(values, mask, 25.0), parts)
    ids = np.unique(target.ids([n for n in target.points if not n.startswith("mp")]))
    positions = PartsDeformer(target, parts, ids)(np.zeros((2, len(ids), 3)), [0.0, 0.0], eyes)
    rest = target.mesh.vertices
    for k, side in enumerate(("eye_left", "eye_right")):
        ball = parts.mask(side)
        centre = parts.eye_centres[k]
        np.testing.assert_allclose(np.linalg.norm(positions[1, ball] - centre, axis=1),
                                   np.linalg.norm(rest[ball] - centre, axis=1), atol=1e-9)
        front = np.flatnonzero(ball)[np.argmax(rest[ball, 2])]
        assert positions[1, front, 0] - rest[front, 0] > 0.1  # the pupil moves to the face's left
    np.testing.assert_allclose(positions[0], rest, atol=1e-12)


def test_a_mesh_without_face_points_is_all_skin_and_no_jaw():
    from conftest import grid_mesh

    from faceanim.target import Target

    mesh = grid_mesh(5)
    parts = face_parts(Target(mesh, {"2.1": 3}, None))
    assert parts.mask("skin").all() and not parts.jaw_weight.any()


def test_parts_file_errors(tmp_path, ict):
    target, _ = ict
    bad = tmp_path / "p.json"
    bad.write_text(json.dumps({"teeth": ["M_Teeth"], "hair": ["M_Hair"]}))
    with pytest.raises(FileFormatError, match="unknown role 'hair'"):
        read_parts_file(bad)
    bad.write_text(json.dumps({"teeth": [[1, "x"]]}))
    with pytest.raises(FileFormatError, match="must be a list of part names"):
        read_parts_file(bad)
    bad.write_text("{")
    with pytest.raises(FileFormatError, match="is not valid JSON"):
        read_parts_file(bad)
    with pytest.raises(InputError, match="names part 'M_Hat', which the mesh lacks"):
        face_parts(target, labels={"static": ["M_Hat"]})
    with pytest.raises(InputError, match=r"range \[0, 99999999\] is outside"):
        face_parts(target, labels={"static": [[0, 99999999]]})
    with pytest.raises(InputError, match=r"range \[5, 2\] runs backwards"):
        face_parts(target, labels={"static": [[5, 2]]})
    missing = tmp_path / "nowhere.json"
    with pytest.raises(InputError, match="nowhere.json: cannot be read"):
        read_parts_file(missing)


def test_labels_override_what_geometry_finds(ict):
    target, _ = ict
    parts = face_parts(target, labels={"lower_teeth": [[ICT_UPPER_TEETH.start, ICT_UPPER_TEETH.stop - 1]]})
    assert (parts.role[ICT_UPPER_TEETH] == 2).all() and (parts.jaw_weight[ICT_UPPER_TEETH] == 1).all()
    # Names and ranges together: the range wins where they overlap, and both count.
    first = ICT_LOWER_TEETH.start
    mixed = face_parts(target, labels={"static": ["M_Teeth"], "lower_teeth": [[first, first + 99]]})
    assert (mixed.role[first:first + 100] == 2).all() and (mixed.jaw_weight[first:first + 100] == 1).all()
    assert mixed.mask("static")[ICT_UPPER_TEETH].all() and mixed.mask("static")[first + 100:ICT_LOWER_TEETH.stop].all()


def test_decode_takes_a_parts_file_and_refuses_a_bad_one_before_any_work(tmp_path, capsys):
    """--parts relabels the ICT head's teeth as still: an opening jaw then leaves them in place, where
    without it the lower set follows the chin. A parts file naming a part the mesh lacks is one line
    on stderr, exit 2, nothing written."""
    from faceanim.cli import main
    from faceanim.mpeg4.fapfile import write_fap
    from faceanim.pipeline import decode

    table = fap_table()
    values = np.zeros((3, 68))
    mask = np.zeros((3, 68), dtype=bool)
    opening = table.number("open_jaw") - 1
    values[:, opening] = [0, 400, 800]
    mask[:, opening] = True
    fap = tmp_path / "open.fap"
    write_fap(fap, FapStream(values, mask, 25.0, name="open"))
    mesh = shared("ict_facekit", "obj", "generic_neutral_mesh.obj")
    moving = decode(fap, tmp_path / "a.glb", target_mesh=mesh)
    lower = moving.positions[:, ICT_LOWER_TEETH]
    assert np.linalg.norm(lower[2] - lower[0], axis=1).min() > 0.3  # the lower teeth go with the jaw (cm)
    labels = tmp_path / "parts.json"
    labels.write_text(json.dumps({"static": ["M_Teeth"]}))
    still = decode(fap, tmp_path / "b.glb", target_mesh=mesh, parts=labels)
    np.testing.assert_allclose(still.positions[:, ICT_LOWER_TEETH], lower[[0, 0, 0]], atol=1e-9)
    labels.write_text(json.dumps({"static": ["M_Hat"]}))
    out = tmp_path / "c.glb"
    assert main(["decode", str(fap), "--target", str(mesh), "--parts", str(labels), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "names part 'M_Hat', which the mesh lacks" in err[0], err
    assert not out.exists()


def test_lips_pressed_into_the_teeth_are_kept_in_front_of_them(ict_lined):
    """The lower lip's inner rim driven 1.2 cm straight back (into the lower incisors) stays in front
    of the teeth: measured with the exact signed distance of geometry.quality, not the deformer's own."""
    from faceanim.geometry.quality import penetration_depth

    target, parts = ict_lined
    names = [n for n in target.points if not n.startswith("mp")]
    ids = np.unique(target.ids(names))
    pressed = np.zeros((2, len(ids), 3))
    lower_lip = np.isin(ids, target.ids([n for n in ("2.3", "2.8", "2.9") if n in target.points]))
    pressed[1, lower_lip] = -1.2 * parts.axes[2]
    mesh = target.mesh
    teeth = parts.mask("lower_teeth") & (parts.jaw_weight == 1) & (np.arange(len(mesh.vertices)) >= 17039)
    tris = mesh.triangles[teeth[mesh.triangles].all(axis=1)]
    local = np.full(len(mesh.vertices), -1)
    local[np.flatnonzero(teeth)] = np.arange(teeth.sum())
    lip = np.flatnonzero(parts.mask("skin") & (np.linalg.norm(mesh.vertices - mesh.vertices[
        target.points["2.3"]], axis=1) < 0.6))
    depths = {}
    for keep in (False, True):
        deformer = PartsDeformer(target, parts, ids, relax=False)
        if not keep:
            deformer.contact.sets.clear()  # the same deformer without the teeth contact
        positions = deformer(pressed, [0.0, 0.0], fit_weights=False)
        depths[keep] = penetration_depth(positions[:, lip], positions[:, teeth], local[tris])[1]
    # Pushed 1.2 cm back, the lip goes into the teeth without the contact (0.09 cm deep with FaceMesh's
    # placement, 0.06 with the Face Landmarker's) and stays within 0.1 mm of their surface with it (0.0054
    # and 0.0060 cm): the bound is on what is left, not on a ratio to a depth the placement decides.
    assert depths[False] > 0.05 and depths[True] < 0.01, depths


def test_the_spread_is_biharmonic_round_the_lips_and_bounded_beyond(ict):
    """Bounded everywhere, a few triangles turned where the lips meet in some wide smiles and the fold
    relaxer flattened the smile; round the lips the spread keeps the biharmonic field's weights, and
    round the eyes (a lid's skin past its lash line) it is bounded: no negative weight there."""
    from faceanim.landmarks import EYE_LIDS, LIP_OUTER, landmark_names

    target, parts = ict
    deformer = PartsDeformer(target, parts, np.unique(list(target.points.values())), relax=False)
    operator = deformer.spread.operator
    names = landmark_names(478)

    def rows_near(points, radius):
        centres = target.mesh.vertices[target.ids([names[i] for i in points])]
        skin = target.mesh.vertices[deformer.skin_ids]
        close = np.linalg.norm(skin[:, None] - centres[None], axis=2).min(axis=1) < radius
        return operator[np.flatnonzero(close)]

    lids = [i for upper, lower in EYE_LIDS.values() for i in upper + lower]
    assert (rows_near(lids, 0.5) >= 0).all()
    assert (rows_near(LIP_OUTER, 0.1 * target.mouth_width) < -1e-3).any()


def test_above_the_face_meshs_top_the_spread_fades_out_and_the_scalp_is_held_whatever_the_controls(ict, monkeypatch):
    """A brow raise is not carried on up the forehead past where anything is measured: over SCALP_FADE
    ES0 above the highest of MediaPipe's points placed on the target the spread's rows fall to nothing;
    at and below it they are as before. The top is the face mesh's, so a target driven through its
    MPEG-4 points alone (the brows their highest) keeps its forehead moving."""
    from faceanim.landmarks import landmark_names
    from faceanim.retarget import deform, spreadshares

    target, parts = ict
    up = parts.axes[1]
    top = (target.mesh.vertices[target.ids([n for n in landmark_names(468) if n in target.points])] @ up).max()
    fade = spreadshares.SCALP_FADE * target.fapu.es0
    for names in (list(target.points), [n for n in target.points if not n.startswith("mp")]):
        ids = np.unique(target.ids(names))
        held = PartsDeformer(target, parts, ids, relax=False)
        with monkeypatch.context() as patched:
            patched.setattr(deform, "scalp_hold", lambda *_: None)
            free = PartsDeformer(target, parts, ids, relax=False)
        height = target.mesh.vertices[held.skin_ids] @ up
        below, beyond = height <= top, height >= top + fade
        between = ~below & ~beyond
        assert below.sum() > 1000 and beyond.sum() > 100 and between.sum() > 10  # ICT's scalp lies above its face
        np.testing.assert_array_equal(held.spread.operator[below], free.spread.operator[below])
        np.testing.assert_array_equal(held.spread.operator[beyond], 0.0)
        free_rows, held_rows = np.abs(free.spread.operator[between]), np.abs(held.spread.operator[between])
        moved = free_rows.sum(axis=1) > 1e-9
        share = held_rows[moved].sum(axis=1) / free_rows[moved].sum(axis=1)
        np.testing.assert_allclose(share, 1.0 - (height[between][moved] - top) / fade, rtol=1e-9)
        raise_ = np.zeros((1, len(ids), 3))
        raise_[..., 1] = 0.5
        positions = held(raise_, [0.0], fit_weights=False)[0]
        scalp = held.skin_ids[beyond]
        np.testing.assert_array_equal(positions[scalp], target.mesh.vertices[scalp])
    feature_points = np.unique(target.ids([n for n in target.points if not n.startswith("mp")]))
    assert (target.mesh.vertices[feature_points] @ up).max() < top - 0.5 * fade  # the brows: well under the top
    from faceanim.target import Target

    mpeg4_only = Target(target.mesh, {n: v for n, v in target.points.items() if not n.startswith("mp")}, target.fapu)
    skin = target.mesh.vertices[held.skin_ids]
    assert spreadshares.scalp_hold(mpeg4_only, skin, up) is None  # no face mesh placed: nothing says where it ends
    assert spreadshares.scalp_hold(Target(target.mesh, target.points, None), skin, up) is None  # no FAPU: no yardstick


def test_frames_in_chunks_give_what_all_frames_at_once_give(ict):
    """The deformer makes any run of frames on its own (memory bounded by the chunk, not the motion);
    the chunking changes nothing, folds relaxed and lips pushed included."""
    target, parts = ict
    ids = np.unique(target.ids([n for n in target.points if not n.startswith("mp")]))
    rng = np.random.default_rng(7)
    deformer = PartsDeformer(target, parts, ids)
    angles = np.array([0.0, 0.1, 0.3, 0.2, 0.05])
    displacements = deformer.jaw_turn(angles, ids) * parts.jaw_weight[ids][None, :, None]
    displacements += rng.normal(scale=0.2, size=displacements.shape)
    frames = deformer.source(displacements, angles)
    in_twos = np.concatenate([frames(a, min(a + 2, 5)) for a in range(0, 5, 2)])
    # to rounding: BLAS may sum a matrix product's terms in another order for another number of frames
    # (one coordinate of 80,157 differs in its last bit since the spread's weights changed)
    np.testing.assert_allclose(in_twos, frames(0, 5), rtol=0, atol=1e-9)
    np.testing.assert_allclose(frames(3, 4), deformer(displacements, angles)[3:4], rtol=0, atol=1e-9)



def test_a_wide_opening_leaves_the_upper_lip_where_its_controls_are(ict_lined):
    """The jaw opens 26 degrees and every control follows it by the parts' weight, so the upper lip's
    controls stay put. The skin of the upper lip stays within 2 mm of rest. (Turned by the weight
    raised against folding, as it once was, it sagged 1 cm between its controls: a curtain over the
    open mouth.)"""
    from scipy.spatial import cKDTree

    from faceanim.parts.faceparts import _UPPER_LIP

    target, parts = ict_lined
    rest = target.mesh.vertices
    ids = np.unique(target.ids([n for n in target.points if not n.startswith("mp")]))
    deformer = PartsDeformer(target, parts, ids)
    angles = np.array([0.0, 0.45])
    displacements = deformer.jaw_turn(angles, ids) * parts.jaw_weight[ids][None, :, None]
    upper = target.ids([n for n in _UPPER_LIP if n in target.points])
    lip = parts.mask("skin") & (parts.jaw_weight < 0.05) & (cKDTree(rest[upper]).query(rest)[0] < 0.25)
    assert lip.sum() > 100
    raised = deformer.unfolded(parts.jaw_weight, angles)
    assert raised[lip].max() > 0.2  # the raise does reach the upper lip
    moved = deformer(displacements, angles, fit_weights=False)[1]
    assert np.linalg.norm(moved[lip] - rest[lip], axis=1).max() < 0.2


def test_lips_squeezed_into_the_teeth_leave_no_skin_triangle_turned_over(ict_lined, monkeypatch):
    """Lip controls pushed 0.4 cm back into the teeth, with noise, while the jaw closes past rest: the
    pushes out of the upper and lower teeth disagree at the corners. The deformer leaves no skin
    triangle turned over, with the teeth cover or by the pushes alone; with the pins held (not
    yielding to the folds they hold) and no cover, folds stay."""
    from scipy.spatial import cKDTree

    import faceanim.geometry.relax as relax
    from faceanim.parts import INNER_LIP_POINTS

    target, parts = ict_lined
    rest = target.mesh.vertices
    ids = np.unique(target.ids(list(target.points)))
    deformer = PartsDeformer(target, parts, ids)
    angles = np.array([-0.05, -0.03, 0.0, 0.02])
    displacements = deformer.jaw_turn(angles, ids) * parts.jaw_weight[ids][None, :, None]
    lips = [n for n in target.points if n in INNER_LIP_POINTS or n in ("8.3", "8.4")]
    width = np.linalg.norm(rest[target.points["8.3"]] - rest[target.points["8.4"]])
    near = cKDTree(rest[target.ids(lips)]).query(rest[ids])[0] < 0.2 * width
    rng = np.random.default_rng(11)
    displacements[:, near] += -0.4 * parts.axes[2] + rng.normal(scale=0.15, size=(len(angles), near.sum(), 3))
    skin = target.mesh.triangles[parts.mask("skin")[target.mesh.triangles].all(axis=1)]

    def turned(positions):
        return turned_over(rest, positions, skin).sum(axis=1)

    assert turned(deformer(displacements, angles, fit_weights=False)).tolist() == [0, 0, 0, 0]
    # Without the teeth cover (which puts lips carried behind the teeth back on the jaw's turn) the
    # pushes alone must mend it: with the pins held, folds stay.
    monkeypatch.setattr(deformer, "cover", lambda field, angles: np.zeros(field.shape[:2], dtype=bool))
    assert turned(deformer(displacements, angles, fit_weights=False)).tolist() == [0, 0, 0, 0]
    monkeypatch.setattr(relax, "_YIELD_RINGS", ())
    assert turned(deformer(displacements, angles, fit_weights=False)).max() > 0


def test_a_target_of_no_human_size_is_refused_before_any_work(tmp_path, capsys):
    """A face whose eyes are 0.0063 units apart (0.63 cm even in metres): decode says so in one line, naming the
    file, and writes nothing (the unit used to be told only when the .glb was written, after the work)."""
    from faceanim.cli import main
    from faceanim.generic import generic_target
    from faceanim.geometry import write_mesh

    target = generic_target()
    tiny = tmp_path / "tiny.obj"
    write_mesh(tiny, target.mesh.with_vertices(target.mesh.vertices * 1e-3))
    points = tmp_path / "points.json"
    points.write_text(json.dumps({n: i for n, i in target.points.items() if not n.startswith("mp")}))
    out = tmp_path / "o.glb"
    fap = shared("xface", "Faps", "joy.fap")
    code = main(["decode", str(fap), "--target", str(tiny), "--points", str(points), "-o", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "tiny.obj" in err[0] and "no human face" in err[0], err
    assert not out.exists()


def test_a_target_without_face_points_does_not_turn_a_jaw():
    """A mesh with a chin point but no eyes or mouth corners: all skin, no jaw, and a displaced chin
    moves by exactly its displacement (no turn about a made-up hinge on top)."""
    from conftest import grid_mesh

    from faceanim.retarget.deform import deform_parts
    from faceanim.target import Target

    mesh = grid_mesh(6)
    target = Target(mesh, {"2.1": 3, "2.2": 20}, None)
    shift = np.zeros((2, 2, 3))
    shift[1, 0] = [0.0, -0.3, 0.1]
    positions = deform_parts(target, None, [3, 20], shift)
    np.testing.assert_allclose(positions[1, [3, 20]] - mesh.vertices[[3, 20]], shift[1], atol=1e-12)
    np.testing.assert_allclose(positions[0], mesh.vertices, atol=1e-12)


def test_coincident_eye_corners_are_refused_by_name():
    from faceanim.parts import face_axes

    p = {n: np.zeros(3) for n in ("3.7", "3.8", "3.11", "3.12")}
    p.update({"8.3": np.array([1.0, -3, 0]), "8.4": np.array([-1.0, -3, 0]), "2.1": np.array([0.0, -5, 0])})
    with pytest.raises(InputError, match="eyes have no width"):
        face_axes(p)


def test_no_view_into_the_avatars_parted_lips_sees_out_through_the_back_of_the_mask():
    """The default avatar is a mask, open behind. With the lower lip let down 1.5 cm, every pixel inside
    the lips' opening, seen from the front or 40 degrees to either side, shows the mouth (its fan, the
    lining from the lips' edge back to the fan's rim, the teeth) or the skin, never the background.
    Without the lining, a view from 40 degrees saw past the fan's rim at the far corner of the mouth."""
    pytest.importorskip("mediapipe", reason="needs faceanim[capture] to make the default avatar")
    from skimage.measure import points_in_poly

    from faceanim.geometry.topology import boundary_loops
    from faceanim.inputs import load_target
    from faceanim.render.camera import front_camera
    from faceanim.render.rasterizer import Renderer

    target = load_target(None)
    parts = face_parts(target)
    mesh, rest = target.mesh, target.mesh.vertices
    ids = np.unique(target.ids([n for n in target.points if not n.startswith("mp")]))
    lower = np.isin(ids, target.ids([n for n in ("2.3", "2.8", "2.9", "8.2", "8.7", "8.8") if n in target.points]))
    down = np.zeros((2, len(ids), 3))
    down[1, lower] = -1.5 * parts.axes[1]
    opened = PartsDeformer(target, parts, ids, relax=False)(down, [0.0, 0.0], fit_weights=False)[1]
    skin = mesh.triangles[parts.mask("skin")[mesh.triangles].all(axis=1)]
    mouth = rest[target.ids(["8.3", "8.4"])].mean(axis=0)
    lips = min(boundary_loops(skin), key=lambda loop: np.linalg.norm(rest[loop].mean(axis=0) - mouth))
    unseen = (0, 255, 0)  # a background no part is drawn in
    pixels = np.stack(np.meshgrid(np.arange(320) + 0.5, np.arange(320) + 0.5), axis=-1).reshape(-1, 2)
    with Renderer(320, 320, background=unseen) as renderer:
        for yaw in (-40.0, 0.0, 40.0):
            camera = front_camera(opened[lips], 320, 320, vertical_fov=20.0, margin=1.4, yaw=yaw)
            image = renderer.render(mesh, camera, positions=opened, mode="shaded")
            inside = points_in_poly(pixels, camera.project(opened[lips])).reshape(320, 320)
            through = inside & (image == unseen).all(axis=2)
            assert inside.sum() > 2000 and not through.any(), (yaw, int(through.sum()))


def test_the_avatars_mouth_socket_spans_the_parted_lips():
    """The default avatar's mouth is a separate socket (a fan behind the lips) and its eyes flat caps,
    not balls: both hang from rims riding on their openings. With the lower lip let down 1.5 cm, the
    socket's lower rim goes down with it, its upper rim stays with the upper lip and its middle hangs
    between: the inside of the mouth has no hole."""
    pytest.importorskip("mediapipe", reason="needs faceanim[capture] to make the default avatar")
    from faceanim.inputs import load_target

    target = load_target(None)
    parts = face_parts(target)
    assert not parts.mask("eye_left", "eye_right").any() and parts.mask("upper_teeth").any()
    names = [n for n in target.points if not n.startswith("mp")]
    ids = np.unique(target.ids(names))
    lower = np.isin(ids, target.ids([n for n in ("2.3", "2.8", "2.9", "8.2", "8.7", "8.8") if n in target.points]))
    down = np.zeros((2, len(ids), 3))
    down[1, lower] = -1.5 * parts.axes[1]
    positions = PartsDeformer(target, parts, ids, relax=False)(down, [0.0, 0.0], fit_weights=False)
    rest = target.mesh.vertices
    mouth = rest[target.ids(["8.3", "8.4"])].mean(axis=0)
    lining = np.flatnonzero(parts.mask("socket"))
    piece = component_labels(target.mesh)
    nearest = lining[np.argmin(np.linalg.norm(rest[lining] - mouth, axis=1))]
    beside = lining[np.linalg.norm(rest[lining] - rest[nearest], axis=1) < 2.0]  # the mouth's fan and band
    fan = min(np.unique(piece[beside]), key=lambda p: np.sum(piece[lining] == p))  # the smaller of the two
    socket = lining[piece[lining] == fan]  # the mouth's fan: not its band, nor an eye's cap
    drop = -(positions[1, socket] - rest[socket]) @ parts.axes[1]
    height = (rest[socket] - mouth) @ parts.axes[1]
    assert drop[height < height.min() + 0.2].min() > 1.0  # the lower rim goes down with the lip
    assert drop[height > height.max() - 0.1].max() < 0.4  # the upper rim stays up
    mesh = target.mesh
    in_socket = np.zeros(len(rest), dtype=bool)
    in_socket[socket] = True
    fan = mesh.triangles[in_socket[mesh.triangles].all(axis=1)]
    tip = np.setdiff1d(np.unique(fan), open_edges(fan))  # the fan's centre, off its rim
    assert len(tip) == 1
    tip_drop = -(positions[1, tip[0]] - rest[tip[0]]) @ parts.axes[1]
    assert 0.2 < tip_drop < 1.3, tip_drop  # the middle hangs between


def test_the_teeth_contact_leaves_no_lip_vertex_deeper_than_at_rest_whatever_it_skips(ict):
    """Every lip vertex, measured exactly against each rigid teeth set after the contact, sits no
    deeper than it did at rest: the screens that spare most vertices the exact distance (moved less than
    it stood clear, the nearest vertices' planes) must not let one through. Lips pushed back by random
    amounts up to 1.2 cm, the jaw open 0.25 rad."""
    from faceanim.geometry.quality import signed_offsets
    from faceanim.retarget.contact import TeethContact

    target, parts = ict
    skin_ids = np.flatnonzero(parts.mask("skin"))
    contact = TeethContact(target, parts, skin_ids)
    assert len(contact.sets) == 2 and len(contact.lips) > 100
    rng = np.random.default_rng(5)
    field = np.zeros((3, len(skin_ids), 3))
    field[:, contact.lips] = -rng.uniform(0, 1.2, (3, len(contact.lips), 1)) * parts.axes[2]
    angles = np.array([0.0, 0.1, 0.25])
    before = field.copy()
    pushed = contact(field, angles)
    # What it says it pushed is exactly what it moved (the deformer relaxes the skin around those).
    np.testing.assert_array_equal(pushed, (field != before).any(axis=2))
    assert pushed.any()
    h, a = parts.hinge, parts.axes[0]
    for teeth in contact.sets:
        for t in range(len(angles)):
            p = contact.lip_rest + field[t, contact.lips]
            turn = -teeth.turn_share * angles[t]  # into the set's rest frame
            r = p - h
            local = h + r * np.cos(turn) + np.cross(a, r) * np.sin(turn) + np.outer(r @ a, a) * (1 - np.cos(turn))
            signed = signed_offsets(local, teeth.surface)[0]
            assert (signed >= teeth.allowed - 0.01).all(), (teeth.turn_share, t, (teeth.allowed - signed).max())
    # Limited to some vertices (those a relaxation moved), it pushes exactly those of them it pushed
    # unlimited, by the same amounts, and leaves the others where they were.
    among = np.zeros(pushed.shape, dtype=bool)
    among[:, skin_ids % 2 == 0] = True
    limited = before.copy()
    pushed_among = contact(limited, angles, among=among)
    np.testing.assert_array_equal(pushed_among, pushed & among)
    np.testing.assert_array_equal(limited[among], field[among])
    np.testing.assert_array_equal(limited[~among], before[~among])


def test_an_eased_push_carries_each_push_onto_the_skin_around_it_and_leaves_no_lip_in(ict_lined):
    """The lips pressed 0.3 cm into the teeth (a smooth dent about the lips' middle). Pushed out one
    vertex at a time, neighbours along an edge end up to the whole push apart; eased, the push is
    carried onto the skin within the radius (nothing beyond it moves), no lip vertex stays in, and
    neighbours move nearly alike (the pushes' differences along edges a third of the plain push's or
    less, nine edges in ten). With radius 0 it is the plain push. A push on the lower lip alone moves
    nothing on the upper lip, which touches it at rest."""
    from faceanim.geometry.topology import submesh
    from faceanim.retarget.contact import TeethContact

    target, parts = ict_lined
    skin = parts.mask("skin")
    skin_ids = np.flatnonzero(skin)
    contact = TeethContact(target, parts, skin_ids)
    rest = contact.skin_rest
    centre = rest[contact.lips].mean(axis=0)
    field = np.zeros((1, len(rest), 3))
    field[0] = -0.3 * np.exp(-((rest - centre) ** 2).sum(axis=1) / 2.0 ** 2)[:, None] * parts.axes[2]
    angles = np.zeros(1)

    plain = field.copy()
    pushed = contact(plain, angles)
    assert pushed.sum() > 20
    alone = field.copy()
    contact.eased(alone, angles, 0.0)
    np.testing.assert_array_equal(alone, plain)
    for bad in (-1.0, np.nan, np.inf):
        with pytest.raises(ValueError, match="radius must be a finite distance of at least 0"):
            contact.eased(field.copy(), angles, bad)

    eased = field.copy()
    radius = contact.reach
    moved = contact.eased(eased, angles, radius)
    assert not contact(eased.copy(), angles).any()  # no lip vertex left in
    change = np.linalg.norm(eased[0] - field[0], axis=1)
    np.testing.assert_array_equal(moved[0], change > 0)
    # Only the lips are pushed, so nothing beyond the radius of them moves; all near a push does.
    assert (change[cKDTree(rest[contact.lips]).query(rest)[0] > radius] == 0).all()
    assert (change[cKDTree(rest[pushed[0]]).query(rest)[0] < 0.5 * radius] > 0).all()
    edges = submesh(target.mesh, skin)[0].edges

    def steps(result):  # on the edges it changes, the difference between the moves of the two ends
        move = result[0] - field[0]
        step = np.linalg.norm(move[edges[:, 0]] - move[edges[:, 1]], axis=1)
        return step[step > 0]

    assert np.percentile(steps(eased), 90) < 0.3 * np.percentile(steps(plain), 90)

    # The lips touch at rest: a push on the lower lip is carried along the skin, not across the mouth.
    weight = parts.jaw_weight[skin_ids]
    lower = np.zeros(len(rest), dtype=bool)
    lower[contact.lips[weight[contact.lips] > 0.95]] = True
    dented = np.where(lower[:, None], field[0], 0.0)[None]
    before = dented.copy()
    assert contact.eased(dented, angles, 2 * radius).any()
    upper = weight < 0.05
    np.testing.assert_array_equal(dented[0, upper], before[0, upper])


def test_a_jaw_weight_that_would_fold_the_skin_is_raised_until_no_turn_up_to_the_widest_folds():
    """A weight stepping from 1 to 0 across a sheet, turned so the weighted half swings into the other:
    the raw weight turns triangles over; the unfolded one turns none at any angle up to the widest
    (or down to the furthest closing), never lowers a weight, and leaves the full-weight half alone."""
    from conftest import grid_mesh

    from faceanim.parts.jaw import unfolded_jaw_weight

    mesh = grid_mesh(21)
    rest, tris = mesh.vertices, mesh.triangles
    hinge, axis = np.array([0.5, 2.0, 0.0]), np.array([0.0, 0.0, 1.0])  # the swing runs along +x, in the sheet
    raw = (rest[:, 0] < 0.5).astype(float)

    def folds(weight, angle):
        c, s = np.cos(angle), np.sin(angle)
        R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        moved = rest + weight[:, None] * ((rest - hinge) @ (R - np.eye(3)).T)
        v0, v1 = rest[tris], moved[tris]
        n0 = np.cross(v0[:, 1] - v0[:, 0], v0[:, 2] - v0[:, 0])
        n1 = np.cross(v1[:, 1] - v1[:, 0], v1[:, 2] - v1[:, 0])
        return int(((n0 * n1).sum(axis=1) < 0).sum())

    assert folds(raw, 0.6) > 0
    weight = unfolded_jaw_weight(rest, tris, raw, hinge, axis, [-0.05, 0.2, 0.6])
    assert all(folds(weight, a) == 0 for a in np.linspace(-0.05, 0.6, 14))
    assert (weight >= raw).all() and (weight[raw == 1] == 1).all()
    assert weight[raw == 0].max() > 0.5  # the raise is real: the unweighted side goes some way along
    np.testing.assert_array_equal(unfolded_jaw_weight(rest, tris, np.ones(len(rest)), hinge, axis, [0.6]),
                                  np.ones(len(rest)))
    kept = unfolded_jaw_weight(rest, tris, raw, hinge, axis, [0.6], movable=rest[:, 0] < 0.75)
    np.testing.assert_array_equal(kept[rest[:, 0] >= 0.75], 0.0)  # vertices not movable keep their weight


def test_turned_vectors_is_the_rotation_about_the_axis():
    """Known answer: scipy's rotation by the same axis and angles, per frame, vectors broadcast."""
    from scipy.spatial.transform import Rotation

    from faceanim.parts.jaw import turned_vectors

    rng = np.random.default_rng(3)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    angles = np.array([-0.3, 0.0, 0.45, np.pi / 2])
    vectors = rng.normal(size=(4, 5, 3))
    got = turned_vectors(vectors, axis, angles[:, None])
    for t, angle in enumerate(angles):
        expected = Rotation.from_rotvec(angle * axis).apply(vectors[t])
        np.testing.assert_allclose(got[t], expected, atol=1e-12)
    np.testing.assert_allclose(turned_vectors(got, axis, -angles[:, None]), vectors, atol=1e-12)


def test_the_avatars_lips_stay_out_of_its_teeth_where_a_lone_last_push_would_fold_them():
    """End to end, d6 frames 560-590 onto the default avatar (eyes shut, a smile, the mouth a little
    open): the last push out of the teeth, vertex by vertex, would turn a sliver at a mouth corner
    over, so the deformer carries it onto the skin around (``_EASED_RADII``); pushed vertex by vertex
    only (radius 0), the lips stayed 0.039 cm in the upper teeth. No lip in, no skin turned over."""
    pytest.importorskip("mediapipe", reason="needs faceanim[capture]")
    from faceanim.geometry.quality import penetration_depth, turned_triangles
    from faceanim.geometry.topology import submesh
    from faceanim.inputs import capture_motion, load_target
    from faceanim.motion import Motion
    from faceanim.retarget.contact import TeethContact
    from faceanim.retarget.follow import animate_motion

    video = shared("videos", "d6.mp4")
    if not video.exists():
        pytest.skip("needs ../shared/data/videos/d6.mp4")
    tracked = capture_motion(video)
    motion = Motion(tracked.names, tracked.neutral, tracked.displacements[560:590], tracked.pose[560:590],
                    tracked.fps, tracked.fapu)
    target = load_target(None)
    parts = face_parts(target)
    skin = np.flatnonzero(parts.mask("skin"))
    lips = skin[TeethContact(target, parts, skin).lips]
    teeth = parts.mask("upper_teeth") | parts.mask("lower_teeth")
    teeth_triangles = submesh(target.mesh, teeth)[0].triangles
    rest = target.mesh.vertices
    assert penetration_depth(rest[lips][None], rest[teeth][None], teeth_triangles).max() == 0.0
    positions = animate_motion(motion, target).chunk(0, len(motion))
    assert penetration_depth(positions[:, lips], positions[:, teeth], teeth_triangles).max() < 1e-3  # cm
    skin_triangles = target.mesh.triangles[parts.mask("skin")[target.mesh.triangles].all(axis=1)]
    assert turned_triangles(rest, positions, skin_triangles).max() == 0


def test_teeth_cover_sees_skin_carried_behind_the_teeth(ict):
    """The skin covering the lower teeth at rest, moved 1.5 cm back (through them): the teeth are ahead
    of most of it; moved 1 cm forward, or left at rest, of none."""
    from faceanim.retarget.contact import TeethCover

    target, parts = ict
    skin_ids = np.flatnonzero(parts.mask("skin"))
    cover = TeethCover(target, parts, skin_ids)
    lower = [s for s in cover.sets if s.turn_share == 1.0]
    assert len(lower) == 1
    covering = lower[0].covering
    assert len(covering) > 200
    field = np.zeros((3, len(skin_ids), 3))
    field[1, covering] = -1.5 * parts.axes[2]
    field[2, covering] = 1.0 * parts.axes[2]
    hidden = cover(field, np.zeros(3))
    assert not hidden[0].any() and not hidden[2].any()
    assert hidden[1, covering].mean() > 0.8


def test_in_front_of_the_upper_teeth_the_cover_watches_the_lips_only(ict):
    """The skin above the upper lip lies on the gums and grazes them as the lip is raised; watched, it
    was put back at rest over the teeth the raised lip bared (d18 onto ICT, frames 90-100). Carried
    back through the upper teeth, the lips are seen; the skin above them is not looked at."""
    from faceanim.retarget.contact import TeethContact, TeethCover

    target, parts = ict
    skin_ids = np.flatnonzero(parts.mask("skin"))
    cover = TeethCover(target, parts, skin_ids)
    lips = set(TeethContact(target, parts, skin_ids).lips.tolist())
    upper = [s for s in cover.sets if s.turn_share == 0.0]
    assert len(upper) == 1 and len(upper[0].covering) > 20
    assert set(upper[0].covering.tolist()) <= lips
    rest = target.mesh.vertices[skin_ids]
    above = np.flatnonzero((rest - rest[list(lips)].mean(axis=0)) @ parts.axes[1] > 0)
    field = np.zeros((1, len(skin_ids), 3))
    field[0] = -1.5 * parts.axes[2]  # everything carried back through the teeth
    hidden = cover(field, np.zeros(1))[0]
    lower = next(s.covering for s in cover.sets if s.turn_share == 1.0)
    assert hidden[upper[0].covering].mean() > 0.5
    assert not hidden[np.setdiff1d(np.setdiff1d(above, list(lips)), lower)].any()


def test_skin_carried_behind_the_lower_teeth_is_put_back_in_front(ict):
    """d6 onto ICT, frame 789, in small: the skin below the lower lip, interpolated between a lip that
    follows the jaw only partly and a chin that follows it fully, ended up behind the lower teeth,
    which showed through it. Here the skin over the chin's teeth is carried 1.5 cm back, jaw at rest:
    after the deformer's cover none of it has a tooth ahead of it, it is back on the jaw's turn (here
    the rest) where it was hidden, and no skin triangle is turned over."""
    target, parts = ict
    rest = target.mesh.vertices
    ids = np.unique(target.ids([n for n in target.points if not n.startswith("mp")]))
    deformer = PartsDeformer(target, parts, ids)
    skin = deformer.skin_ids
    covering = [s for s in deformer.cover.sets if s.turn_share == 1.0][0].covering
    below_lip = covering[(rest[skin[covering]] - rest[target.points["8.2"]]) @ parts.axes[1] < 0]
    assert len(below_lip) > 50
    field = np.zeros((1, len(skin), 3))
    field[0, below_lip] = -1.5 * parts.axes[2]
    angles = np.zeros(1)
    hidden = deformer.cover(field, angles)
    assert hidden.sum() > 40
    deformer._kept_in_front_of_teeth(field, rest[skin][None].copy(), angles)
    assert not deformer.cover(field, angles).any()
    assert np.abs(field[0, hidden[0]]).max() < 1e-9
    skin_triangles = target.mesh.triangles[parts.mask("skin")[target.mesh.triangles].all(axis=1)]
    positions = rest[None].copy()
    positions[0, skin] += field[0]
    assert not turned_over(rest, positions, skin_triangles).any()


def test_controls_none_of_which_lie_on_the_skin_are_refused_in_one_line(ict):
    """Controls all off the skin's surface (a parts file that calls the face something else, points on the
    eyeballs) leave nothing to spread: the user is told, not handed a face that never moves."""
    target, parts = ict
    off = np.flatnonzero(~parts.mask("skin"))[:12]
    with pytest.raises(InputError, match=r"no control point lies on the skin's surface .* --parts PARTS.json"):
        PartsDeformer(target, parts, off)
