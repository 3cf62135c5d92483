"""Following a Motion onto a target directly (faceanim.retarget.follow)."""

import numpy as np
import pytest
from conftest import grid_mesh

from faceanim.errors import InputError
from faceanim.motion import Motion
from faceanim.mpeg4 import Fapu
from faceanim.retarget.follow import animate_motion, shared_points
from faceanim.target import Target

FAPU = Fapu(irisd0=1.0, es0=6.0, ens0=4.0, mns0=2.0, mw0=5.0)


def setting(count=10, frames=4, seed=0):
    """A grid target with ``count`` named control vertices, and a Motion of the same points seen in
    another frame: turned 30 degrees about y, twice the size, moved."""
    mesh = grid_mesh(8, 1.0)
    rng = np.random.default_rng(seed)
    ids = rng.choice(len(mesh.vertices), size=count, replace=False)
    names = tuple(f"mp{i}" for i in range(count))
    target = Target(mesh, dict(zip(names, (int(i) for i in ids), strict=True)), FAPU)
    c, s = np.cos(np.radians(30)), np.sin(np.radians(30))
    R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    neutral = 2.0 * mesh.vertices[ids] @ R.T + [1.0, -2.0, 3.0]
    displacements = rng.normal(scale=0.05, size=(frames, count, 3))
    motion = Motion(names, neutral, displacements, np.tile(np.eye(4), (frames, 1, 1)), 25.0, FAPU)
    return target, motion, ids, R


def test_control_points_move_by_the_motion_carried_into_the_target_frame():
    target, motion, ids, R = setting()
    animation = animate_motion(motion, target)
    expected = motion.displacements @ R / 2.0  # undo the turn (R^T applied to row vectors) and the size
    moved = animation.positions[:, ids] - target.mesh.vertices[ids]
    np.testing.assert_allclose(moved, expected, atol=1e-9)
    assert animation.fps == 25.0


def test_frames_without_a_face_hold_the_last_face_seen():
    target, motion, ids, _ = setting()
    d = motion.displacements.copy()
    d[[0, 2]] = np.nan
    valid = np.array([False, True, False, True])
    lost = Motion(motion.names, motion.neutral, d, motion.pose, motion.fps, motion.fapu, valid=valid)
    positions = animate_motion(lost, target).positions
    np.testing.assert_allclose(positions[0], target.mesh.vertices)  # rest before the first face
    np.testing.assert_allclose(positions[2], positions[1])
    assert not np.allclose(positions[3], positions[1])


def test_eyeball_points_do_not_drive_the_skin_and_too_few_points_are_refused():
    target, motion, _, _ = setting()
    pupil = Target(target.mesh, {**target.points, "3.5": 0, "mp470": 1}, FAPU)
    extra = Motion((*motion.names, "3.5", "mp470"), np.r_[motion.neutral, np.zeros((2, 3))],
                   np.concatenate([motion.displacements, np.ones((len(motion), 2, 3))], axis=1), motion.pose,
                   motion.fps, FAPU)
    assert shared_points(extra, pupil) == motion.names
    few = Target(target.mesh, dict(list(target.points.items())[:5]), FAPU)
    with pytest.raises(InputError, match="share 5 control points; at least 8 are needed"):
        animate_motion(motion, few)


def test_head_motion_turns_the_target_about_its_own_axes():
    target, motion, ids, R = setting(frames=2)
    c, s = np.cos(np.radians(10)), np.sin(np.radians(10))
    pitch = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    pose = np.tile(np.eye(4), (2, 1, 1))
    pose[1, :3, :3] = pitch  # the head pitches 10 degrees about the motion's own x axis
    still = Motion(motion.names, motion.neutral, np.zeros_like(motion.displacements), pose, 25.0, FAPU)
    positions = animate_motion(still, target, head_motion=True, pivot=np.zeros(3)).positions
    np.testing.assert_allclose(positions[0], target.mesh.vertices, atol=1e-12)
    # the motion's frame is the target's turned by R, so the target turns by R^T pitch R
    np.testing.assert_allclose(positions[1], target.mesh.vertices @ (R.T @ pitch @ R).T, atol=1e-9)


def test_a_streamed_motion_with_gaps_moves_the_target_as_the_held_one_does():
    """The carried controls are read by runs of frames: a run that starts inside a gap must show the
    last face before it, however far back (here across several of the deformer's 32-frame chunks)."""
    target, motion, ids, _ = setting(frames=120, seed=1)
    d = motion.displacements.copy()
    valid = np.ones(120, bool)
    valid[:3] = valid[30:100] = valid[117:] = False
    d[~valid] = np.nan
    held = Motion(motion.names, motion.neutral, d, motion.pose, motion.fps, motion.fapu, valid=valid)
    read = []

    def frames(a, b):
        read.append((a, b))
        return d[a:b]

    streamed = Motion.streamed(motion.names, motion.neutral, frames, motion.pose, motion.fps, motion.fapu, valid=valid)
    expected = animate_motion(held, target).positions
    animation = animate_motion(streamed, target)
    for a, b in ((0, 5), (40, 41), (64, 96), (95, 110), (117, 120), (0, 120)):
        # (runs of 16 frames or more go through the float32 operator: equal to 1e-7 of the unit)
        np.testing.assert_allclose(animation.chunk(a, b), expected[a:b], atol=1e-7)
    np.testing.assert_allclose(expected[64], expected[29], atol=1e-7)  # deep in the gap: frame 29's face (float32)
    assert max(b - a for a, b in read) <= 1024  # read by runs, never the whole motion at once
