"""Brows from the Face Landmarker's scores: calibration against the neutral, the heights, what is kept."""

import numpy as np

from faceanim.capture.browscores import BROWS, LOWER, RAISE, TRACKED_SHARE, BrowDrive

NAMES = ("browDownLeft", "browDownRight", "browInnerUp", "browOuterUpLeft", "browOuterUpRight", "jawOpen")


def scores_over(frames: int, **on) -> np.ndarray:
    """(frames, 6) scores at a resting 0.1, the named ones at the given value from frame 20 on."""
    scores = np.full((frames, len(NAMES)), 0.1)
    for name, value in on.items():
        scores[20:, NAMES.index(name)] = value
    return scores


def drive_of(scores, ens0=3.0):
    times = np.arange(len(scores)) / 25.0
    return BrowDrive.of_scores(scores, NAMES, times, ens0, np.arange(10))


def test_a_full_inner_raise_lifts_the_inner_ends_and_not_the_outer():
    drive = drive_of(scores_over(80, browInnerUp=1.0))
    inner = [list(drive.points).index(BROWS["Left"][0][0]), list(drive.points).index(BROWS["Right"][1][0])]
    outer = [list(drive.points).index(BROWS["Left"][0][-1]), list(drive.points).index(BROWS["Right"][1][-1])]
    np.testing.assert_allclose(drive.heights[:10], 0.0, atol=1e-12)           # calibrated on the neutral
    np.testing.assert_allclose(drive.heights[-1, inner], RAISE * 3.0, rtol=1e-3)  # settled after the filter
    np.testing.assert_allclose(drive.heights[-1, outer], 0.0, atol=1e-12)


def test_brow_down_lowers_its_own_side_only():
    drive = drive_of(scores_over(80, browDownLeft=1.0))
    points = list(drive.points)
    left = [points.index(p) for contour in BROWS["Left"] for p in contour]
    right = [points.index(p) for contour in BROWS["Right"] for p in contour]
    np.testing.assert_allclose(drive.heights[-1, left], -LOWER * 3.0, rtol=1e-3)
    np.testing.assert_allclose(drive.heights[-1, right], 0.0, atol=1e-12)


def test_scores_below_the_neutral_do_not_push_the_brows():
    drive = drive_of(scores_over(60, browInnerUp=0.0, browOuterUpLeft=0.0, browDownRight=0.0))
    np.testing.assert_allclose(drive.heights, 0.0, atol=1e-12)


def test_apply_changes_only_the_brows_heights_and_keeps_frames_without_scores():
    scores = scores_over(40, browInnerUp=1.0)
    scores[30] = np.nan  # a gap the capture filled: landmarks but no scores
    drive = drive_of(scores)
    moved = np.random.default_rng(0).normal(size=(40, 478, 3))
    moved[:, drive.points, 1] = 0.1  # a tracked rise the scores call for more of
    before = moved.copy()
    drive.apply(moved, 0)
    others = np.setdiff1d(np.arange(478), drive.points)
    np.testing.assert_array_equal(moved[:, others], before[:, others])
    np.testing.assert_array_equal(moved[:, drive.points, ::2], before[:, drive.points, ::2])  # x and z kept
    np.testing.assert_array_equal(moved[30, drive.points], before[30, drive.points])
    raised = drive.heights[35] > 0.1 / TRACKED_SHARE
    assert raised.any()
    np.testing.assert_allclose(moved[35, drive.points[raised], 1], 0.1 / TRACKED_SHARE)
    chunk = before[32:40].copy()
    np.testing.assert_array_equal(drive.apply(chunk, 32), moved[32:40])  # chunk by chunk, as streamed


def test_the_geometry_must_agree_on_the_way():
    """Scores calling for a raise lift a brow no further than its tracked rise over the tracked share;
    a brow the landmarks see still, or lowered, stays where it is (a painted face's blink scores a brow
    raise the landmarks do not show); a brow the landmarks see higher than the scores say keeps its
    tracked height (the scores only add)."""
    drive = drive_of(scores_over(60, browInnerUp=1.0))
    inner = list(drive.points).index(BROWS["Left"][0][0])
    full = drive.heights[-1, inner]
    moved = np.zeros((60, 478, 3))
    for tracked, expected in ((0.0, 0.0), (-0.2, -0.2), (0.5 * full * TRACKED_SHARE, 0.5 * full), (full, full),
                              (1.5 * full, 1.5 * full)):
        moved[-1, BROWS["Left"][0][0], 1] = tracked
        drive.apply(moved, 0)
        np.testing.assert_allclose(moved[-1, BROWS["Left"][0][0], 1], expected, atol=1e-12)


def test_no_brow_scores_or_no_neutral_scores_means_no_drive():
    assert BrowDrive.of_scores(None, (), np.arange(5), 3.0, np.arange(2)) is None
    assert BrowDrive.of_scores(np.zeros((5, 1)), ("jawOpen",), np.arange(5), 3.0, np.arange(2)) is None
    scores = scores_over(30)
    scores[:10] = np.nan
    assert BrowDrive.of_scores(scores, NAMES, np.arange(30) / 25, 3.0, np.arange(10)) is None


def test_noisy_scores_leave_the_neutral_frames_at_rest():
    """Calibrated on the neutral frames' highest score, a jittering score moves no brow inside its own
    neutral window, so the rest face stays the neutral frames' mean."""
    scores = scores_over(60, browInnerUp=0.9)
    scores[:20] += np.random.default_rng(1).normal(scale=0.03, size=(20, len(NAMES)))
    drive = BrowDrive.of_scores(scores, NAMES, np.arange(60) / 25.0, 3.0, np.arange(5, 15))
    np.testing.assert_array_equal(drive.heights[5:15], 0.0)
    assert drive.heights[-1].max() > 0.5 * RAISE * 3.0
    unfiltered = BrowDrive.of_scores(scores, NAMES, np.arange(60) / 25.0, 3.0, np.arange(5, 15), smoothing=None)
    np.testing.assert_array_equal(unfiltered.heights[5:15], 0.0)


def test_scores_that_miss_a_raise_the_landmarks_show_do_not_hold_the_brows_back():
    """The Face Landmarker can score a full brow raise at 0.05 (one ICT tuning identity): a brow whose
    landmarks rise more than those scores' height keeps its tracked rise, frame by frame; a lowered
    brow the scores barely lower keeps its tracked fall."""
    drive = drive_of(scores_over(60, browInnerUp=0.12, browDownLeft=0.12))
    points = np.asarray(drive.points)
    moved = np.zeros((60, 478, 3))
    moved[40:, points, 1] = np.linspace(0.3, 0.6, 20)[:, None]
    moved[50:, points[:10], 1] = -0.4  # the left brow lowered, past what its scores say
    before = moved.copy()
    drive.apply(moved, 0)
    assert (np.abs(drive.heights[40:]) < 0.3).all()  # the scores say less than the landmarks show
    np.testing.assert_allclose(moved[40:, points, 1], before[40:, points, 1])


BLINKING = NAMES + ("eyeBlinkLeft", "eyeBlinkRight")


def blink_drive(frames=80, neutral_blink=False, **on):
    """A drive over scores with the eyes' blink scores too (at rest 0.1), the named ones on from frame 20."""
    scores = np.full((frames, len(BLINKING)), 0.1)
    for name, value in on.items():
        scores[20:, BLINKING.index(name)] = value
    if neutral_blink:  # a blink among the neutral frames
        scores[3:6, BLINKING.index("eyeBlinkLeft")] = 0.95
    return BrowDrive.of_scores(scores, BLINKING, np.arange(frames) / 25.0, 3.0, np.arange(10))


def test_where_no_brow_score_speaks_the_movement_goes_as_far_as_the_eye_on_its_side_shuts():
    """The tracker's brow landmarks move with the lids in a blink the scores say nothing of: with the
    left eye shut (eyeBlinkLeft 1) the left brow's tracked rise and dip are taken away, the right
    brow's (its eye open) stay; half shut, half stays; a blink among the neutral frames does not move
    the eyes' rest."""
    for neutral_blink in (False, True):
        for shut, kept in ((1.0, 0.0), (0.55, 0.5)):
            drive = blink_drive(neutral_blink=neutral_blink, eyeBlinkLeft=shut)
            points = np.asarray(drive.points)
            moved = np.zeros((80, 478, 3))
            moved[60:, points, 1] = -0.1
            moved[60:, points[[0, 10]], 1] = 0.05  # one rising point on each side
            drive.apply(moved, 0)
            np.testing.assert_allclose(moved[-1, points[1:10], 1], -0.1 * kept, atol=2e-3)
            np.testing.assert_allclose(moved[-1, points[0], 1], 0.05 * kept, atol=2e-3)
            np.testing.assert_allclose(moved[-1, points[11:20], 1], -0.1, atol=1e-12)
            np.testing.assert_allclose(moved[-1, points[10], 1], 0.05, atol=1e-12)


def test_where_a_brow_score_speaks_a_shut_eye_changes_nothing():
    """A frown or a raise with the eye shut: browDownLeft (or browInnerUp) on, each brow point the score
    speaks for goes as the scores and its landmarks say, as without the blink scores (browInnerUp says
    nothing of the brows' outer ends: those are damped as in a blink)."""
    for on in ({"browDownLeft": 1.0}, {"browInnerUp": 1.0}):
        with_blink = blink_drive(eyeBlinkLeft=1.0, **on)
        without = drive_of(scores_over(80, **on))
        points = np.asarray(with_blink.points)
        results = []
        for drive in (with_blink, without):
            moved = np.zeros((80, 478, 3))
            moved[60:, points, 1] = -0.1 if "browDownLeft" in on else 0.1
            drive.apply(moved, 0)
            results.append(moved[-1, points[:10], 1])
        speaking = np.abs(without.heights[-1, :10]) > 0.01
        assert speaking.sum() >= 8
        np.testing.assert_allclose(results[0][speaking], results[1][speaking], atol=1e-12)
        assert np.abs(results[0][speaking]).min() > 0.05


def test_a_frame_without_scores_keeps_its_tracked_heights_with_the_blink_scores_too():
    """A gap the capture filled (no scores, blink scores included) is left as tracked, the eye shut or not."""
    scores = np.full((80, len(BLINKING)), 0.1)
    scores[20:, BLINKING.index("eyeBlinkLeft")] = 1.0
    scores[70] = np.nan
    drive = BrowDrive.of_scores(scores, BLINKING, np.arange(80) / 25.0, 3.0, np.arange(10))
    points = np.asarray(drive.points)
    moved = np.zeros((80, 478, 3))
    moved[60:, points, 1] = 0.05
    drive.apply(moved, 0)
    np.testing.assert_array_equal(moved[70, points, 1], 0.05)
    assert np.abs(moved[75, points[:10], 1]).max() < 5e-3  # around the gap, the shut eye's damping
