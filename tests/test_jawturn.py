"""The jaw's turning centre and turns fitted to the chin's control points (faceanim.retarget.jawturn)."""

import numpy as np
import pytest

from faceanim.parts import FaceParts
from faceanim.retarget.jawturn import fitted_jaw_turns

MOUTH_WIDTH = 5.0


def _parts(rest, jaw_weight, hinge):
    return FaceParts(np.zeros(len(rest), dtype=np.int64), jaw_weight, hinge, np.eye(3), np.zeros((2, 3)))


def _turned(points, centre, angle):
    """``points`` turned about the x axis through ``centre``: opening (the chin down and back) positive."""
    c, s = np.cos(angle), np.sin(angle)
    r = points - centre
    return np.c_[r[:, 0], c * r[:, 1] - s * r[:, 2], s * r[:, 1] + c * r[:, 2]] + centre


@pytest.fixture
def chin():
    """A chin of 12 points (a patch 4 cm wide, 3 tall, curving back) below a lower lip at y = -4."""
    x, y = np.meshgrid(np.linspace(-2, 2, 4), np.linspace(-8, -5, 3))
    x, y = x.ravel(), y.ravel()
    return np.c_[x, y, 9.0 - 0.1 * x ** 2 - 0.2 * (y + 6.5) ** 2]


def test_a_rigid_turn_gives_back_its_centre_and_angles(chin):
    rest = np.vstack([chin, [[0.0, -4.0, 11.0]]])  # and a lip point, which must be left out
    true_centre = np.array([0.0, -1.5, 2.3])
    angles = np.r_[np.linspace(0.0, 0.45, 20), np.linspace(0.45, 0.05, 10)]
    moved = np.stack([np.vstack([_turned(chin, true_centre, a), rest[-1:] + [0.0, 0.3, 0.5]]) for a in angles])
    parts = _parts(rest, np.ones(len(rest)), hinge=np.array([0.0, -3.5, 4.0]))  # a guess 2.6 cm off

    turns = fitted_jaw_turns(parts, rest, np.arange(len(rest)), moved - rest, mouth_width=MOUTH_WIDTH,
                             below=rest[-1])

    assert turns is not None
    np.testing.assert_allclose(turns.centre[1:], true_centre[1:], atol=0.05)
    np.testing.assert_allclose(turns.angles, angles, atol=2e-3)


def test_the_turns_are_clipped_and_streamed_motion_gives_the_same(chin):
    true_centre = np.array([0.0, -1.0, 3.0])
    angles = np.linspace(0.0, 0.8, 40)
    displacements = np.stack([_turned(chin, true_centre, a) for a in angles]) - chin
    parts = _parts(chin, np.ones(len(chin)), hinge=np.array([0.0, -3.0, 4.0]))

    class Streamed:  # read by runs of frames, as a streamed capture's controls are
        def __len__(self):
            return len(displacements)

        def __getitem__(self, key):
            return displacements[key]

    whole = fitted_jaw_turns(parts, chin, np.arange(len(chin)), displacements, mouth_width=MOUTH_WIDTH,
                             limits=(-0.05, 0.6))
    streamed = fitted_jaw_turns(parts, chin, np.arange(len(chin)), Streamed(), mouth_width=MOUTH_WIDTH,
                                limits=(-0.05, 0.6))
    assert whole.angles.max() == pytest.approx(0.6)
    np.testing.assert_allclose(streamed.angles, whole.angles)
    np.testing.assert_allclose(streamed.centre, whole.centre)


def test_a_still_chin_or_too_few_points_on_the_jaw_say_nothing(chin):
    parts = _parts(chin, np.ones(len(chin)), hinge=np.array([0.0, -3.0, 4.0]))
    still = np.full((10, len(chin), 3), 0.001)
    assert fitted_jaw_turns(parts, chin, np.arange(len(chin)), still, mouth_width=MOUTH_WIDTH) is None

    opening = np.stack([_turned(chin, np.array([0.0, -1.0, 3.0]), a) for a in (0.0, 0.3)]) - chin
    weak = np.where(np.arange(len(chin)) < 2, 1.0, 0.5)  # only two points follow the jaw fully
    assert fitted_jaw_turns(_parts(chin, weak, parts.hinge), chin, np.arange(len(chin)), opening,
                            mouth_width=MOUTH_WIDTH) is None


def test_the_centre_stays_between_the_guess_and_the_condyles(chin):
    """A chin turning about a centre in front of and below the parts' guess (skin that stretches as it
    turns reads so) moves the centre no further down or forward than a tenth of the mouth's width."""
    guess = np.array([0.0, -3.0, 4.0])
    ahead = np.array([0.0, -5.0, 6.0])  # 2 cm below and 2 cm in front of the guess
    displacements = np.stack([_turned(chin, ahead, a) for a in np.linspace(0.0, 0.4, 20)]) - chin
    turns = fitted_jaw_turns(_parts(chin, np.ones(len(chin)), guess), chin, np.arange(len(chin)), displacements,
                             mouth_width=MOUTH_WIDTH)
    shift = turns.centre - guess
    np.testing.assert_allclose(shift[1:], [-0.1 * MOUTH_WIDTH, 0.1 * MOUTH_WIDTH])  # as far down and forward as allowed


def test_pinned_points_and_frames_without_a_face_are_left_out(chin):
    """Points a FAP stream pins (never moving) are not taken as on the jaw, and a NaN frame gets a NaN turn
    without spoiling the others' fit; with only two points left that move, nothing is fitted."""
    true_centre = np.array([0.0, -1.5, 2.3])
    angles = np.linspace(0.0, 0.4, 25)
    displacements = np.stack([_turned(chin, true_centre, a) for a in angles]) - chin
    displacements[:, :4] = 0.0  # four points pinned
    displacements[7] = np.nan
    parts = _parts(chin, np.ones(len(chin)), hinge=np.array([0.0, -3.5, 4.0]))
    turns = fitted_jaw_turns(parts, chin, np.arange(len(chin)), displacements, mouth_width=MOUTH_WIDTH)
    np.testing.assert_allclose(turns.centre[1:], true_centre[1:], atol=0.05)
    assert np.isnan(turns.angles[7])
    np.testing.assert_allclose(np.delete(turns.angles, 7), np.delete(angles, 7), atol=2e-3)
    displacements[:, 4:-2] = 0.0
    assert fitted_jaw_turns(parts, chin, np.arange(len(chin)), displacements, mouth_width=MOUTH_WIDTH) is None


def test_a_motion_read_in_small_runs_gives_what_it_gives_whole(chin, monkeypatch):
    """The size ranking, the widest frames and the turns are read a run of frames at a time: runs of 7 frames
    over a noisy motion of 100 give the fit the whole array gives."""
    from faceanim.retarget import jawturn

    rng = np.random.default_rng(5)
    angles = 0.3 * np.abs(np.sin(np.arange(100) / 9.0))
    displacements = (np.stack([_turned(chin, np.array([0.0, -1.0, 3.0]), a) for a in angles]) - chin
                     + rng.normal(scale=0.02, size=(100, len(chin), 3)))
    parts = _parts(chin, np.ones(len(chin)), hinge=np.array([0.0, -3.0, 4.0]))
    whole = fitted_jaw_turns(parts, chin, np.arange(len(chin)), displacements, mouth_width=MOUTH_WIDTH)

    class Streamed:
        def __len__(self):
            return len(displacements)

        def __getitem__(self, key):
            return displacements[key]

    monkeypatch.setattr(jawturn, "_CHUNK", 7)
    monkeypatch.setattr(jawturn, "_FITTED_FRAMES", 30)  # not all of them: which 30 must not depend on the runs
    runs = fitted_jaw_turns(parts, chin, np.arange(len(chin)), Streamed(), mouth_width=MOUTH_WIDTH)
    monkeypatch.setattr(jawturn, "_CHUNK", 1024)
    array = fitted_jaw_turns(parts, chin, np.arange(len(chin)), displacements, mouth_width=MOUTH_WIDTH)
    np.testing.assert_allclose(runs.centre, array.centre)
    np.testing.assert_allclose(runs.angles, array.angles)
    assert not np.allclose(array.centre, whole.centre)  # the 30 widest frames are not all 100
