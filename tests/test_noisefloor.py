"""The capture's noise floor (faceanim.capture.noisefloor): the garrote's known values, the points it
leaves alone (lips, irises), a floor in the face's own yardstick, the capture applying it last on a real
video or not when asked, and which jobs ask."""

import numpy as np
import pytest
from conftest import shared

from faceanim.capture.headframe import unscored_drives
from faceanim.capture.noisefloor import NOISE_FLOOR, NoiseFloor, garrote
from faceanim.landmarks import LIP_BETWEEN, LIP_INNER, LIP_OUTER
from faceanim.mpeg4 import Fapu

LIPS = sorted(set(LIP_OUTER + LIP_INNER + LIP_BETWEEN))


def _fapu(es0=6.0, unit=1.0):
    return Fapu(irisd0=1.0 * unit, es0=es0 * unit, ens0=4.0 * unit, mns0=3.0 * unit, mw0=5.0 * unit)


def test_the_garrote_drops_what_is_under_the_floor_and_shortens_the_rest_by_tau_squared_over_length():
    d = np.array([[0.05, 0.0, 0.0], [0.0, 0.0, -0.1], [0.3, 0.4, 0.0], [np.nan, 0.0, 0.0], [0.0, 0.0, 0.0]])
    out = garrote(d, 0.1)
    np.testing.assert_array_equal(out[[0, 1, 4]], 0.0)  # under the floor and on it: nothing
    np.testing.assert_allclose(out[2], [0.288, 0.384, 0.0], rtol=1e-14)  # |d| = 0.5 becomes 0.5 - 0.1^2 / 0.5
    assert np.isnan(out[3]).all()  # a frame without a face stays without one
    lengths = np.linspace(0.1, 0.11, 50)[:, None] * [[0.6, 0.0, 0.8]]
    assert np.abs(np.diff(np.linalg.norm(garrote(lengths, 0.1), axis=1))).max() < 1e-3  # no jump past the floor
    np.testing.assert_array_equal(garrote(d[:3], 0.0), d[:3])  # no floor, nothing dropped


def test_the_lips_red_is_every_face_mesh_point_inside_the_outer_contour_and_on_neither_contour():
    from skimage.measure import points_in_poly

    from faceanim.capture.metric import canonical_face

    face = canonical_face().vertices[:468]
    inside = np.flatnonzero(points_in_poly(face[:, :2], face[list(LIP_OUTER), :2]))
    assert LIP_BETWEEN == tuple(sorted(set(inside) - set(LIP_OUTER) - set(LIP_INNER)))


def test_the_lips_and_irises_stay_as_tracked_and_every_other_point_is_shrunk():
    assert len(LIPS) == 80  # the two contours and the red between them
    rng = np.random.default_rng(0)
    moved = rng.normal(scale=0.08, size=(5, 478, 3))
    given = moved.copy()
    NoiseFloor(0.1).apply(moved, 0)
    np.testing.assert_array_equal(moved[:, LIPS], given[:, LIPS])
    np.testing.assert_array_equal(moved[:, 468:], given[:, 468:])
    others = np.setdiff1d(np.arange(468), LIPS)
    short = np.linalg.norm(given[:, others], axis=-1) <= 0.1
    assert short.any() and (~short).any()
    np.testing.assert_array_equal(moved[:, others][short], 0.0)
    kept = np.linalg.norm(moved[:, others][~short], axis=-1) / np.linalg.norm(given[:, others][~short], axis=-1)
    assert (kept > 0).all() and (kept < 1).all()  # shortened, never lengthened nor turned round
    np.testing.assert_allclose(np.cross(moved[:, others][~short], given[:, others][~short]), 0.0, atol=1e-15)


def test_the_floor_is_a_share_of_the_faces_es0_so_a_face_in_mm_or_m_loses_the_same_motion():
    moved_cm = np.random.default_rng(1).normal(scale=0.1, size=(3, 478, 3))
    kept = {}
    for unit in (1.0, 10.0, 0.01):  # cm, mm, m
        floor = NoiseFloor.of_face(np.zeros((478, 3)), _fapu(unit=unit))
        assert floor.tau == pytest.approx(NOISE_FLOOR * 6.0 * unit)
        kept[unit] = floor.apply(moved_cm * unit, 0) / unit
    np.testing.assert_allclose(kept[10.0], kept[1.0], atol=1e-12)
    np.testing.assert_allclose(kept[0.01], kept[1.0], atol=1e-12)


@pytest.mark.parametrize("tau", [-0.1, np.nan, np.inf])
def test_a_floor_that_is_no_length_is_refused_naming_tau(tau):
    with pytest.raises(ValueError, match="tau must be a finite length >= 0"):
        NoiseFloor(tau)
    with pytest.raises(ValueError, match="tau must be a finite length >= 0"):
        garrote(np.zeros((2, 3)), tau)


def test_a_floor_that_is_not_a_number_is_refused_naming_tau():
    with pytest.raises(TypeError, match="tau must be a number"):
        NoiseFloor(None)


def test_the_floor_comes_last_among_the_drives_and_not_for_a_layout_without_the_face_mesh():
    assert NoiseFloor.of_face(np.zeros((68, 3)), _fapu()) is None
    kinds = [type(drive).__name__ for drive in unscored_drives(np.zeros((478, 3)), _fapu())]
    assert kinds == ["BlinkCoupling", "NoiseFloor"]  # after the blink's move is taken out
    assert [type(d).__name__ for d in unscored_drives(np.zeros((478, 3)), _fapu(), floor=False)] == ["BlinkCoupling"]


@pytest.fixture(scope="module")
def d18_track():
    from faceanim.capture.track import track_video

    return track_video(shared("videos", "d18.mp4"), progress=False)


def test_the_capture_applies_the_floor_last_held_or_streamed_and_not_when_asked(d18_track, tmp_path):
    from faceanim.capture.headframe import track_to_motion
    from faceanim.capture.stream import captured

    raw = track_to_motion(d18_track, floor=False)
    floored = track_to_motion(d18_track)
    expected = np.asarray(raw.displacements).copy()
    NoiseFloor(NOISE_FLOOR * raw.fapu.es0).apply(expected, 0)
    np.testing.assert_allclose(np.asarray(floored.displacements), expected, atol=1e-12, equal_nan=True)
    np.testing.assert_array_equal(floored.pose, raw.pose)  # the head's motion is not touched
    streamed = captured(d18_track, progress=False, folder=tmp_path).motion  # read back a run of frames at a time
    np.testing.assert_allclose(np.asarray(streamed.displacements), expected, atol=1e-5, equal_nan=True)
    unfloored = captured(d18_track, progress=False, folder=tmp_path, floor=False).motion
    np.testing.assert_allclose(np.asarray(unfloored.displacements), np.asarray(raw.displacements), atol=1e-5,
                               equal_nan=True)
    still = np.linalg.norm(expected[:, :468], axis=-1) == 0
    assert 0.05 < still.mean() < 0.95  # d18 moves: some points fall under the floor, not all


def test_a_job_has_the_floor_as_its_filter_says_unless_told(d18_track, tmp_path):
    from faceanim.capture.stream import captured
    from faceanim.inputs import captured_source

    saved = tmp_path / "d18.npz"
    d18_track.save(saved)

    def displacements(capture):
        return np.asarray(capture.motion.displacements)

    unfiltered = displacements(captured(d18_track, smoothing=None, progress=False, folder=tmp_path, floor=False))
    np.testing.assert_allclose(displacements(captured_source(saved, smoothing=False, folder=tmp_path)), unfiltered,
                               atol=1e-12, equal_nan=True)  # --no-filter: neither the filter nor the floor
    floored = displacements(captured(d18_track, smoothing=None, progress=False, folder=tmp_path))
    np.testing.assert_allclose(displacements(captured_source(saved, smoothing=False, folder=tmp_path, floor=True)),
                               floored, atol=1e-12, equal_nan=True)  # asked for, it is there without the filter
    assert not np.allclose(floored, unfiltered, equal_nan=True)


def test_the_speakers_commands_capture_without_the_floor(monkeypatch, tmp_path):
    from faceanim import speech

    asked = []

    def capture_motion(video, **options):
        asked.append(options.get("floor"))
        raise RuntimeError("stop here")

    monkeypatch.setattr(speech, "capture_motion", capture_motion)
    video = tmp_path / "v.mp4"
    video.write_bytes(b"")
    with pytest.raises(RuntimeError, match="stop here"):
        speech.build_speaker(video, tmp_path / "m.npz")
    assert asked == [False]
