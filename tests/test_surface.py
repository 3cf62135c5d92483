import numpy as np
import pytest
from conftest import grid_mesh

from faceanim.geometry import BiharmonicInterpolation, Mesh, RbfWarp, geodesic_distances
from faceanim.retarget import SparseTransfer


def slit_mesh(n=11, slit=range(3, 8)):
    """A grid cut along part of its middle row: a closed 'mouth' whose two lips coincide in space."""
    base = grid_mesh(n)
    v = list(base.vertices)
    mid = n // 2
    twin = {}
    for col in slit:
        twin[mid * n + col] = len(v)
        v.append(base.vertices[mid * n + col].copy())
    tris = base.triangles.copy()
    below = tris.min(axis=1) < mid * n  # triangles of the lower half use the twins on the cut
    for old, new in twin.items():
        tris[below & (tris == old).any(1)] = np.where(tris[below & (tris == old).any(1)] == old, new,
                                                       tris[below & (tris == old).any(1)])
    return Mesh(np.array(v), tris), mid * n + 5, twin[mid * n + 5], twin


def test_geodesic_goes_around_the_slit():
    mesh, upper, lower, _ = slit_mesh()
    assert np.linalg.norm(mesh.vertices[upper] - mesh.vertices[lower]) == 0
    assert geodesic_distances(mesh, [upper])[0, lower] > 0.35  # around a corner of the slit


def test_surface_interpolation_does_not_leak_across_the_mouth():
    mesh, upper, lower, twin = slit_mesh()
    boundary = np.flatnonzero((mesh.vertices[:, :2] == 0).any(1) | (mesh.vertices[:, :2] == 1).any(1))
    controls = np.r_[boundary, upper]
    values = np.zeros((len(controls), 3))
    values[-1] = [0, 1, 0]  # the middle of the upper lip rises; the face's border stays
    surface = SparseTransfer(mesh, controls, metric="surface", falloff=0)(values)
    euclid = SparseTransfer(mesh, controls, metric="euclidean", kernel="multiquadric", smoothing=0)(values)
    # Euclidean: the lower lip, which touches the upper one, rises with it.
    assert euclid[lower, 1] == pytest.approx(1.0)
    # Along the surface the lower lip is a slit's half-length away: it moves far less.
    assert surface[upper, 1] == pytest.approx(1.0)
    assert surface[lower, 1] < 0.35


@pytest.mark.parametrize("falloff", [0.0, 0.25])
def test_biharmonic_is_exact_at_controls(falloff):
    mesh = grid_mesh(8)
    ids = np.array([0, 7, 27, 36, 56, 63])
    values = np.random.default_rng(0).normal(size=(6, 3))
    out = BiharmonicInterpolation(mesh, ids, falloff=falloff)(values)
    np.testing.assert_allclose(out[ids], values, atol=1e-12)


def test_plain_biharmonic_reproduces_constants_and_falloff_relaxes_to_zero():
    mesh = grid_mesh(15)
    ids = np.array([0, 14, 210, 224])  # the corners
    constant = BiharmonicInterpolation(mesh, ids, falloff=0)(np.ones((4, 1)))
    np.testing.assert_allclose(constant, 1, atol=1e-9)
    faded = BiharmonicInterpolation(mesh, ids, falloff=0.1)(np.ones((4, 1)))
    assert faded[112, 0] < 0.5  # the centre is far from every corner in units of the falloff


def test_bounded_biharmonic_moves_no_vertex_past_its_controls():
    # A row of controls coming down beside a row held still (a lash line and the lid's skin above it):
    # the biharmonic field carries the slope between them on, so the skin beyond the still row rises;
    # the bounded field stays between the two, and both land the controls exactly and carry a uniform
    # motion alike.
    mesh = grid_mesh(12)
    rows = np.arange(12)
    ids = np.r_[rows + 12 * 3, rows + 12 * 5]
    values = np.r_[np.full(12, -1.0), np.zeros(12)][:, None]
    plain = BiharmonicInterpolation(mesh, ids, falloff=0.25)
    bounded = BiharmonicInterpolation(mesh, ids, falloff=0.25, bounded=True)
    assert plain(values).max() > 0.03  # the overshoot the bounded field is for
    out = bounded(values)
    assert out.min() >= -1.0 - 1e-12 and out.max() <= 1e-12
    np.testing.assert_allclose(out[ids], values, atol=1e-12)
    np.testing.assert_allclose(bounded(np.ones((len(ids), 1))), plain(np.ones((len(ids), 1))), atol=1e-9)
    assert (bounded.operator >= 0).all()


def test_bounded_interpolation_keeps_random_values_within_their_range():
    mesh = grid_mesh(10)
    ids = np.random.default_rng(1).choice(100, size=15, replace=False)
    values = np.random.default_rng(2).normal(size=(15, 3))
    plain = BiharmonicInterpolation(mesh, ids, falloff=0)(values)
    assert (plain.min(axis=0) < values.min(axis=0) - 0.05).any()  # the biharmonic field leaves the range
    out = BiharmonicInterpolation(mesh, ids, falloff=0, bounded=True)(values)
    # falloff 0: every row sums to 1, so each vertex is a weighted mean of the controls' values
    assert (out >= values.min(axis=0) - 1e-12).all() and (out <= values.max(axis=0) + 1e-12).all()
    assert (SparseTransfer(mesh, ids, bounded=True).operator >= 0).all()  # the transfer passes it on
    assert (SparseTransfer(mesh, ids).operator < 0).any()


def test_weights_are_eased_to_nonnegative_without_a_kink():
    from faceanim.geometry.surface import EASE, eased_weights

    h = 1e-7
    for at in (0.0, EASE):  # where the curve's pieces meet: no jump and no kink (a plain cut at 0 kinks)
        below, here, above = eased_weights(np.array([at - h, at, at + h]))
        assert (here - below) / h == pytest.approx((above - here) / h, abs=1e-5)
    np.testing.assert_allclose(eased_weights(np.array([-0.3, 0.0, EASE / 2, 1.0])),
                               [0.0, 0.0, EASE / 8, 1.0 - EASE / 2])


def test_surface_interpolation_errors():
    two_parts = Mesh(np.r_[grid_mesh(3).vertices, grid_mesh(3).vertices + 5],
                     np.r_[grid_mesh(3).triangles, grid_mesh(3).triangles + 9])
    with pytest.raises(ValueError, match="1 connected parts of the mesh hold no control vertex"):
        BiharmonicInterpolation(two_parts, [0, 1, 2])
    with pytest.raises(ValueError, match=r"control_vertices must be distinct; repeated: \[1\]"):
        BiharmonicInterpolation(grid_mesh(3), [0, 1, 1])
    with pytest.raises(ValueError, match="falloff must be a finite number >= 0"):
        BiharmonicInterpolation(grid_mesh(3), [0, 1], falloff=-1)
    with pytest.raises(ValueError, match="bounded is for the surface metric only"):
        SparseTransfer(grid_mesh(3), [0, 1, 2], metric="euclidean", bounded=True)


def test_euclidean_sparse_transfer_is_the_rbf_warp():
    mesh = grid_mesh(6)
    ids = np.array([0, 5, 14, 21, 30, 35])
    d = np.random.default_rng(2).normal(size=(6, 3))
    moved = SparseTransfer(mesh, ids, metric="euclidean", kernel="multiquadric")(d)
    expected = RbfWarp(mesh.vertices[ids], d, kernel="multiquadric")(mesh.vertices)
    np.testing.assert_allclose(moved, expected, atol=1e-10)


def test_geodesic_rbf_on_a_flat_sheet_is_the_euclidean_one():
    """On a plane geodesics are straight lines, so the geodesic RBF is the plain one up to the heat
    method's few per cent; its poor score on faces (benchmarks/results/transfer_ict.md) comes from the
    method, not from this code."""
    from faceanim.geometry import SurfaceRbf

    mesh = grid_mesh(41)
    ids = np.random.default_rng(4).choice(len(mesh.vertices), 15, replace=False)
    values = np.random.default_rng(5).normal(size=(15, 1))
    geodesic = SurfaceRbf(mesh, ids, kernel="multiquadric", smoothing=0)(values)
    plain = RbfWarp(mesh.vertices[ids, :2], values, kernel="multiquadric", smoothing=0)(mesh.vertices[:, :2])
    np.testing.assert_allclose(geodesic[ids], values, atol=1e-9)
    assert np.sqrt(np.mean((geodesic - plain) ** 2)) < 0.3 * np.sqrt(np.mean(plain ** 2))
