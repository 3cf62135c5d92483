"""The blink's coupling taken out of the capture (faceanim.capture.blinkcoupling): the eyes' closure read
from the lids, the move taken out per eye and in proportion, the packaged table, and the capture
applying it on a real video exactly as the table says."""

import numpy as np
import pytest
from conftest import shared

from faceanim.capture import blinkcoupling
from faceanim.capture.blinkcoupling import MIDDLE_LIDS, OPEN_BELOW, BlinkCoupling, closure, coupling_field, shutting
from faceanim.capture.headframe import track_to_motion
from faceanim.landmarks import EYE_LIDS
from faceanim.mpeg4 import Fapu

(LEFT_UP, LEFT_DOWN), (RIGHT_UP, RIGHT_DOWN) = MIDDLE_LIDS
LIDS = sorted({p for upper, lower in EYE_LIDS.values() for p in upper + lower})


def _face(points=478):
    """A neutral whose middle lid points are 1 cm apart on both eyes."""
    neutral = np.random.default_rng(0).normal(size=(points, 3))
    for up, down in MIDDLE_LIDS:
        neutral[down] = neutral[up] - [0.0, 1.0, 0.0]
    return neutral


def test_an_eye_is_as_shut_as_its_lids_have_closed_clipped_to_0_and_1():
    neutral = _face()
    moved = np.zeros((4, 478, 3))
    moved[1, LEFT_UP, 1] = -0.6  # the left upper lid 0.6 of the way down
    moved[2, LEFT_UP, 1], moved[2, LEFT_DOWN, 1] = -0.8, 0.2  # the left eye shut, the lids meeting
    moved[2, RIGHT_UP, 1] = -1.3  # the right upper lid past the lower
    moved[3, [LEFT_UP, RIGHT_UP], 1] = 0.3  # both eyes opened wider than at rest
    np.testing.assert_allclose(closure(moved, neutral), [[0, 0], [0.6, 0], [1, 1], [0, 0]], atol=1e-12)


def test_an_eye_counts_as_open_up_to_the_lids_jitter_and_shuts_fully_at_1():
    np.testing.assert_allclose(shutting(np.array([0.0, OPEN_BELOW, (1 + OPEN_BELOW) / 2, 1.0])), [0, 0, 0.5, 1])


def test_each_eye_takes_out_its_own_move_in_proportion_to_its_closure_and_no_more():
    neutral = _face()
    field = np.random.default_rng(1).normal(size=(2, 468, 3))
    coupling = BlinkCoupling(neutral, field, es0=6.0)
    moved = np.zeros((3, 478, 3))
    moved[1, LEFT_UP, 1] = -0.5  # left eye half shut, right open
    moved[2, :] = np.nan  # a frame without a face
    given = moved.copy()
    coupling.apply(moved, 0)
    np.testing.assert_array_equal(moved[0], given[0])  # eyes open: nothing taken out
    expected = given[1].copy()
    expected[:468] -= 6.0 * (0.5 - OPEN_BELOW) / (1 - OPEN_BELOW) * field[0]
    others = np.setdiff1d(np.arange(478), LIDS)  # a lid's move may be held back (the next test)
    np.testing.assert_allclose(moved[1, others], expected[others], atol=1e-12)
    np.testing.assert_array_equal(moved[1, 468:], 0.0)  # the irises move with the eyeballs, not the mesh
    assert np.isnan(moved[2]).all()


def test_the_packaged_table_covers_the_face_mesh_and_a_layout_without_it_is_left_alone():
    table = coupling_field()
    assert table.shape == (2, 468, 3) and np.isfinite(table).all()
    assert np.abs(table).max() > 0  # learned, not a placeholder of zeros
    fapu = Fapu(irisd0=1.0, es0=6.0, ens0=4.0, mns0=3.0, mw0=5.0)
    assert BlinkCoupling.of_face(np.zeros((68, 3)), fapu) is None
    with pytest.raises(ValueError, match="es0"):
        BlinkCoupling(_face(), table, es0=0.0)


def test_the_capture_takes_out_exactly_the_tables_move_at_the_tracked_closure(monkeypatch):
    from faceanim.capture.track import track_video

    track = track_video(shared("videos", "d0.mp4"), progress=False)  # d0 blinks once
    monkeypatch.setattr(blinkcoupling, "coupling_field", lambda: np.zeros((2, 468, 3)))
    without = track_to_motion(track, floor=False)  # the noise floor after the table is not linear
    table = np.random.default_rng(2).normal(scale=0.01, size=(2, 468, 3))
    monkeypatch.setattr(blinkcoupling, "coupling_field", lambda: table)
    with_table = track_to_motion(track, floor=False)
    moved = np.asarray(without.displacements)
    shut = np.nan_to_num(shutting(closure(moved, without.neutral)))
    assert shut.max() > 0.5  # the blink is there to take the move out of
    expected = moved.copy()
    expected[:, :468] -= without.fapu.es0 * np.einsum("tk,klc->tlc", shut, table)
    others = np.setdiff1d(np.arange(moved.shape[1]), LIDS)  # the lids' moves may be held where they meet
    np.testing.assert_allclose(np.asarray(with_table.displacements)[:, others], expected[:, others], atol=1e-12,
                               equal_nan=True)


def test_taking_the_move_out_never_brings_a_pair_of_lids_past_each_other():
    neutral = _face()
    field = np.zeros((2, 468, 3))
    # the table is subtracted: at a shut left eye this takes the upper lid 0.5 cm up and the lower 1 cm down
    field[0, LEFT_UP, 1], field[0, LEFT_DOWN, 1] = -0.5 / 6.0, 1.0 / 6.0
    moved = np.zeros((2, 478, 3))
    moved[:, LEFT_UP, 1] = -0.9  # the left eye 0.9 shut (gap 0.1 cm)
    apart = moved.copy()
    BlinkCoupling(neutral, field, es0=6.0).apply(apart, 0)
    assert apart[0, LEFT_DOWN, 1] < -0.5  # moves that open the eye are taken out in full
    field = -field  # now both moves close the eye, by far more than its 0.1 cm gap
    shut = moved.copy()
    BlinkCoupling(neutral, field, es0=6.0).apply(shut, 0)
    gap = (neutral[LEFT_UP, 1] + shut[:, LEFT_UP, 1]) - (neutral[LEFT_DOWN, 1] + shut[:, LEFT_DOWN, 1])
    np.testing.assert_allclose(gap, 0.0, atol=1e-12)  # held where they meet
    rise, fall = shut[0, LEFT_DOWN, 1] - moved[0, LEFT_DOWN, 1], moved[0, LEFT_UP, 1] - shut[0, LEFT_UP, 1]
    assert rise > 0 and fall > 0 and rise == pytest.approx(2 * fall)  # both held back in proportion
