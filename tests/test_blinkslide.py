"""The eyes' sideways slide in a blink: the scores' calibration, and what is taken out where."""

import numpy as np
import pytest

from faceanim.capture.blinkslide import EYE_CORNERS, FAR, NEAR, BlinkSlide
from faceanim.capture.browscores import BROWS
from faceanim.capture.metric import canonical_face
from faceanim.capture.scores import shut_eyes

NAMES = ("browInnerUp", "eyeBlinkLeft", "eyeBlinkRight")


def blinks(frames: int, left: float, right: float, rest: float = 0.2) -> np.ndarray:
    """(frames, 3) scores at ``rest``, the blinks at ``left`` and ``right`` from frame 30 on."""
    scores = np.full((frames, len(NAMES)), rest)
    scores[30:, 1], scores[30:, 2] = left, right
    return scores


def times(frames: int) -> np.ndarray:
    return np.arange(frames) / 25.0


def test_the_neutral_scores_are_the_rest_and_a_full_score_is_shut():
    shut = shut_eyes(blinks(80, 1.0, 0.6), NAMES, times(80), np.arange(10), smoothing=None)
    np.testing.assert_allclose(shut["Left"][:30], 0.0)
    np.testing.assert_allclose(shut["Left"][30:], 1.0)
    np.testing.assert_allclose(shut["Right"][30:], (0.6 - 0.2) / 0.8)


def test_a_blink_among_the_neutral_frames_does_not_move_the_rest():
    scores = blinks(80, 1.0, 1.0)
    scores[4] = 0.9  # one shut frame in the neutral window
    shut = shut_eyes(scores, NAMES, times(80), np.arange(10), smoothing=None)
    np.testing.assert_allclose(shut["Left"][30:], 1.0)


def test_without_a_neutral_the_rest_is_the_videos_low_scores_and_without_blink_scores_nothing():
    shut = shut_eyes(blinks(80, 1.0, 1.0), NAMES, times(80), None, smoothing=None)
    np.testing.assert_allclose(shut["Right"][:30], 0.0)
    np.testing.assert_allclose(shut["Right"][30:], 1.0)
    assert shut_eyes(blinks(80, 1.0, 1.0)[:, :1], NAMES[:1], times(80), None, smoothing=None) is None
    assert shut_eyes(None, NAMES, times(80), None, smoothing=None) is None


@pytest.fixture(scope="module")
def face():
    """MediaPipe's canonical face with 10 iris points at the eyes' centres (478 points, cm), its ES0
    (between the eyes' centres) and the centres."""
    mesh = canonical_face().vertices
    centres = {side: mesh[list(ids)].mean(axis=0) for side, ids in EYE_CORNERS.items()}
    rest = np.vstack([mesh, np.repeat([centres["Right"], centres["Left"]], 5, axis=0)])
    return rest, float(np.linalg.norm(centres["Left"] - centres["Right"])), centres


def test_a_shut_eye_takes_out_the_slide_near_it_only_and_leaves_height_and_depth(face):
    rest, es0, centres = face
    frames = 40
    slide = BlinkSlide.of_scores(blinks(frames, 1.0, 0.2), NAMES, times(frames), rest, es0, np.arange(10),
                                 smoothing=None)
    moved = np.full((frames, len(rest), 3), 0.3)
    out = slide.apply(moved.copy(), 0)
    np.testing.assert_array_equal(out[:, :, 1:], moved[:, :, 1:])  # heights and depths as tracked
    np.testing.assert_array_equal(out[:30], moved[:30])              # eyes open: nothing taken
    distance = np.linalg.norm(rest - centres["Left"], axis=1) / es0
    near, far = distance < NEAR, distance > FAR
    face_mesh = np.arange(len(rest)) < 468
    brows = np.zeros(len(rest), dtype=bool)
    brows[[p for side in BROWS.values() for contour in side for p in contour]] = True
    assert (near & face_mesh & ~brows).sum() > 20 and (~far & brows).any()  # brows within reach
    np.testing.assert_allclose(out[30:, near & face_mesh & ~brows, 0], 0.0, atol=1e-12)  # the left eye shut
    np.testing.assert_array_equal(out[30:, brows, 0], 0.3)  # the brows' sideways movement is their own
    right_far = (np.linalg.norm(rest - centres["Right"], axis=1) / es0 > FAR)
    np.testing.assert_array_equal(out[30:, far & right_far, 0], 0.3)               # far from both: as tracked
    between = ~near & ~far & right_far & face_mesh & ~brows
    assert between.any()
    assert np.all((out[30:, between, 0] > 0) & (out[30:, between, 0] < 0.3))       # a fall-off, not a seam
    assert len(rest) == 478
    np.testing.assert_array_equal(out[30:, 468:, 0], 0.3)                          # the irises follow the eyeballs


def test_a_frame_without_scores_and_a_later_block_are_handled_in_step(face):
    rest, es0, _ = face
    scores = blinks(60, 1.0, 1.0)
    scores[45] = np.nan
    slide = BlinkSlide.of_scores(scores, NAMES, times(60), rest, es0, np.arange(10), smoothing=None)
    whole = slide.apply(np.full((60, len(rest), 3), 0.3), 0)
    block = slide.apply(np.full((20, len(rest), 3), 0.3), 40)
    np.testing.assert_array_equal(block, whole[40:])
    np.testing.assert_array_equal(whole[45], 0.3)  # no scores: the frame as tracked
    assert whole[44, 263, 0] == 0.0


def test_the_capture_applies_the_brows_then_the_slide_and_the_brows_shut_eyes_are_the_slides(face):
    """Both capture paths take their drives from ``score_drives``: with brow and blink scores, the brows'
    drive and then the slide; the brows' damping reads the same calibrated eyes (neutral frames 0-9,
    the capture's filter) as the slide does."""
    from faceanim.capture.browscores import BrowDrive
    from faceanim.capture.headframe import DEFAULT_SMOOTHING, score_drives
    from faceanim.mpeg4.fapu import Fapu

    rest, es0, _ = face
    names = ("browDownLeft", "browDownRight", "browInnerUp", "browOuterUpLeft", "browOuterUpRight",
             "eyeBlinkLeft", "eyeBlinkRight")
    rng = np.random.default_rng(1)
    scores = np.clip(0.2 + 0.05 * rng.normal(size=(80, len(names))), 0, 1)
    scores[:, :5] = 0.05                  # the brows silent: their damping by the eyes applies everywhere
    scores[4, 5:] = 0.95                  # a blink inside the neutral window
    scores[40:60, 5] = 0.9
    fapu = Fapu(irisd0=1.0, es0=es0, ens0=4.0, mns0=2.0, mw0=5.0)
    drives = score_drives(scores, names, times(80), rest, fapu, np.ones(80, dtype=bool), (0, 10))
    assert [type(d) for d in drives] == [BrowDrive, BlinkSlide]
    brows, slide = drives
    expected = shut_eyes(scores, names, times(80), np.arange(10), smoothing=DEFAULT_SMOOTHING)
    np.testing.assert_allclose(slide.shut, np.stack([expected["Left"], expected["Right"]], axis=1))
    left = list(brows.points).index(BROWS["Left"][0][0])
    np.testing.assert_allclose(brows.shut[:, left], expected["Left"])
    assert expected["Left"][45] > 0.8 and expected["Left"][20] < 0.05  # the neutral's blink did not move the rest


def test_frames_filled_across_a_lost_face_keep_the_slide_of_the_frames_around_them(face):
    """Where the tracker lost the face for a few frames their landmarks are filled across the gap
    (``track.fill_short_gaps``) but they have no scores: the scores are filled the same way, so a
    blink's slide holds through the gap instead of coming back for those frames. Frames with a face
    past the last scored one hold its scores; a frame with no face at all is left without."""
    from faceanim.capture.headframe import score_drives
    from faceanim.capture.scores import scores_across_filled_frames
    from faceanim.mpeg4.fapu import Fapu

    rest, es0, _ = face
    scores = blinks(60, 1.0, 1.0)
    scores[40:43] = np.nan  # lost in the middle of the shut eyes, its landmarks filled
    scores[50] = np.nan     # a frame with no face at all
    scores[58:] = np.nan    # the face lost at the end
    usable = np.ones(60, dtype=bool)
    usable[50] = False  # the end's frames have landmarks (a saved track's own fill) but nothing to fill between
    fapu = Fapu(irisd0=1.0, es0=es0, ens0=4.0, mns0=2.0, mw0=5.0)
    (slide,) = score_drives(scores, NAMES, times(60), rest, fapu, usable, (0, 10), smoothing=None)
    moved = slide.apply(np.full((60, len(rest), 3), 0.3), 0)
    np.testing.assert_array_equal(moved[39:44, 263, 0], 0.0)  # shut through the gap: no slide at the corner
    np.testing.assert_array_equal(moved[50, 263, 0], 0.3)     # no face: the frame as given
    np.testing.assert_array_equal(moved[58:, 263, 0], 0.0)     # past the last scores: held shut

    ramp = np.c_[np.linspace(0.0, 1.0, 11)]
    ramp[3:6] = np.nan
    ramp[9:] = np.nan
    usable = np.ones(11, dtype=bool)
    usable[4] = False
    filled = scores_across_filled_frames(ramp, usable)
    np.testing.assert_allclose(filled[[3, 5], 0], [0.3, 0.5])  # linear across the gap
    assert np.isnan(filled[4, 0])  # no face
    np.testing.assert_allclose(filled[9:, 0], 0.8)  # held past the last
    assert np.isnan(ramp[3:6]).all() and scores_across_filled_frames(None, np.ones(11, dtype=bool)) is None
