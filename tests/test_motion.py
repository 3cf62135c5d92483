"""The Motion type (immutable, checked however it is made) and FAPs that do not depend on its unit."""

import copy
import pickle

import numpy as np
import pytest

from faceanim.motion import EYEBALL_RADIUS_ES0, Motion, motion_to_faps
from faceanim.mpeg4 import Fapu, fap_table
from faceanim.mpeg4.fapu import HUMAN_ES0
from faceanim.parts import FaceParts
from faceanim.retarget.gaze import eye_rotations

FAPU_CM = Fapu(irisd0=1.1, es0=100 * HUMAN_ES0, ens0=4.0, mns0=2.5, mw0=5.0)


def parts(T=3, K=2):
    return dict(names=tuple(f"p{k}" for k in range(K)), neutral=np.zeros((K, 3)),
                displacements=np.zeros((T, K, 3)), pose=np.tile(np.eye(4), (T, 1, 1)), fps=25.0, fapu=FAPU_CM,
                valid=np.ones(T, bool))


def test_a_motion_keeps_read_only_copies():
    given = parts()
    motion = Motion(**given)
    for name in ("neutral", "displacements", "pose", "valid"):
        assert not getattr(motion, name).flags.writeable, name
        assert not np.shares_memory(getattr(motion, name), given[name]), name
    with pytest.raises(ValueError, match="read-only"):
        motion.displacements[0] += 1
    for other in (pickle.loads(pickle.dumps(motion)), copy.deepcopy(motion)):
        assert not other.displacements.flags.writeable and other.names == motion.names


@pytest.mark.parametrize("change, error, match", [
    (dict(names=("a", "a")), ValueError, "control point names must be distinct"),
    (dict(names=("a", 2)), TypeError, "names must be strings, got 2"),
    (dict(neutral=np.zeros((3, 3))), ValueError, r"neutral must have shape \(2, 3\), got \(3, 3\)"),
    (dict(displacements=np.zeros((3, 2, 2))), ValueError, r"displacements must have shape \(T, 2, 3\)"),
    (dict(pose=np.zeros((2, 4, 4))), ValueError, r"pose must have shape \(3, 4, 4\), got \(2, 4, 4\)"),
    (dict(valid=np.ones(4, bool)), ValueError, r"valid must have shape \(3,\), got \(4,\)"),
    (dict(valid=[1, 2, 1]), ValueError, r"valid must hold booleans \(or 0 and 1\), got 2"),
    (dict(displacements=np.full((3, 2, 3), np.nan)), ValueError, "displacements must be finite on valid frames"),
    (dict(fps=-1.0), ValueError, "fps must be a positive number, got -1.0"),
    (dict(fps="25"), ValueError, "fps must be a positive number, got '25'"),
    (dict(fapu=None), TypeError, "fapu must be a Fapu, got NoneType"),
])
def test_a_motion_made_directly_is_checked_naming_the_field(change, error, match):
    with pytest.raises(error, match=match):
        Motion(**{**parts(), **change})


def gaze_motion(metres_per_unit: float) -> Motion:
    """A face measured in centimetres, metres or millimetres: pupils turned, jaw dropped, head turned."""
    s = 0.01 / metres_per_unit  # model units per centimetre
    names = ("2.1", "2.2", "2.3", "8.3", "3.5", "3.6", "9.15")
    neutral = np.array([[0, -7, 1], [0, -4, 2], [0, -4.5, 2], [2.5, -4.2, 1.5], [3.15, 0, 0.5],
                        [-3.15, 0, 0.5], [0, -2, 3]]) * s
    d = np.zeros((3, len(names), 3))
    radius_cm = EYEBALL_RADIUS_ES0 * FAPU_CM.es0  # 1.2 cm on this face
    d[1, names.index("3.5")] = [0.5 * radius_cm, 0, 0]  # half the radius to the face's left: 30 degrees
    d[2, names.index("3.6")] = [0, -0.25 * radius_cm, 0]
    d[1:, names.index("2.1")] = [0, -1.0, 0]
    d[2, names.index("8.3")] = [0.4, 0.1, 0]
    pose = np.tile(np.eye(4), (3, 1, 1))
    c, sn = np.cos(0.2), np.sin(0.2)
    pose[2, :3, :3] = 1.7 * np.array([[c, 0, sn], [0, 1, 0], [-sn, 0, c]])  # a similarity, as tracking gives
    pose[:, :3, 3] = [1.0, 2.0, 40.0]
    pose[:, :3, 3] *= s
    fapu = Fapu(*(value * s for value in (FAPU_CM.irisd0, FAPU_CM.es0, FAPU_CM.ens0, FAPU_CM.mns0, FAPU_CM.mw0)))
    return Motion(names, neutral, d * s, pose, 25.0, fapu)


def test_faps_and_gaze_do_not_depend_on_the_unit():
    """The review's case: gaze assumed a 1.2 cm eyeball, so a face in metres looked 100 times less far.
    In ES0 terms the same face gives the same FAPs in centimetres, metres and millimetres, and the
    decoder turns the eyeballs by the same angles."""
    table = fap_table()
    streams = {unit: motion_to_faps(gaze_motion(unit)) for unit in (0.01, 1.0, 0.001)}
    cm = streams[0.01]
    yaw_l, pitch_r = table.number("yaw_l_eyeball") - 1, table.number("pitch_r_eyeball") - 1
    assert cm.values[1, yaw_l] == pytest.approx(np.arcsin(0.5) / 1e-5)  # 30 degrees
    assert cm.values[2, pitch_r] == pytest.approx(np.arcsin(0.25) / 1e-5)  # looking down is positive pitch
    assert cm.values[1, table.number("open_jaw") - 1] == pytest.approx(1024 / 2.5)
    assert cm.values[2, table.number("head_yaw") - 1] == pytest.approx(0.2 / 1e-5)
    axes = np.eye(3)
    for unit, stream in streams.items():
        np.testing.assert_allclose(stream.values, cm.values, rtol=1e-9, atol=1e-6, err_msg=f"{unit} m per unit")
        np.testing.assert_array_equal(stream.mask, cm.mask)
        s = 0.01 / unit
        face = FaceParts(np.zeros(1, np.int64), np.zeros(1), np.array([0, -2, -6.0]) * s, axes,
                         np.array([[3.15, 0, -0.7], [-3.15, 0, -0.7]]) * s)
        np.testing.assert_allclose(eye_rotations(stream, face), eye_rotations(cm, face), atol=1e-12)
    turned = eye_rotations(cm, face)[1, 0]
    np.testing.assert_allclose(turned @ [0, 0, 1], [0.5, 0, np.sqrt(0.75)], atol=1e-9)  # 30 degrees left
