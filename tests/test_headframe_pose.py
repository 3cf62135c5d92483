"""The head fit to the person's neutral on known answers: an expression's shift of the skull's
landmarks is not read as a turn of the head, and a real turn is (``capture/headframe.restabilise``)."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import faceanim.capture.headframe as headframe
from faceanim.capture.headframe import restabilise
from faceanim.capture.metric import canonical_face

# Forehead landmarks: the skull's landmarks a brow raise or a smile moves most on ICT renders of a
# still head (benchmarks/skull_shifts.py), MediaPipe's depth of them shifting by 1-4 mm.
FOREHEAD = [10, 67, 297, 54, 284]


def turn_of(pose: np.ndarray) -> float:
    """The whole angle (degrees) of the rotation in a similarity ``pose (4, 4)``."""
    linear = pose[:3, :3] / np.cbrt(np.linalg.det(pose[:3, :3]))
    return float(np.degrees(np.linalg.norm(Rotation.from_matrix(linear).as_rotvec())))


def fitted(frames: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """Each frame's pose after the refit to ``rest``, starting from the identity."""
    _, pose = restabilise(frames, np.tile(np.eye(4), (len(frames), 1, 1)), rest, np.ones(len(frames), bool))
    return pose


@pytest.fixture
def rest():
    return canonical_face().vertices[:468].copy()


def test_an_expressions_depth_shift_on_the_forehead_is_not_a_turn(rest):
    expressed = rest.copy()
    expressed[FOREHEAD, 2] += 0.3  # 3 mm forward, as a brow raise is seen
    pose = fitted(np.stack([rest, expressed]), rest)
    assert turn_of(pose[0]) < 1e-9
    robust = turn_of(pose[1])
    assert robust < 0.4  # degrees: the robust fit lets the carried-off points count less ...
    saved = headframe._SKULL_SPREAD
    try:
        headframe._SKULL_SPREAD = np.inf  # ... than every skull landmark at full weight: 1.1 degrees
        assert turn_of(fitted(np.stack([rest, expressed]), rest)[1]) > 3 * robust
    finally:
        headframe._SKULL_SPREAD = saved


def test_a_real_turn_comes_out_as_pose_with_or_without_an_expression(rest):
    R = Rotation.from_euler("xyz", [8.0, -15.0, 4.0], degrees=True).as_matrix()
    expressed = rest.copy()
    expressed[FOREHEAD, 2] += 0.3
    turned = np.stack([rest @ R.T + [1.0, -2.0, 0.5], expressed @ R.T + [1.0, -2.0, 0.5]])
    points, pose = restabilise(turned, np.tile(np.eye(4), (2, 1, 1)), rest, np.ones(2, bool))
    np.testing.assert_allclose(pose[0, :3, :3], R, atol=1e-9)  # exact without an expression
    np.testing.assert_allclose(points[0], rest, atol=1e-9)
    error = pose[1, :3, :3] @ R.T / np.cbrt(np.linalg.det(pose[1, :3, :3]))
    assert np.degrees(np.linalg.norm(Rotation.from_matrix(error).as_rotvec())) < 0.4
    # the head frame keeps the expression and nothing else: the chin stays put
    chin = 152
    assert np.linalg.norm(points[1, chin] - rest[chin]) < 0.06  # cm: 0.5 mm, the chin 12 cm below the nose bridge


def test_unview_takes_out_what_the_view_adds_and_nothing_at_the_rests_view(rest):
    from faceanim.capture.headframe import _view_table, unview, view_features

    turns = Rotation.from_euler("yx", [[0, 0], [0, 0], [18, 0], [-12, 8]], degrees=True).as_matrix()
    pose = np.tile(np.eye(4), (4, 1, 1))
    pose[:, :3, :3] = turns
    pose[:, :3, 3] = [0.0, 0.0, -50.0]  # the camera 50 cm in front of the face
    features = view_features(pose)
    np.testing.assert_allclose(features[0], 0.0, atol=1e-12)  # seen from straight ahead
    assert features[2, 0] < -0.25 and abs(features[3, 1]) > 0.1  # a turn is seen as one
    table = _view_table().reshape(5, -1, 3)[:, :468]
    added = np.einsum("tf,flc->tlc", features - features[:2].mean(axis=0), table)
    seen = rest[None] + added
    unview(seen, pose, np.ones(4, bool), at_rest=[0, 1])
    np.testing.assert_allclose(seen, np.broadcast_to(rest, seen.shape), atol=1e-12)
    assert np.abs(added[2:]).max() > 0.05  # cm: the correction is not nothing


def test_a_fast_real_turn_is_followed_by_the_filtered_pose_without_lagging(rest):
    from faceanim.capture.headframe import head_frame_into

    fps, T = 25.0, 40
    times = np.arange(T) / fps
    yaw = 20.0 * np.sin(np.linspace(0, np.pi, T))  # a turn to 20 degrees and back in 1.6 s
    distance = 45.0
    landmarks = np.empty((T, 468, 3))
    for t in range(T):
        turned = rest @ Rotation.from_euler("y", yaw[t], degrees=True).as_matrix().T
        depth = distance - turned[:, 2]
        landmarks[t, :, 0] = 0.5 + 1.2 * turned[:, 0] / depth  # a perspective view, normalised
        landmarks[t, :, 1] = 0.5 - 1.2 * turned[:, 1] / depth
        landmarks[t, :, 2] = -turned[:, 2] * 1.2 / distance
    read = {}
    for name, smoothing in (("raw", None), ("filtered", headframe.DEFAULT_SMOOTHING)):
        points, pose = np.empty((T, 468, 3)), np.empty((T, 4, 4))
        head_frame_into(landmarks, np.ones(T, bool), times, 512, 512, points, pose, smoothing)
        linear = pose[:, :3, :3] / np.cbrt(np.linalg.det(pose[:, :3, :3]))[:, None, None]
        read[name] = Rotation.from_matrix(linear).as_euler("yxz", degrees=True)[:, 0]
    rising = slice(3, T // 2)  # the filter's lag shows while the head turns fastest
    assert np.abs(read["filtered"][rising] - read["raw"][rising]).max() < 2.0  # degrees: 1.4 (3.2 at a fixed cut-off)
