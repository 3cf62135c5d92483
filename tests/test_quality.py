"""Surface-quality measures (faceanim.geometry.quality), on small cases with known answers."""

import numpy as np
import pytest
from conftest import grid_mesh

from faceanim.geometry.quality import (
    bend_change,
    edge_stretch,
    penetration_depth,
    rigid_residual,
    signed_distance,
    turned_over,
    turned_triangles,
)


def rotation(axis, degrees):
    axis = np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)
    a = np.radians(degrees)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K


def closed_box(size=1.0):
    """A cube [0, size]^3 with outward-facing triangles."""
    v = np.array([[x, y, z] for x in (0, size) for y in (0, size) for z in (0, size)], dtype=np.float64)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    tris = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    centre = v.mean(axis=0)
    tris = [t if np.cross(v[t[1]] - v[t[0]], v[t[2]] - v[t[0]]) @ (v[list(t)].mean(0) - centre) > 0 else t[::-1]
            for t in tris]
    return v, np.array(tris)


# ---- turned triangles


def test_a_flipped_triangle_is_counted_in_the_frames_it_is_flipped():
    mesh = grid_mesh(4)
    rest = mesh.vertices
    frames = np.stack([rest, rest, rest])
    frames[1, 5] += [0.0, 0.0, 0.2]          # a bump: nothing turns over
    frames[2, 5] = rest[5] + [-0.7, -0.7, 0]  # dragged across its neighbours: some triangles fold
    counts = turned_triangles(rest, frames, mesh.triangles)
    assert counts[0] == 0 and counts[1] == 0 and counts[2] > 0
    folded = turned_over(rest, frames, mesh.triangles)[2]
    assert np.all(np.isin(mesh.triangles[folded], 5).any(axis=1))  # only triangles at the moved vertex


def test_a_whole_mesh_turned_over_counts_every_triangle_and_a_rigid_turn_none():
    mesh = grid_mesh(4)
    rest = mesh.vertices
    upside_down = rest @ rotation([1, 0, 0], 180).T
    tilted = rest @ rotation([1, 1, 0], 60).T + [3.0, 0, 0]
    counts = turned_triangles(rest, np.stack([upside_down, tilted]), mesh.triangles)
    np.testing.assert_array_equal(counts, [len(mesh.triangles), 0])


def test_turned_triangles_counts_only_the_masked_triangles():
    mesh = grid_mesh(4)
    upside_down = (mesh.vertices @ rotation([1, 0, 0], 180).T)[None]
    mask = np.zeros(len(mesh.triangles), dtype=bool)
    mask[:5] = True
    assert turned_triangles(mesh.vertices, upside_down, mesh.triangles, mask=mask)[0] == 5
    assert turned_over(mesh.vertices, upside_down, mesh.triangles, mask=mask).shape == (1, 5)


def test_turned_triangles_equals_a_plain_loop_across_frame_chunks(monkeypatch):
    import faceanim.geometry.quality as quality

    monkeypatch.setattr(quality, "_CHUNK_VALUES", 50)  # several frames per chunk, several chunks
    mesh = grid_mesh(5)
    rng = np.random.default_rng(1)
    frames = mesh.vertices + rng.normal(scale=0.3, size=(7, len(mesh.vertices), 3))
    expected = [sum(np.cross(p[b] - p[a], p[c] - p[a]) @ np.cross(mesh.vertices[b] - mesh.vertices[a],
                                                                   mesh.vertices[c] - mesh.vertices[a]) < 0
                    for a, b, c in mesh.triangles) for p in frames]
    np.testing.assert_array_equal(turned_triangles(mesh.vertices, frames, mesh.triangles), expected)


# ---- rigid residual


def test_a_rigid_motion_has_no_residual_and_a_bend_has_its_size():
    rng = np.random.default_rng(0)
    rest = rng.normal(size=(30, 3))
    turned = rest @ rotation([0.3, 1, -0.2], 40).T + [1.0, -2.0, 0.5]
    stretched = rest * [1.1, 1.0, 1.0]
    residual = rigid_residual(rest, np.stack([rest, turned, stretched]))
    assert residual[0] < 1e-12 and residual[1] < 1e-12
    assert residual[2] > 0.01


def test_rigid_residual_of_a_symmetric_stretch_is_the_stretch():
    rest = np.array([[-1.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0]])
    np.testing.assert_allclose(rigid_residual(rest, (rest * [1.25, 1, 1])[None]), [0.25], atol=1e-12)


def test_rigid_residual_does_not_depend_on_the_unit():
    rng = np.random.default_rng(2)
    rest = rng.normal(size=(20, 3))
    moved = rest + rng.normal(scale=0.01, size=(3, 20, 3))
    in_cm = rigid_residual(rest, moved)
    np.testing.assert_allclose(rigid_residual(10 * rest, 10 * moved), 10 * in_cm, rtol=1e-9)


# ---- edge stretch


def test_an_edge_doubled_or_halved_gives_a_ratio_of_two():
    rest = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    edges = np.array([[0, 1], [0, 2], [1, 2]])
    doubled = rest.copy()
    doubled[1] = [2.0, 0, 0]  # edge 0-1 doubles; 1-2 grows by sqrt(5)/sqrt(2) < 2
    halved = rest.copy()
    halved[2] = [0, 0.5, 0]   # edge 0-2 halves
    stretch = edge_stretch(rest, np.stack([rest, doubled, halved]), edges)
    np.testing.assert_allclose(stretch, [1.0, 2.0, 2.0])


def test_edge_stretch_ignores_rigid_motion_and_zero_length_edges():
    mesh = grid_mesh(4)
    moved = mesh.vertices @ rotation([1, 2, 3], 70).T + 5.0
    np.testing.assert_allclose(edge_stretch(mesh.vertices, moved[None], mesh.edges), [1.0])
    rest = np.array([[0.0, 0, 0], [0, 0, 0], [1, 0, 0]])
    frames = np.stack([rest + [[0, 0, 0], [1, 0, 0], [0, 0, 0]]])
    np.testing.assert_allclose(edge_stretch(rest, frames, [[0, 1], [0, 2]]), [1.0])


# ---- penetration depth


def plane(size=4.0):
    """A square in z = 0 facing +z, centred on the origin."""
    h = size / 2
    return np.array([[-h, -h, 0], [h, -h, 0], [h, h, 0], [-h, h, 0]]), np.array([[0, 1, 2], [0, 2, 3]])


def test_bend_change_is_zero_for_a_rigid_turn_and_counts_a_ridge_turned_into_a_valley_twice():
    """A curved sheet (a cylinder's quarter) turned and moved as a whole: no edge bends. Flattened, each
    edge across the curve loses its own bend. One crease pushed in (a row of vertices lifted) is a few
    edges bent far more than the rest: the highest percentile sees it, the median does not. A ridge
    turned into a valley changes by twice its angle, not zero."""
    from scipy.spatial.transform import Rotation

    mesh = grid_mesh(n=11, size=1.0)
    angle = mesh.vertices[:, 0] * (np.pi / 2)
    curved = np.stack([np.sin(angle), mesh.vertices[:, 1], 1 - np.cos(angle)], axis=1)
    tris = mesh.triangles
    turned = curved @ Rotation.from_euler("xyz", [20, -35, 50], degrees=True).as_matrix().T + [3.0, -1.0, 2.0]
    np.testing.assert_allclose(bend_change(curved, turned[None], tris, percentile=100), 0.0, atol=1e-9)
    flat = mesh.vertices
    across = bend_change(curved, flat[None], tris, percentile=[50, 100])[0]
    assert 8.0 < across[1] < 10.0  # the curve turns 90 degrees over 10 columns
    creased = flat.copy()
    creased[np.isclose(flat[:, 0], 0.5), 2] = 0.1
    median, top = bend_change(flat, creased[None], tris, percentile=[50, 100])[0]
    assert median == 0.0 and top > 20.0
    ridge = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.3]])
    valley = ridge * [1, 1, -1]
    flat_pair = ridge * [1, 1, 0]
    pair = [[0, 1, 2], [1, 3, 2]]
    once = bend_change(ridge, flat_pair[None], pair, percentile=100)[0]
    np.testing.assert_allclose(bend_change(ridge, valley[None], pair, percentile=100)[0], 2 * once)


def test_a_point_pushed_behind_a_plane_reports_its_depth():
    vertices, tris = plane()
    points = np.array([[[0.2, 0.1, 0.5], [0.0, 0.0, 0.3]],     # both in front
                       [[0.2, 0.1, 0.5], [0.0, 0.0, -0.3]],    # one pushed 0.3 behind
                       [[0.2, 0.1, -0.1], [0.0, 0.0, -0.3]]])  # the deepest counts
    depth = penetration_depth(points, np.stack([vertices] * 3), tris)
    np.testing.assert_allclose(depth, [0.0, 0.3, 0.3], atol=1e-12)


def test_penetration_follows_the_moving_surface():
    vertices, tris = plane()
    points = np.array([[[0.0, 0.0, 0.2]]] * 2)
    surface = np.stack([vertices, vertices + [0, 0, 0.5]])  # the plane moves out through the point
    np.testing.assert_allclose(penetration_depth(points, surface, tris), [0.0, 0.3], atol=1e-12)


def test_inside_a_closed_surface_is_behind_it_even_nearest_an_edge_or_corner():
    vertices, tris = closed_box()
    inside = [[0.5, 0.5, 0.9], [0.95, 0.5, 0.95], [0.9, 0.9, 0.9]]  # near a face, an edge, a corner
    outside = [[0.5, 0.5, 1.2], [1.2, 0.5, 1.2], [1.1, 1.1, 1.1]]
    np.testing.assert_allclose(signed_distance(inside, vertices, tris), [-0.1, -0.05, -0.1], atol=1e-12)
    np.testing.assert_allclose(signed_distance(outside, vertices, tris), [0.2, np.sqrt(0.08), np.sqrt(0.03)],
                               atol=1e-12)


def test_penetration_depth_scales_with_the_unit():
    vertices, tris = closed_box()
    points = np.array([[[0.5, 0.5, 0.8]]])
    depth_cm = penetration_depth(points, vertices[None], tris)
    depth_mm = penetration_depth(10 * points, 10 * vertices[None], tris)
    np.testing.assert_allclose([depth_cm[0], depth_mm[0]], [0.2, 2.0], atol=1e-12)


# ---- caller mistakes


def test_wrong_shapes_and_indices_are_named():
    rest = np.zeros((3, 3))
    with pytest.raises(ValueError, match=r"positions must have shape \(T, 3, 3\), got \(2, 4, 3\)"):
        turned_triangles(rest, np.zeros((2, 4, 3)), [[0, 1, 2]])
    with pytest.raises(ValueError, match=r"triangles must lie in \[0, 3\), got 3"):
        turned_triangles(rest, rest[None], [[0, 1, 3]])
    with pytest.raises(ValueError, match=r"mask must have shape \(1,\), got \(2,\)"):
        turned_triangles(rest, rest[None], [[0, 1, 2]], mask=[True, False])
    with pytest.raises(ValueError, match=r"moved must have shape \(T, 3, 3\), got \(3, 3\)"):
        rigid_residual(rest, rest)
    with pytest.raises(ValueError, match=r"edges must have shape \(E, 2\), got \(1, 3\)"):
        edge_stretch(rest, rest[None], [[0, 1, 2]])
    with pytest.raises(ValueError, match=r"percentile must be in \[0, 100\], got 101"):
        bend_change(rest, rest[None], [[0, 1, 2]], percentile=101)
    with pytest.raises(ValueError, match=r"triangles must lie in \[0, 3\), got 3"):
        bend_change(rest, rest[None], [[0, 1, 3]])
    vertices, tris = plane()
    with pytest.raises(ValueError, match=r"surface must have shape \(2, W, 3\), got \(1, 4, 3\)"):
        penetration_depth(np.zeros((2, 1, 3)), vertices[None], tris)
    with pytest.raises(ValueError, match=r"points must have shape \(T, N, 3\), got \(1, 3\)"):
        penetration_depth(np.zeros((1, 3)), vertices[None], tris)


def test_a_point_beyond_an_open_surface_border_is_not_behind_it():
    vertices, tris = plane()  # the square spans [-2, 2] in x and y
    beside = [[2.5, 0.0, -0.3], [2.5, 2.5, -0.3]]  # past an edge, past a corner: both slightly behind
    behind = [[1.9, 0.0, -0.3]]                     # over the square: behind it
    np.testing.assert_allclose(signed_distance(beside + behind, vertices, tris),
                               [np.hypot(0.5, 0.3), np.sqrt(0.59), -0.3], atol=1e-12)
    points = np.array([beside + behind])
    np.testing.assert_allclose(penetration_depth(points, vertices[None], tris), [0.3], atol=1e-12)
    np.testing.assert_allclose(penetration_depth(points[:, :2], vertices[None], tris), [0.0], atol=1e-12)
