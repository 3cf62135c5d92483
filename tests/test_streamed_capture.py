"""Capture streamed through disk (issue 20, memory flat in the video's length): the frame store reads
back what was written, a streamed Motion answers as a held one does, and the streamed capture of a
real video gives the motion the in-memory capture gives, to float32 precision."""

import os
import pickle

import numpy as np
import pytest
from conftest import shared

from faceanim.capture.headframe import track_to_motion
from faceanim.capture.smoothing import OneEuroFilter, one_euro
from faceanim.capture.stream import captured
from faceanim.capture.track import Track, fill_gaps, fill_short_gaps
from faceanim.framestore import FrameStore
from faceanim.motion import Motion, motion_to_faps
from faceanim.mpeg4 import Fapu


def test_a_frame_store_reads_back_what_it_holds_by_frame_run_and_selection():
    rng = np.random.default_rng(3)
    rows = rng.normal(size=(50, 7, 3)).astype(np.float32)
    with FrameStore((7, 3)) as store:
        store.append(rows[:20])
        for row in rows[20:]:
            store.append(row)
        store.append(None)
        assert store.shape == (51, 7, 3) and np.isnan(store[50]).all() and np.isnan(store[-1]).all()
        np.testing.assert_array_equal(store[5:17], rows[5:17])
        pick = np.array([44, 3, 4, 5, 3, 49, 0])  # unsorted, repeated, runs of consecutive frames
        np.testing.assert_array_equal(store[pick], rows[pick])
        store[10:12] = np.zeros((2, 7, 3))
        assert not store[10:12].any() and np.array_equal(store[12], rows[12])
        assert store[0:0].shape == (0, 7, 3)
        for bad in (slice(0, 10, 2), np.array([51]), 60, np.array([0.5])):
            with pytest.raises(IndexError):
                store[bad]
        with pytest.raises(ValueError, match=r"rows must have shape \(7, 3\)"):
            store.append(np.zeros((2, 3)))


def test_a_frame_store_leaves_no_file_behind(tmp_path):
    with FrameStore((4,), folder=tmp_path) as store:
        store.append(np.ones((1000, 4)))
        assert os.listdir(tmp_path) == []  # unlinked as it is made: no name in any folder
    assert os.listdir(tmp_path) == []  # the stores have no name in the folder


def test_a_reserved_frame_store_takes_rows_out_of_order_and_reads_unwritten_ones_as_zeros():
    """What the parallel deformation relies on: reserve the length, write runs in any order (as
    workers finish them), and read back exactly what was written; a reserve never shrinks the store."""
    rng = np.random.default_rng(3)
    rows = rng.normal(size=(10, 2, 3)).astype(np.float32)
    with FrameStore((2, 3)) as store:
        store.append(rows[:2])
        store.reserve(10)
        assert len(store) == 10 and store.shape == (10, 2, 3)
        np.testing.assert_array_equal(store[2:10], np.zeros((8, 2, 3)))
        for start in (8, 4, 2, 6):  # out of order
            store[start:start + 2] = rows[start:start + 2]
        np.testing.assert_array_equal(store[0:10], rows)
        with pytest.raises(ValueError, match="at least the 10 rows"):
            store.reserve(4)
        with pytest.raises(ValueError, match="whole number"):
            store.reserve(10.5)
        assert len(store) == 10


def test_the_filter_run_in_blocks_equals_the_filter_run_at_once():
    rng = np.random.default_rng(1)
    t = np.cumsum(rng.uniform(0.02, 0.05, 200))
    x = np.cumsum(rng.normal(size=(200, 5, 3)), axis=0)
    x[60:64] = np.nan  # a gap restarts the filter, across a block's edge too
    run = OneEuroFilter()
    blocks = [run(x[a:b], t[a:b]) for a, b in ((0, 61), (61, 62), (62, 150), (150, 200))]
    np.testing.assert_array_equal(np.concatenate(blocks), one_euro(x, t))


def test_short_gaps_are_filled_alike_in_an_array_and_in_a_store():
    rng = np.random.default_rng(2)
    landmarks = rng.random((30, 4, 3))
    valid = np.ones(30, bool)
    valid[[0, 5, 6, 12, 13, 14, 15, 16, 17, 29]] = False
    landmarks[~valid] = np.nan
    track = Track(landmarks, valid, np.zeros(30, bool), np.arange(30) / 25.0, 25.0, 64, 48)
    held = fill_gaps(track, max_gap=0.2)
    with FrameStore((4, 3)) as store:
        store.append(landmarks)
        filled = fill_short_gaps(store, valid, 25.0, 0.2)
        np.testing.assert_array_equal(filled, held.filled)
        assert filled.tolist().count(True) == 2  # frames 5-6; 12-17 is longer than 0.2 s; the ends stay
        np.testing.assert_allclose(store[0:30], held.landmarks, rtol=1e-6, atol=1e-7, equal_nan=True)


def _motion_pair():
    rng = np.random.default_rng(4)
    names = ("2.1", "8.3", "mp1", "3.5")
    neutral = rng.normal(size=(4, 3)) * 3
    d = rng.normal(size=(40, 4, 3)) * 0.1
    valid = np.ones(40, bool)
    valid[[3, 4, 20]] = False
    d[~valid] = np.nan
    pose = np.tile(np.eye(4), (40, 1, 1))
    fapu = Fapu(irisd0=1.2, es0=6.3, ens0=4.0, mns0=3.0, mw0=5.0)
    held = Motion(names, neutral, d, pose, 30.0, fapu, valid=valid)
    streamed = Motion.streamed(names, neutral, lambda a, b: d[a:b], pose, 30.0, fapu, valid=valid)
    return held, streamed


def test_a_streamed_motion_answers_as_a_held_one():
    held, streamed = _motion_pair()
    assert streamed.is_streamed and not held.is_streamed and len(streamed) == len(held) == 40
    np.testing.assert_array_equal(streamed.displacements, held.displacements)
    np.testing.assert_array_equal(streamed.points_over_time(["8.3", "2.1"]), held.displacements[:, [1, 0]])
    assert [s for s, _ in streamed.chunks(16)] == [0, 16, 32]
    a, b = motion_to_faps(held), motion_to_faps(streamed)
    np.testing.assert_array_equal(a.values, b.values)
    np.testing.assert_array_equal(a.mask, b.mask)
    with pytest.raises(TypeError, match="cannot be pickled"):
        pickle.dumps(streamed)
    again = pickle.loads(pickle.dumps(held))
    np.testing.assert_array_equal(again.displacements, held.displacements)
    assert not again.displacements.flags.writeable
    with pytest.raises(AttributeError, match="immutable"):
        held.fps = 10.0


def test_a_streamed_motion_checks_each_chunk_it_reads():
    held, _ = _motion_pair()
    broken = Motion.streamed(held.names, held.neutral, lambda a, b: np.full((b - a, 4, 3), np.nan), held.pose,
                             30.0, held.fapu, valid=held.valid)
    with pytest.raises(ValueError, match="finite on valid frames, got NaN or infinity on frame 0"):
        broken.chunk(0, 5)
    short = Motion.streamed(held.names, held.neutral, lambda a, b: np.zeros((1, 4, 3)), held.pose, 30.0, held.fapu)
    with pytest.raises(ValueError, match=r"made shape \(1, 4, 3\) for frames 0:5"):
        short.chunk(0, 5)
    with pytest.raises(IndexError, match="outside the motion's 0:40"):
        held.chunk(30, 41)


@pytest.mark.skipif(not shared("videos", "d6.mp4").exists(), reason="needs ../shared/data/videos/d6.mp4")
def test_the_streamed_capture_of_a_video_is_the_held_capture(tmp_path):
    from faceanim.capture.track import track_video

    track = track_video(shared("videos", "d6.mp4"), progress=False)
    held = track_to_motion(track)
    capture = captured(shared("videos", "d6.mp4"), progress=False, folder=tmp_path)
    motion = capture.motion
    assert motion.is_streamed and len(capture) == len(track)
    np.testing.assert_array_equal(capture.valid, track.valid)
    np.testing.assert_array_equal(capture.filled, track.filled)
    np.testing.assert_array_equal(capture.times, track.times)
    np.testing.assert_allclose(capture.landmarks[0:len(track)], track.landmarks, atol=1e-6, equal_nan=True)
    # float32 head-frame points on disk: 1e-6 cm on a face measured in centimetres
    np.testing.assert_allclose(motion.displacements, held.displacements, atol=1e-5, equal_nan=True)
    # the pose refitted from those float32 points: a float32's relative precision on its translation (cm)
    np.testing.assert_allclose(motion.pose, held.pose, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(motion.neutral, held.neutral, atol=1e-5)
    assert os.listdir(tmp_path) == []  # the stores have no name in the folder
    capture = captured(track, neutral=(10, 20), progress=False)
    np.testing.assert_allclose(capture.motion.displacements, track_to_motion(track, neutral=(10, 20)).displacements,
                               atol=1e-5, equal_nan=True)
