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
