import numpy as np
import pytest
from scipy.interpolate import RBFInterpolator

from faceanim.geometry import KERNELS, RbfWarp, apply_operator

rng = np.random.default_rng(3)
CENTRES = rng.normal(size=(40, 3))
VALUES = rng.normal(size=(40, 3))
POINTS = rng.normal(size=(200, 3))


@pytest.mark.parametrize("kernel", ["thin_plate", "cubic", "linear", "gaussian"])
def test_exact_kernels_pass_through_centres(kernel):
    np.testing.assert_allclose(RbfWarp(CENTRES, VALUES, kernel=kernel)(CENTRES), VALUES, atol=1e-6)


@pytest.mark.parametrize("kernel", ["thin_plate", "cubic", "linear", "gaussian"])
@pytest.mark.parametrize("scale, shift", [(1.0, 0.0), (0.01, 0.5), (1000.0, -3e4)])  # cm, m, mm far away
def test_exact_kernels_hit_their_centres_to_rounding(kernel, scale, shift):
    """Passing through the centres to ~1e-12 relative, at any unit. Distances once computed as
    |a|^2 + |b|^2 - 2 a.b made the linear kernel miss by 5e-8 (a distance of 0 came out ~1e-8)."""
    centres = CENTRES * scale + shift
    warp = RbfWarp(centres, VALUES, kernel=kernel)
    miss = np.abs(warp(centres) - VALUES).max() / np.abs(VALUES).max()
    assert miss < 1e-12
    assert np.abs(warp.operator(centres) @ VALUES - VALUES).max() / np.abs(VALUES).max() < 1e-12


@pytest.mark.parametrize("kernel", ["thin_plate", "cubic", "linear"])
def test_affine_kernels_reproduce_affine_motion(kernel):
    A = rng.normal(size=(3, 3))
    b = rng.normal(size=3)
    warp = RbfWarp(CENTRES, CENTRES @ A.T + b, kernel=kernel)
    np.testing.assert_allclose(warp(POINTS), POINTS @ A.T + b, atol=1e-7)


def test_thin_plate_matches_scipy():
    ours = RbfWarp(CENTRES, VALUES, kernel="thin_plate")(POINTS)
    theirs = RBFInterpolator(CENTRES, VALUES, kernel="thin_plate_spline", degree=1)(POINTS)
    np.testing.assert_allclose(ours, theirs, atol=1e-8)


def test_multiquadric_is_the_seeds_formula():
    """h_ij = sqrt(r_ij^2 + sc_j^2), sc_j = nearest other centre, (H + gamma I) w = d, in normalised units."""
    gamma = 1e-3
    c = (CENTRES - CENTRES.mean(0)) / np.sqrt(((CENTRES - CENTRES.mean(0)) ** 2).sum(1).mean())
    r = np.linalg.norm(c[:, None] - c[None], axis=2)
    sc = np.array([np.min(np.delete(r[j], j)) for j in range(len(c))])
    H = np.array([[np.sqrt(r[i, j] ** 2 + sc[j] ** 2) for j in range(len(c))] for i in range(len(c))])
    w = np.linalg.solve(H + gamma * np.eye(len(c)), VALUES)
    p = (POINTS - CENTRES.mean(0)) / np.sqrt(((CENTRES - CENTRES.mean(0)) ** 2).sum(1).mean())
    expected = np.sqrt(np.linalg.norm(p[:, None] - c[None], axis=2) ** 2 + sc ** 2) @ w
    np.testing.assert_allclose(RbfWarp(CENTRES, VALUES, kernel="multiquadric")(POINTS), expected, atol=1e-9)


@pytest.mark.parametrize("kernel", KERNELS)
def test_units_do_not_matter(kernel):
    """Scaling and moving the whole problem (cm to mm, another origin) moves the answer with it."""
    base = RbfWarp(CENTRES, VALUES, kernel=kernel)(POINTS)
    scaled = RbfWarp(10 * CENTRES + 5, VALUES, kernel=kernel)(10 * POINTS + 5)
    np.testing.assert_allclose(scaled, base, atol=1e-7)


@pytest.mark.parametrize("kernel", KERNELS)
def test_operator_and_frames_agree_with_single_calls(kernel):
    frames = rng.normal(size=(4, 40, 3))
    warp = RbfWarp(CENTRES, frames, kernel=kernel)
    M = RbfWarp(CENTRES, VALUES, kernel=kernel).operator(POINTS)
    together = warp(POINTS)
    assert together.shape == (4, 200, 3)
    for t in range(4):
        single = RbfWarp(CENTRES, frames[t], kernel=kernel)(POINTS)
        np.testing.assert_allclose(together[t], single, atol=1e-9)
        np.testing.assert_allclose(apply_operator(M, frames)[t], single, atol=1e-8)


def test_two_dimensional_warps():
    c2 = CENTRES[:, :2]
    np.testing.assert_allclose(RbfWarp(c2, VALUES)(c2), VALUES, atol=1e-8)


def test_coincident_centres_are_named():
    c = CENTRES.copy()
    c[7] = c[2]
    with pytest.raises(ValueError, match="coincident centres: 2 and 7"):
        RbfWarp(c, VALUES)


@pytest.mark.parametrize("kwargs, match", [
    (dict(centres=CENTRES[:3], values=VALUES[:3]), "needs at least 4 centres for its affine term, got 3"),
    (dict(centres=CENTRES, values=VALUES[:5]), r"values must have shape \(40, C\) or \(T, 40, C\)"),
    (dict(centres=CENTRES, values=VALUES, kernel="spline"), "kernel must be one of"),
    (dict(centres=CENTRES, values=VALUES, smoothing=-1), "smoothing must be a finite number >= 0"),
    (dict(centres=np.c_[CENTRES[:, :2], np.zeros(40)], values=VALUES), "singular.*plane"),
])
def test_bad_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        RbfWarp(**kwargs)
