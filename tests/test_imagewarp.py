import numpy as np
import pytest

from faceanim.geometry.imagewarp import ImageWarp


def _checker(h=64, w=80):
    y, x = np.mgrid[0:h, 0:w]
    return (((x // 8 + y // 8) % 2) * 200 + 20).astype(np.uint8)[..., None].repeat(3, axis=2)


def test_no_motion_gives_the_image_back():
    image = _checker()
    warp = ImageWarp([[30.0, 30.0], [50.0, 20.0], [40.0, 45.0]], 80, 64)
    assert np.array_equal(warp(image, np.zeros((3, 2))), image)


def test_points_land_where_they_were_moved_and_the_border_stays():
    image = np.zeros((64, 80), np.uint8)
    image[30, 30] = 255  # one bright pixel on the driving point
    warp = ImageWarp([[30.0, 30.0], [55.0, 30.0]], 80, 64, step=2)
    moved = warp(image.astype(np.float64), [[6.0, -4.0], [0.0, 0.0]])
    y, x = np.unravel_index(np.argmax(moved), moved.shape)
    assert (x, y) == (36, 26)
    ramp = np.tile(3.0 * np.arange(80), (64, 1))  # 3 levels per pixel, so a shift shows as a change of value
    out = ImageWarp([[40.0, 32.0]], 80, 64, step=2)(ramp, [[5.0, 0.0]])
    assert abs(out[32, 45] - ramp[32, 40]) < 0.5  # the point moved 5 pixels right
    border = np.concatenate([out[0] - ramp[0], out[-1] - ramp[-1], out[:, 0] - ramp[:, 0], out[:, -1] - ramp[:, -1]])
    assert np.abs(border).max() < 0.3  # the edge moved less than a tenth of a pixel


def test_fixed_points_hold_the_image_still_around_them():
    frame = _checker()
    free = ImageWarp([[40.0, 32.0]], 80, 64)(frame, [[6.0, 0.0]])
    ring = [[40 + 12 * np.cos(a), 32 + 12 * np.sin(a)] for a in np.linspace(0, 2 * np.pi, 16, endpoint=False)]
    held = ImageWarp([[40.0, 32.0]], 80, 64, fixed=ring)(frame, [[6.0, 0.0]])
    outside = np.zeros((64, 80), bool)
    outside[:, :20] = True  # far left of the ring
    assert np.abs(held[outside].astype(int) - frame[outside]).sum() < np.abs(free[outside].astype(int)
                                                                              - frame[outside]).sum()


def test_warp_errors():
    with pytest.raises(ValueError, match=r"points must have shape \(K, 2\)"):
        ImageWarp([[1.0, 2.0, 3.0]], 10, 10)
    with pytest.raises(ValueError, match="image size must be at least 2 x 2"):
        ImageWarp([[1.0, 2.0]], 1, 10)
    warp = ImageWarp([[4.0, 4.0]], 10, 10)
    with pytest.raises(ValueError, match="image must be 10 x 10 pixels"):
        warp(np.zeros((8, 10, 3), np.uint8), [[0.0, 0.0]])
    with pytest.raises(ValueError, match=r"displacements must have shape \(1, 2\)"):
        warp(np.zeros((10, 10, 3), np.uint8), [[0.0, 0.0], [1.0, 1.0]])
