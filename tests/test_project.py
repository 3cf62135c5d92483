import numpy as np
import pytest
from conftest import grid_mesh

from faceanim.geometry import Mesh, closest_point_on_triangles, project_points


def brute_force(mesh, point):
    corners = mesh.vertices[mesh.triangles]
    closest, _ = closest_point_on_triangles(np.repeat(point[None], len(corners), 0), corners)
    d = np.linalg.norm(closest - point, axis=1)
    return d.min()


def bumpy_sphere(n=12):
    rng = np.random.default_rng(5)
    theta, phi = np.meshgrid(np.linspace(0.2, np.pi - 0.2, n), np.linspace(0, 2 * np.pi, n, endpoint=False))
    r = 1 + 0.1 * rng.random(theta.shape)
    v = np.stack([r * np.sin(theta) * np.cos(phi), r * np.sin(theta) * np.sin(phi), r * np.cos(theta)], -1)
    v = v.reshape(-1, 3)
    tris = []
    for i in range(n):
        for j in range(n - 1):
            a, b = i * n + j, ((i + 1) % n) * n + j
            tris += [(a, b, b + 1), (a, b + 1, a + 1)]
    return Mesh(v, np.array(tris))


def test_matches_brute_force_loop():
    mesh = bumpy_sphere()
    points = np.random.default_rng(1).normal(scale=1.2, size=(150, 3))
    hit = project_points(mesh, points)
    expected = [brute_force(mesh, p) for p in points]
    np.testing.assert_allclose(hit.distances, expected, atol=1e-12)
    np.testing.assert_allclose(hit.barycentric.sum(1), 1)
    assert (hit.barycentric >= -1e-12).all()
    np.testing.assert_allclose(hit.interpolate(mesh.vertices), hit.points, atol=1e-12)
    np.testing.assert_allclose(hit.matrix(len(mesh.vertices)) @ mesh.vertices, hit.points, atol=1e-12)


def test_near_points_among_triangles_of_many_sizes_match_brute_force():
    # Near points are settled by their nearest vertex's distance alone, one ball per size class; the
    # sphere's triangles are stretched to sizes a hundredfold apart so that many classes are searched,
    # and the far points still take the growing search.
    mesh = bumpy_sphere(16)
    rng = np.random.default_rng(2)
    squeeze = np.exp(rng.uniform(-2.3, 2.3, size=len(mesh.vertices)))
    stretched = Mesh(mesh.vertices * np.c_[squeeze ** 0.5, np.ones(len(squeeze)), np.ones(len(squeeze))],
                     mesh.triangles)
    on = stretched.vertices[rng.integers(0, len(stretched.vertices), 300)]
    points = np.r_[on + rng.normal(scale=0.01, size=on.shape), rng.normal(scale=4.0, size=(30, 3))]
    hit = project_points(stretched, points)
    expected = [brute_force(stretched, p) for p in points]
    np.testing.assert_allclose(hit.distances, expected, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(hit.points - points, axis=1), hit.distances, atol=1e-12)


def test_closest_point_regions_of_one_triangle():
    tri = np.array([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]])
    cases = {(-1, -1, 0): [1, 0, 0], (2, -1, 0): [0, 1, 0], (-1, 2, 0): [0, 0, 1], (0.5, -1, 3): [0.5, 0.5, 0],
             (1, 1, 0): [0, 0.5, 0.5], (-1, 0.5, 0): [0.5, 0, 0.5], (0.2, 0.3, -1): [0.5, 0.2, 0.3]}
    for point, bary in cases.items():
        _, got = closest_point_on_triangles(np.array([point], float), tri)
        np.testing.assert_allclose(got[0], bary, atol=1e-12)


def test_normal_test_skips_sheets_facing_away():
    """Two touching sheets facing opposite ways (a closed mouth): each point lands on its own sheet."""
    upper = grid_mesh(4)
    lower_vertices = upper.vertices - [0, 0, 0.01]
    lower_tris = upper.triangles[:, ::-1] + len(upper.vertices)  # flipped: faces -z
    both = Mesh(np.vstack([upper.vertices, lower_vertices]), np.vstack([upper.triangles, lower_tris]))
    points = np.array([[0.5, 0.5, -0.004]])  # nearer the upper sheet, but looking down
    assert project_points(both, points).triangles[0] < len(upper.triangles)
    hit = project_points(both, points, normals=[[0, 0, -1]], max_angle=60)
    assert hit.triangles[0] >= len(upper.triangles) and hit.distances[0] == pytest.approx(0.006)


def test_bad_angle():
    with pytest.raises(ValueError, match=r"max_angle must be in \(0, 180\]"):
        project_points(grid_mesh(3), [[0, 0, 0]], max_angle=0)
