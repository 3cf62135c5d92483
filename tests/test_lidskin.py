"""The upper lids' skin brought down with the lash lines (capture/lidskin.py)."""

import numpy as np

from faceanim.capture.lidskin import LASH_TO_SKIN, SHARE, STILL, follow_lid_skin

LASH = [lash for lash, _ in LASH_TO_SKIN]
SKIN = [skin for _, skin in LASH_TO_SKIN]


def test_the_ring_above_comes_down_by_its_share_of_the_lash_lines_descent_and_nothing_else_moves():
    moved = np.random.default_rng(0).normal(scale=0.05, size=(3, 478, 3))
    moved[0, LASH, 1] = -0.6  # shutting
    moved[1, LASH, 1] = 0.2   # opening wide: a rise adds nothing
    moved[1, LASH[:7], 1] = -0.5 * STILL  # nor does jitter at rest
    moved[2] = np.nan          # no face
    out = follow_lid_skin(moved.copy())
    np.testing.assert_allclose(out[0, SKIN, 1], moved[0, SKIN, 1] - SHARE * (0.6 - STILL))
    np.testing.assert_array_equal(out[1], moved[1])
    assert np.isnan(out[2]).all()
    others = np.setdiff1d(np.arange(478), SKIN)
    np.testing.assert_array_equal(out[:2, others], moved[:2, others])
    np.testing.assert_array_equal(out[:2, :, [0, 2]], moved[:2, :, [0, 2]])


def test_the_pairs_are_each_eyes_lash_line_under_its_own_skin_and_other_layouts_are_left_alone():
    from faceanim.capture.metric import canonical_face

    face = canonical_face().vertices  # +y up
    for lash, skin in LASH_TO_SKIN:
        assert face[skin, 1] > face[lash, 1]                       # the skin above its lash point
        assert abs(face[skin, 0] - face[lash, 0]) < 0.6            # in the same column across the eye
    assert len(set(LASH)) == len(set(SKIN)) == 14 and not set(LASH) & set(SKIN)
    few = np.full((2, 68, 3), -0.5)
    np.testing.assert_array_equal(follow_lid_skin(few.copy()), few)


def test_the_capture_brings_the_lid_skin_down_with_its_displacements():
    """``displacements_from``, which both capture paths use, applies it: a lash line tracked 0.6 cm down
    brings its ring down by the share; a frame without a face stays NaN."""
    from faceanim.capture.headframe import displacements_from
    from faceanim.capture.metric import canonical_face

    rest = canonical_face().vertices
    points = np.repeat(rest[None], 2, axis=0)
    points[0, LASH, 1] -= 0.6
    out = displacements_from(points, rest, np.array([True, False]))
    np.testing.assert_allclose(out[0, SKIN, 1], -SHARE * (0.6 - STILL), atol=1e-12)
    np.testing.assert_allclose(out[0, LASH, 1], -0.6, atol=1e-12)
    assert np.isnan(out[1]).all()
