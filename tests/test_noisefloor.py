"""The capture's noise floor (faceanim.capture.noisefloor): the garrote's known values, the points it
leaves alone (lips, irises), a floor in the face's own yardstick, and the capture applying it last on a
real video, or not when asked."""

import numpy as np
import pytest
from conftest import shared

from faceanim.capture.headframe import unscored_drives
from faceanim.capture.noisefloor import NOISE_FLOOR, NoiseFloor, garrote
from faceanim.landmarks import LIP_INNER, LIP_OUTER
from faceanim.mpeg4 import Fapu

LIPS = sorted(set(LIP_OUTER + LIP_INNER))


def _fapu(es0=6.0, unit=1.0):
    return Fapu(irisd0=1.0 * unit, es0=es0 * unit, ens0=4.0 * unit, mns0=3.0 * unit, mw0=5.0 * unit)


def test_the_garrote_drops_what_is_under_the_floor_and_shortens_the_rest_by_floor_squared_over_length():
    d = np.array([[0.05, 0.0, 0.0], [0.0, 0.0, -0.1], [0.3, 0.4, 0.0], [np.nan, 0.0, 0.0], [0.0, 0.0, 0.0]])
    out = garrote(d, 0.1)
    np.testing.assert_array_equal(out[[0, 1, 4]], 0.0)  # under the floor and on it: nothing
    np.testing.assert_allclose(out[2], d[2] * (1 - 0.01 / 0.25), rtol=1e-15)  # |d| = 0.5: 0.5 - 0.02 long
    assert np.isnan(out[3]).all()  # a frame without a face stays without one
    lengths = np.linspace(0.1, 0.11, 50)[:, None] * [[0.6, 0.0, 0.8]]
    assert np.abs(np.diff(np.linalg.norm(garrote(lengths, 0.1), axis=1))).max() < 1e-3  # no jump past the floor


def test_the_floor_leaves_the_lips_and_irises_as_tracked_and_shrinks_every_other_point():
    floor = NoiseFloor(0.1)
    moved = np.random.default_rng(0).normal(scale=0.08, size=(5, 478, 3))
    given = moved.copy()
    floor.apply(moved, 0)
    np.testing.assert_array_equal(moved[:, LIPS], given[:, LIPS])
    np.testing.assert_array_equal(moved[:, 468:], given[:, 468:])
    others = np.setdiff1d(np.arange(468), LIPS)
    np.testing.assert_array_equal(moved[:, others], garrote(given[:, others], 0.1))
    assert (np.linalg.norm(moved[:, others], axis=-1) == 0).mean() > 0.3  # most of this noise is gone


def test_the_floor_is_a_share_of_the_faces_es0_so_a_face_in_mm_or_m_loses_the_same_motion():
    rng = np.random.default_rng(1)
    moved_cm = rng.normal(scale=0.1, size=(3, 478, 3))
    kept = {}
    for unit in (1.0, 10.0, 0.01):  # cm, mm, m
        floor = NoiseFloor.of_face(np.zeros((478, 3)), _fapu(unit=unit))
        assert floor.floor == pytest.approx(NOISE_FLOOR * 6.0 * unit)
        kept[unit] = floor.apply(moved_cm * unit, 0) / unit
    np.testing.assert_allclose(kept[10.0], kept[1.0], atol=1e-12)
    np.testing.assert_allclose(kept[0.01], kept[1.0], atol=1e-12)


def test_a_layout_without_the_face_mesh_has_no_floor_and_a_negative_floor_is_refused():
    assert NoiseFloor.of_face(np.zeros((68, 3)), _fapu()) is None
    with pytest.raises(ValueError, match="floor must be a finite length >= 0"):
        NoiseFloor(-0.1)
    kinds = [type(drive).__name__ for drive in unscored_drives(np.zeros((478, 3)), _fapu())]
    assert kinds == ["BlinkCoupling", "NoiseFloor"]  # the floor last, after the blink's move is taken out
    assert [type(d).__name__ for d in unscored_drives(np.zeros((478, 3)), _fapu(), floor=False)] == ["BlinkCoupling"]


def test_the_capture_applies_the_floor_last_and_not_when_asked(tmp_path):
    from faceanim.capture.headframe import track_to_motion
    from faceanim.capture.stream import captured
    from faceanim.capture.track import track_video

    track = track_video(shared("videos", "d18.mp4"), progress=False)
    raw = track_to_motion(track, floor=False)
    floored = track_to_motion(track)
    expected = np.asarray(raw.displacements).copy()
    NoiseFloor(NOISE_FLOOR * raw.fapu.es0).apply(expected, 0)
    np.testing.assert_allclose(np.asarray(floored.displacements), expected, atol=1e-12, equal_nan=True)
    np.testing.assert_array_equal(floored.pose, raw.pose)  # the head's motion is not touched
    streamed = captured(track, progress=False, folder=tmp_path).motion  # the streamed capture does the same
    np.testing.assert_allclose(np.asarray(streamed.displacements), expected, atol=1e-5, equal_nan=True)
    still = np.linalg.norm(expected[:, :468], axis=-1) == 0
    assert 0.05 < still.mean() < 0.95  # d18 moves: some points fall under the floor, not all
