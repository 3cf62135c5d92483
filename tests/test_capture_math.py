"""Capture's arithmetic, without video: alignment, MediaPipe's golden geometry, FAPs, filtering, neutral."""

import re

import numpy as np
import pytest
from conftest import shared

from faceanim.capture.headframe import restabilise
from faceanim.capture.jaw import _carried_share, correct_jaw_depth, jaw_carried
from faceanim.capture.metric import canonical_face, metric_geometry
from faceanim.capture.neutral import parse_neutral, relaxed_window
from faceanim.capture.smoothing import OneEuro, jitter, one_euro
from faceanim.errors import InputError
from faceanim.geometry.align import batch_procrustes, robust_depth_affine, robust_procrustes, weighted_procrustes
from faceanim.landmarks import FEATURE_POINT_LANDMARK, IBUG68_LANDMARK
from faceanim.motion import EYEBALL_RADIUS_ES0, Motion, clip_to_range, head_angles, motion_to_faps
from faceanim.mpeg4 import Fapu, fap_table, feature_points


def rotation(axis, angle):
    c, s = np.cos(angle), np.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R = np.eye(3)
    R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
    return R


def test_procrustes_recovers_a_similarity_and_ignores_zero_weights():
    rng = np.random.default_rng(0)
    p = rng.normal(size=(30, 3))
    R = rotation(0, 0.3) @ rotation(1, -0.7)
    target = 1.7 * p @ R.T + [1, -2, 3]
    target[:5] += rng.normal(size=(5, 3)) * 10  # outliers ...
    weights = np.r_[np.zeros(5), np.ones(25)]   # ... with no weight
    M = weighted_procrustes(p, target, weights)
    np.testing.assert_allclose(M[:3, :3], 1.7 * R, atol=1e-12)
    np.testing.assert_allclose(M[:3, 3], [1, -2, 3], atol=1e-12)
    np.testing.assert_allclose(batch_procrustes(p, target[None], weights)[0], M, atol=1e-12)


def test_procrustes_never_reflects():
    p = np.random.default_rng(1).normal(size=(20, 3))
    M = weighted_procrustes(p, p * [-1, 1, 1])
    assert np.linalg.det(M[:3, :3]) > 0


def test_mediapipe_golden_geometry():
    """faceanim's head pose against MediaPipe's own test vector (tolerance 1e-4 as upstream)."""
    data = shared("mediapipe", "testdata")
    number = r"([-0-9.eE]+)"
    text = (data / "face_blendshapes_in_landmarks.prototxt").read_text()
    landmarks = np.array(re.findall(rf"x:\s*{number}\s*y:\s*{number}\s*z:\s*{number}", text), dtype=float)
    expected = (data / "face_geometry_expected_out.pbtxt").read_text()
    mesh = np.array(re.findall(rf"vertex_buffer:\s*{number}", expected), dtype=float).reshape(-1, 5)[:, :3]
    pose = np.array(re.findall(rf"packed_data:\s*{number}", expected), dtype=float).reshape(4, 4).T  # column-major
    metric, found = metric_geometry(landmarks, 820, 1024)
    np.testing.assert_allclose(metric[:468], mesh, atol=1e-4)
    np.testing.assert_allclose(found, pose, atol=1e-4)


def test_batch_procrustes_takes_one_set_of_weights_a_frame():
    rng = np.random.default_rng(2)
    p = rng.normal(size=(25, 3))
    targets, weights = rng.normal(size=(4, 25, 3)), rng.random((4, 25))
    found = batch_procrustes(p, targets, weights)
    for t in range(4):
        np.testing.assert_allclose(found[t], weighted_procrustes(p, targets[t], weights[t]), atol=1e-12)


def test_robust_procrustes_is_not_tilted_by_a_few_points_carried_off_together():
    """A forehead lifted 5 mm by a brow raise (5 of 30 skull points, all the same way): the plain fit
    tilts and lifts the head; the robust one is pulled less than a tenth as far (Cauchy weights
    shrink, they do not reject). With nothing carried off both are the same."""
    rng = np.random.default_rng(3)
    rest = rng.normal(size=(30, 3)) * 4.0
    R = rotation(0, 0.2) @ rotation(1, 0.1)
    seen = (1.1 * rest @ R.T + [0.5, -1.0, 2.0])[None]
    lifted = seen.copy()
    lifted[0, :5] += 1.1 * np.array([0.0, 0.5, 0.0]) @ R.T
    weights = np.ones(30)
    truth = batch_procrustes(rest, seen, weights)
    plain = batch_procrustes(rest, lifted, weights)
    robust = robust_procrustes(rest, lifted, weights, scale=0.1)
    assert np.abs(plain - truth).max() > 1e-2
    assert np.abs(robust - truth).max() < 0.1 * np.abs(plain - truth).max()
    np.testing.assert_allclose(robust_procrustes(rest, seen, weights, scale=0.1), truth, atol=1e-12)


def test_robust_depth_affine_undoes_a_squashed_tilted_depth_along_its_own_direction_only():
    """Points squashed 4% along a slanted direction about an off-centre point, tilted along it by their
    place across it and shifted along it: the map found brings them back exactly, moving them along that
    direction and no other; a few points carried 5 mm along it pull the fit less than a tenth as far as a
    plain least squares would."""
    rng = np.random.default_rng(5)
    rest = rng.normal(size=(30, 3)) * 3.0
    u = np.array([0.3, -0.2, 1.0]) / np.linalg.norm([0.3, -0.2, 1.0])
    across = np.cross(u, [0.0, 1.0, 0.0])
    offset = rest - [1.0, 0.5, -2.0]
    seen = rest + (-0.04 * (offset @ u) + 0.05 * (offset @ across) + 0.3)[:, None] * u
    M = robust_depth_affine(rest, seen[None], np.ones(30), u[None], scale=0.05)[0]
    np.testing.assert_allclose(seen @ M[:3, :3].T + M[:3, 3], rest, atol=1e-12)
    moved = (seen @ M[:3, :3].T + M[:3, 3]) - seen
    np.testing.assert_allclose(np.cross(moved, u), 0.0, atol=1e-12)  # along u only
    carried = seen.copy()
    carried[:4] += 0.5 * u
    plain = robust_depth_affine(rest, carried[None], np.ones(30), u[None], scale=np.inf)[0]
    robust = robust_depth_affine(rest, carried[None], np.ones(30), u[None], scale=0.05)[0]

    def miss(m):
        return np.abs((seen[4:] @ m[:3, :3].T + m[:3, 3]) - rest[4:]).max()
    assert miss(plain) > 1e-2 and miss(robust) < 0.1 * miss(plain)


def test_robust_depth_affine_without_the_tilt_undoes_a_squash_and_leaves_a_tilt():
    """``tilt=False`` fits the stretch and the shift alone: a squash along u comes back exactly; a tilt
    along u (the depth rising with the place across it) does not."""
    rng = np.random.default_rng(6)
    rest = rng.normal(size=(30, 3)) * 3.0
    u = np.array([0.0, 0.0, 1.0])
    squashed = rest + (-0.04 * rest[:, 2] + 0.3)[:, None] * u
    M = robust_depth_affine(rest, squashed[None], np.ones(30), u[None], scale=0.05, tilt=False)[0]
    np.testing.assert_allclose(squashed @ M[:3, :3].T + M[:3, 3], rest, atol=1e-12)
    tilted = rest + (0.05 * rest[:, 1])[:, None] * u
    M = robust_depth_affine(rest, tilted[None], np.ones(30), u[None], scale=np.inf, tilt=False)[0]
    assert np.abs(tilted @ M[:3, :3].T + M[:3, 3] - rest).max() > 0.1


def test_robust_depth_affine_takes_each_frame_along_its_own_direction():
    """Frames each tilted along its own line of sight (one of them along x, where the directions across it
    are made another way): each comes back, and a frame already in place is left exactly where it is."""
    rng = np.random.default_rng(8)
    rest = rng.normal(size=(25, 3)) * 2.0
    directions = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8], [-1.0, 0.0, 0.0]])  # the last: along x
    tilted = rest + (0.06 * rest[:, 1] - 0.1)[:, None] * directions[1]
    sideways = rest + (0.05 * rest[:, 2] - 0.03 * rest[:, 0] + 0.2)[:, None] * directions[2]
    M = robust_depth_affine(rest, np.stack([rest, tilted, sideways]), np.ones(25), directions, scale=0.05)
    np.testing.assert_allclose(M[0], np.eye(4), atol=1e-12)
    np.testing.assert_allclose(tilted @ M[1, :3, :3].T + M[1, :3, 3], rest, atol=1e-12)
    np.testing.assert_allclose(sideways @ M[2, :3, :3].T + M[2, :3, 3], rest, atol=1e-12)


def test_landmark_maps_respect_sides_and_symmetry():
    v = canonical_face().vertices
    table = feature_points()
    for point, index in FEATURE_POINT_LANDMARK.items():
        if index >= 468:
            continue
        side = table.sides[table.index(point)]
        x = v[index, 0]
        assert {"left": x > 0.1, "right": x < -0.1, "middle": abs(x) < 0.1}[side], point
    L = IBUG68_LANDMARK
    for a, b in [(36, 45), (39, 42), (17, 26), (21, 22), (48, 54), (31, 35), (60, 64), (0, 16), (4, 12)]:
        np.testing.assert_allclose(v[L[a]] * [-1, 1, 1], v[L[b]], atol=0.05)


def test_restabilise_keeps_only_expression_and_camera_positions():
    """A face opening its jaw and smiling, seen through a head frame that the expression tilted and
    shifted: fitted back onto its own rest over the skull's points, the expression is all that is left,
    and pose @ points is the same camera-space face."""
    rest = canonical_face().vertices
    expression = np.zeros((2, 468, 3))
    jaw = rest[:, 1] < -4.0                                  # the lower face, jaw points 136/365 included
    expression[1, jaw] = [0.0, -1.2, -0.6]
    expression[1, [61, 291, 205, 425]] += [0.0, 0.5, 0.2]    # lip corners and cheeks rise
    drift = np.eye(4)
    drift[:3, :3], drift[:3, 3] = 1.02 * rotation(0, 0.06), [0.0, 0.3, -0.1]  # how the fit was pulled
    seen = (rest + expression) @ drift[:3, :3].T + drift[:3, 3]
    pose = np.tile(np.eye(4), (2, 1, 1))
    pose[:, :3, 3] = [0.0, 0.0, -50.0]
    points, new_pose = restabilise(seen, pose, rest, np.array([True, True]))
    np.testing.assert_allclose(points - rest, expression, atol=1e-9)
    camera_before = np.einsum("tij,tlj->tli", pose[:, :3, :3], seen) + pose[:, None, :3, 3]
    camera_after = np.einsum("tij,tlj->tli", new_pose[:, :3, :3], points) + new_pose[:, None, :3, 3]
    np.testing.assert_allclose(camera_after, camera_before, atol=1e-9)


def test_jaw_depth_follows_the_chins_drop():
    """The jaw turns about its hinge; a tracker that sees its drop but only a third of its swing back
    gets the swing back, and motion the chin does not share (a smile) is left alone."""
    rest = canonical_face().vertices
    carried, chin, hinge = jaw_carried(rest)
    assert 152 in chin and 17 in carried and 17 not in chin  # the chin; the lower lip rides on the jaw too
    assert 13 not in carried and 1 not in carried            # not the upper lip, not the nose
    arm = rest - hinge
    share = _carried_share(np.asarray(rest))  # the jaw's share fades out beside and above what it carries
    assert (share[carried] > 0).all() and (share[chin] == 1).all() and share[13] == 0 and share[1] == 0
    turn = np.array([0.0, 0.05, 0.1, np.nan])  # radians; the last frame has no face
    opened = np.zeros((4, 468, 3))
    opened[:, :, 1] = -turn[:, None] * arm[:, 2] * share
    opened[:, :, 2] = turn[:, None] * arm[:, 1] * share
    seen = opened.copy()
    seen[..., 2] *= 1 / 3
    smile = np.zeros((468, 3))
    smile[[61, 291, 84, 17, 314], 1] = [0.4, 0.4, 0.2, 0.2, 0.2]  # on top: mouth corners and lower lip rise
    smile[[84, 17, 314], 2] = 0.1
    seen += smile
    seen[3] = np.nan
    expected = opened + smile
    corrected = correct_jaw_depth(rest, seen)
    np.testing.assert_allclose(corrected[:3], expected[:3], atol=1e-12)
    assert np.isnan(corrected[3]).all()
    assert corrected[2, 152, 2] < 0 and corrected[2, 152, 1] < 0  # the chin goes down and back


def test_head_angles_follow_mpeg4_words():
    # pitch about +X turns the face's forward (+Z) down (-Y); yaw about +Y turns it to its left (+X);
    # roll about +Z tilts its up (+Y) toward its right (-X)
    np.testing.assert_allclose((rotation(0, 0.2) @ [0, 0, 1])[1], -np.sin(0.2))
    np.testing.assert_allclose((rotation(1, 0.2) @ [0, 0, 1])[0], np.sin(0.2))
    np.testing.assert_allclose((rotation(2, 0.2) @ [0, 1, 0])[0], -np.sin(0.2))
    R = rotation(1, 0.3) @ rotation(0, -0.2) @ rotation(2, 0.1)
    np.testing.assert_allclose(head_angles(R[None])[0], [-0.2, 0.3, 0.1], atol=1e-12)


def test_the_canonical_face_and_landmark_tables_are_frozen():
    from faceanim.landmarks import FEATURE_POINT_LANDMARK

    face = canonical_face()
    for name in ("vertices", "triangles", "uv", "weights"):
        with pytest.raises(ValueError, match="read-only"):
            getattr(face, name)[0] = 0
    with pytest.raises(TypeError):
        FEATURE_POINT_LANDMARK["2.1"] = 0


def small_motion(displace: dict, frames=3):
    names = ("2.1", "2.2", "2.3", "8.3", "3.5", "3.6")
    neutral = np.zeros((len(names), 3))
    d = np.zeros((frames, len(names), 3))
    for name, vector in displace.items():
        d[1:, names.index(name)] = vector
    fapu = Fapu(irisd0=1.0, es0=6.0, ens0=4.0, mns0=2.0, mw0=5.0)
    return Motion(names, neutral, d, np.tile(np.eye(4), (frames, 1, 1)), 25.0, fapu)


def test_motion_to_faps_known_answers():
    table = fap_table()
    f = motion_to_faps(small_motion({"2.1": [0, -1.0, 0], "8.3": [0.5, 0, 0], "2.3": [0, -1.0, 0]}))
    assert f.values[1, table.number("open_jaw") - 1] == pytest.approx(512)          # 1 cm = MNS0/2 down
    assert f.values[1, table.number("stretch_l_cornerlip_o") - 1] == pytest.approx(102.4)  # MW0/10 outward
    # the lower lip rode down with the jaw: relative to the jaw it did not move
    assert f.values[1, table.number("raise_b_midlip") - 1] == pytest.approx(0)
    assert f.values[0].max() == 0 and f.mask[:, 2].all()
    gaze = motion_to_faps(small_motion({"3.5": [0.5 * EYEBALL_RADIUS_ES0 * 6.0, 0, 0]}))  # half the radius
    assert gaze.values[1, table.number("yaw_l_eyeball") - 1] == pytest.approx(np.arcsin(0.5) / 1e-5)


def test_clipping_counts_what_it_changes():
    f = motion_to_faps(small_motion({"2.1": [0, 1.0, 0]}))  # jaw up: below open_jaw's range
    clipped, count = clip_to_range(f)
    assert count == 2 and clipped.values[1, 2] == 0 and not clipped.out_of_range().any()


def test_one_euro_smooths_still_noise_and_follows_motion():
    rng = np.random.default_rng(2)
    t = np.arange(300) / 30.0
    still = rng.normal(scale=0.05, size=(300, 10, 3))
    assert jitter(one_euro(still, t), 30, np.ones(300, bool)) < 0.3 * jitter(still, 30, np.ones(300, bool))
    ramp = np.repeat((10 * t)[:, None, None], 3, axis=2)  # 10 cm/s
    lag_fast = np.abs(one_euro(ramp, t, OneEuro(beta=0.5)) - ramp)[150:].mean()
    lag_slow = np.abs(one_euro(ramp, t, OneEuro(beta=0.0)) - ramp)[150:].mean()
    assert lag_fast < 0.5 * lag_slow
    gap = still.copy()
    gap[100] = np.nan
    assert np.isnan(one_euro(gap, t)[100]).all() and np.isfinite(one_euro(gap, t)[101]).all()


def test_relaxed_window_finds_the_rest():
    rng = np.random.default_rng(3)
    T = 100
    points = np.zeros((T, 5, 3))
    points[:25] += np.sin(np.arange(25))[:, None, None]  # busy
    points[75:] += 2.0                                     # held expression; rest in between
    points += rng.normal(scale=0.01, size=points.shape)
    start, end = relaxed_window(points, np.ones(T, bool), 25.0, seconds=0.4)
    assert 25 <= start and end <= 75
    assert parse_neutral("10:20", 100) == (10, 20) and parse_neutral("5", 100) == (5, 6)
    assert parse_neutral("face.png", 100) == "face.png"
    with pytest.raises(InputError, match=r"--neutral 90:120: frames must lie in \[0, 100\)"):
        parse_neutral("90:120", 100)


def test_short_gaps_are_filled_and_flagged_long_ones_reported(tmp_path):
    from faceanim.capture.track import Track, fill_gaps

    T = 40
    face = np.random.default_rng(5).random((478, 3)) * 0.1  # a face's spread (a flat one is refused at load)
    landmarks = np.repeat(np.linspace(0, 1, T)[:, None, None], 3, axis=2) + face
    valid = np.ones(T, bool)
    valid[[5, 6]] = False          # 2 frames: short
    valid[20:32] = False           # 12 frames at 25 fps: longer than 0.2 s
    landmarks[~valid] = np.nan
    track = Track(landmarks, valid, np.zeros(T, bool), np.arange(T) / 25.0, 25.0, 64, 64, "synthetic")
    assert track.gaps() == [(5, 6), (20, 31)]
    filled = fill_gaps(track, max_gap=0.2)
    assert filled.filled.tolist() == [t in (5, 6) for t in range(T)]
    np.testing.assert_allclose(filled.landmarks[5:7, 0, 0], np.linspace(0, 1, T)[5:7] + face[0, 0])  # ramp restored
    assert filled.gaps() == [(20, 31)] and not filled.valid[5]
    filled.save(tmp_path / "t.npz")
    back = Track.load(tmp_path / "t.npz")
    np.testing.assert_array_equal(back.filled, filled.filled)
    (tmp_path / "bad.npz").write_bytes(b"not a track")
    with pytest.raises(InputError, match="bad.npz: is not a faceanim track"):
        Track.load(tmp_path / "bad.npz")


def test_option_bundles_reject_bad_settings():
    from faceanim.capture.tracker import TrackerOptions

    with pytest.raises(ValueError, match="min_cutoff must be positive, got 0"):
        OneEuro(min_cutoff=0)
    with pytest.raises(ValueError, match="beta must be positive, got -1"):
        OneEuro(beta=-1)
    with pytest.raises(ValueError, match="start_face must be one of largest, left, right, got 'middle'"):
        TrackerOptions(start_face="middle")
    with pytest.raises(ValueError, match="max_faces must be at least 1, got 0"):
        TrackerOptions(max_faces=0)
    with pytest.raises(KeyError, match="unknown FAPU 'XYZ'"):
        Fapu(1, 1, 1, 1, 1).unit("XYZ")
