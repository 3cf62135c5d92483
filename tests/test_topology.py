import numpy as np
import pytest
from conftest import grid_mesh

from faceanim.geometry import Mesh
from faceanim.geometry.topology import boundary_loops, component_labels, harmonic_fill, nearest_neighbour_on


def test_boundary_of_a_grid_is_one_counter_clockwise_loop():
    mesh = grid_mesh(4)
    (loop,) = boundary_loops(mesh.triangles)
    assert sorted(loop.tolist()) == [0, 1, 2, 3, 4, 7, 8, 11, 12, 13, 14, 15]
    p = mesh.vertices[loop, :2]
    signed_area = 0.5 * np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1])
    assert signed_area == pytest.approx(1.0)  # counter-clockwise seen from +z, the side the grid faces


def test_a_hole_is_a_second_loop_running_the_other_way():
    mesh = grid_mesh(5)
    centre = 12  # the middle vertex: removing its six triangles opens a hexagonal hole
    triangles = mesh.triangles[~np.isin(mesh.triangles, [centre]).any(axis=1)]
    outline, hole = boundary_loops(triangles)
    assert len(outline) == 16 and sorted(hole.tolist()) == [6, 7, 11, 13, 17, 18]
    p = mesh.vertices[hole, :2]
    assert np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1]) < 0


def test_boundary_errors_and_closed_surfaces():
    tetra = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]]
    assert boundary_loops(tetra) == []
    with pytest.raises(ValueError, match="non-manifold"):
        boundary_loops([[0, 1, 2], [0, 1, 3], [1, 0, 4]])
    with pytest.raises(ValueError, match="two holes meet"):  # two fans touching at vertex 0
        boundary_loops([[0, 1, 2], [0, 3, 4]])


def test_component_labels_split_parts_and_are_cached():
    a = grid_mesh(3)
    mesh = Mesh(np.vstack([a.vertices, a.vertices + 5]), np.vstack([a.triangles, a.triangles + 9]))
    labels = component_labels(mesh)
    assert labels.tolist() == [0] * 9 + [1] * 9
    assert component_labels(mesh) is labels and not labels.flags.writeable


def test_shared_edges_pair_each_inner_edge_with_its_two_triangles_in_the_first_ones_winding():
    from faceanim.geometry.topology import open_edges, shared_edges

    tetrahedron = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    ends, first, second = shared_edges(tetrahedron)
    assert len(ends) == 6 and not len(open_edges(tetrahedron))  # closed: every edge shared
    for (a, b), f, g in zip(ends, first, second, strict=True):
        assert f != g and {a, b} <= set(tetrahedron[f]) and {a, b} <= set(tetrahedron[g])
        row = tetrahedron[f].tolist()
        assert row[(row.index(a) + 1) % 3] == b  # a -> b is how the first triangle runs
        other = tetrahedron[g].tolist()
        assert other[(other.index(b) + 1) % 3] == a  # a consistently wound neighbour runs it the other way
    fin = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])  # three triangles on one edge: a row per consecutive pair
    ends, first, second = shared_edges(fin)
    assert sorted(map(sorted, ends.tolist())) == [[0, 1], [0, 1]]
    assert sorted(zip(first.tolist(), second.tolist(), strict=True)) == [(0, 1), (1, 2)]
    strip = np.array([[0, 1, 2], [2, 1, 3], [2, 3, 4]])
    ends, first, second = shared_edges(strip)
    assert sorted(map(sorted, ends.tolist())) == [[1, 2], [2, 3]] and len(open_edges(strip)) == 5


def test_the_harmonic_fill_of_a_fans_centre_is_the_mean_of_its_rim_and_of_a_strip_is_linear():
    ring = 6
    fan = np.array([[0, 1 + k, 1 + (k + 1) % ring] for k in range(ring)])
    np.testing.assert_allclose(harmonic_fill(fan, ring + 1, np.array([0]), np.arange(1, ring + 1)),
                               np.full((1, ring), 1.0 / ring), atol=1e-8)
    # A path of edges (degenerate triangles) from 0 to 4 held at its ends: the fill is linear between them,
    # and a vertex no held vertex reaches (5, apart) holds 0.
    path = np.array([[0, 1, 1], [1, 2, 2], [2, 3, 3], [3, 4, 4], [5, 5, 5]])
    fill = harmonic_fill(path, 6, np.array([1, 2, 3, 5]), np.array([0, 4]))
    np.testing.assert_allclose(fill @ [0.0, 1.0], [0.25, 0.5, 0.75, 0.0], atol=1e-8)


def test_nearest_neighbour_on_takes_the_shortest_edge_to_an_allowed_vertex_or_none():
    vertices = np.array([[0.0, 0, 0], [1, 0, 0], [0, 0.5, 0], [5, 5, 0], [6, 5, 0], [5, 6, 0]])
    mesh = Mesh(vertices, np.array([[0, 1, 2], [3, 4, 5]]))
    on = np.array([False, True, True, False, False, False])
    np.testing.assert_array_equal(nearest_neighbour_on(mesh, np.array([0, 3]), on), [2, -1])
    with pytest.raises(ValueError, match="sorted"):
        nearest_neighbour_on(mesh, np.array([3, 0]), on)


def test_vertex_adjacency_is_symmetric_ones_on_the_edges():
    from faceanim.geometry.topology import vertex_adjacency

    adjacency = vertex_adjacency([[0, 1], [1, 2], [3, 1]], 5).toarray()
    expected = np.zeros((5, 5))
    for a, b in ((0, 1), (1, 2), (3, 1)):
        expected[a, b] = expected[b, a] = 1
    np.testing.assert_array_equal(adjacency, expected)  # vertex 4 has no edge: an empty row
