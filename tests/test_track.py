"""The Track type: immutable and checked however it is made (Track.load's own checks are in
test_readers_fuzz.py)."""

import copy
import pickle

import numpy as np
import pytest

from faceanim.capture.track import Track, fill_gaps


def parts(T=3, L=4):
    rng = np.random.default_rng(0)
    landmarks = rng.random((T, L, 3))
    landmarks[1] = np.nan
    return dict(landmarks=landmarks, valid=np.array([True, False, True]), filled=np.zeros(T, bool),
                times=np.arange(T) / 25.0, fps=25.0, width=64, height=48, source="v.mp4",
                blendshapes=rng.random((T, 2)), blendshape_names=("jawOpen", "mouthSmile_L"))


def test_a_track_keeps_read_only_copies():
    given = parts()
    track = Track(**given)
    for name in ("landmarks", "valid", "filled", "times", "blendshapes"):
        assert not getattr(track, name).flags.writeable, name
        assert not np.shares_memory(getattr(track, name), given[name]), name
    with pytest.raises(ValueError, match="read-only"):
        track.landmarks[0] = 0
    given["valid"][1] = True  # the caller's arrays stay the caller's
    assert track.gaps() == [(1, 1)]
    filled = fill_gaps(track, max_gap=1.0)  # works on copies of its own
    assert filled.filled.tolist() == [False, True, False] and not filled.filled.flags.writeable
    for other in (pickle.loads(pickle.dumps(track)), copy.deepcopy(track)):
        assert not other.landmarks.flags.writeable
        np.testing.assert_array_equal(other.valid, track.valid)


@pytest.mark.parametrize("change, error, match", [
    (dict(landmarks=np.zeros((3, 4, 2))), ValueError, r"landmarks must have shape \(T, L, 3\), got \(3, 4, 2\)"),
    (dict(landmarks=np.zeros((0, 4, 3))), ValueError, "landmarks must have at least 1 entries, got 0"),
    (dict(landmarks=np.zeros((3, 0, 3))), ValueError, "landmarks must have at least 1 landmark per frame"),
    (dict(valid=np.ones(2, bool)), ValueError, r"valid must have shape \(3,\), got \(2,\)"),
    (dict(valid=np.array([1, 0.5, 1])), ValueError, r"valid must hold booleans \(or 0 and 1\), got 0.5"),
    (dict(filled=np.ones(3, bool)), ValueError, "filled must mark only frames without a face, got frame 0"),
    (dict(valid=np.ones(3, bool)), ValueError, "landmarks must be finite on frames with a face .* frame 1"),
    (dict(times=np.arange(4.0)), ValueError, r"times must have shape \(3,\), got \(4,\)"),
    (dict(times=[0, np.inf, 1]), ValueError, "times must be finite"),
    (dict(fps=0), ValueError, "fps must be a positive number, got 0"),
    (dict(fps=np.nan), ValueError, "fps must be a positive number, got nan"),
    (dict(width=0), ValueError, "width must be a whole number of pixels from 1 to 1048576, got 0"),
    (dict(height=10**300), ValueError, "height must be a whole number of pixels"),
    (dict(width=64.5), ValueError, "width must be a whole number of pixels"),
    (dict(source=None), TypeError, "source must be a str, got NoneType"),
    (dict(blendshapes=np.zeros((3, 3))), ValueError, r"blendshapes must have shape \(3, 2\), got \(3, 3\)"),
    (dict(blendshape_names=("a", 2)), TypeError, "blendshape_names must be strings"),
])
def test_a_track_made_directly_is_checked_naming_the_field(change, error, match):
    with pytest.raises(error, match=match):
        Track(**{**parts(), **change})


def test_whole_number_sizes_are_kept_as_ints():
    track = Track(**{**parts(), "width": np.int64(64), "height": 48.0})
    assert type(track.width) is int and type(track.height) is int and track.height == 48


def test_per_frame_rows_grow_in_one_array_with_nan_where_no_face_was():
    from faceanim.capture.track import _Rows

    rows = _Rows()
    rows.append(None)  # frames before the first face
    rows.append(None)
    for t in range(200):  # past the first capacity, so the array grows
        rows.append(None if t % 7 == 3 else np.full((4, 3), float(t)))
    kept = rows.array()
    assert kept.shape == (202, 4, 3) and not kept.flags.writeable and kept.base is None  # owned: taken uncopied
    assert np.isnan(kept[[0, 1, 5, 201]]).all() and (kept[2] == 0).all() and (kept[200] == 198).all()
    empty = _Rows()
    empty.append(None)
    assert empty.array() is None
