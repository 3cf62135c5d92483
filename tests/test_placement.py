"""Automatic placement's lid points: moved onto the lid margins seen in the skin's depth buffer."""

import numpy as np
import pytest

from faceanim.retarget.placement import _EYE_LIDS, _lid_margins

SKIN, SOCKET, FOCAL = 10.0, 13.0, 500.0


def _eye_scene(hole: bool = False, opening: bool = True):
    """A flat skin at depth 10 with one eye opening, an ellipse centred at pixel (100, 100), 40 pixels half-wide
    and 12 half-high, that shows a socket 3 deeper (or nothing: a hole); MediaPipe's points read the eye as
    half shut: both lids' points on one line 4 pixels below the middle, the corners at the ellipse's ends. The
    other eye lies far off and has no opening."""
    rows, cols = np.mgrid[0:220, 0:400]
    depth = np.full(rows.shape, SKIN)
    inside = ((cols + 0.5 - 100) / 40) ** 2 + ((rows + 0.5 - 100) / 12) ** 2 < 1
    if opening:
        depth[inside] = np.inf if hole else SOCKET
    pixels = np.zeros((478, 2))
    for k, (outer, inner, upper, lower) in enumerate(_EYE_LIDS):
        centre = np.array([100.0 if k == 0 else 300.0, 100.0])
        pixels[outer], pixels[inner] = centre - [40, 0], centre + [40, 0]
        xs = centre[0] + np.linspace(-30, 30, len(upper))
        pixels[list(upper)] = np.c_[xs, np.full(len(xs), centre[1] + 4)]
        pixels[list(lower)] = np.c_[xs, np.full(len(xs), centre[1] + 4)]
    return pixels, depth


@pytest.mark.parametrize("hole", [False, True])
def test_half_shut_lid_points_each_go_to_their_own_lids_margin(hole):
    pixels, depth = _eye_scene(hole=hole)
    ids, moved, distance = _lid_margins(pixels, depth, FOCAL)
    _, _, upper, lower = _EYE_LIDS[0]
    assert sorted(ids.tolist()) == sorted(upper + lower)  # the eye without an opening keeps its points
    assert np.allclose(distance, SKIN)  # the rim's own skin, not the socket behind
    dx = moved[:, 0] - 100
    rim = 12 * np.sqrt(1 - (dx / 40) ** 2)
    is_upper = np.isin(ids, upper)
    assert np.allclose(moved[:, 0], pixels[ids, 0])  # each stays at its place along the eye
    assert np.abs(moved[is_upper, 1] - (100 - rim[is_upper])).max() <= 1.0  # on the upper margin
    assert np.abs(moved[~is_upper, 1] - (100 + rim[~is_upper])).max() <= 1.0  # on the lower margin


def test_closed_lids_keep_their_points():
    pixels, depth = _eye_scene(opening=False)
    ids, moved, distance = _lid_margins(pixels, depth, FOCAL)
    assert len(ids) == 0 and moved.shape == (0, 2) and distance.shape == (0,)


def test_a_brow_in_front_of_the_upper_lid_is_not_taken_for_its_margin():
    """A deep-set eye seen face-on: the brow overhangs the upper lid, so the opening's top edge is the brow's,
    2 in front of the skin (more than a quarter of the eye's width, 1.6). The upper lid's points stay where
    MediaPipe put them; the lower lid's still go to their margin."""
    pixels, depth = _eye_scene()
    rows, cols = np.mgrid[0:depth.shape[0], 0:depth.shape[1]]
    top = 100 - 12 * np.sqrt(np.clip(1 - ((cols + 0.5 - 100) / 40) ** 2, 0, 1))
    brow = (depth == SKIN) & (rows + 0.5 < top) & (rows + 0.5 > top - 8) & (np.abs(cols - 100) < 40)
    depth[brow] = SKIN - 2.0
    ids, moved, distance = _lid_margins(pixels, depth, FOCAL)
    _, _, upper, lower = _EYE_LIDS[0]
    assert sorted(ids.tolist()) == sorted(lower)
    assert np.allclose(distance, SKIN)
