import numpy as np
import pytest

from faceanim.geometry import Mesh


def two_triangles_with_seam():
    v = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]
    t = [[0, 1, 2], [0, 2, 3]]
    uv = [[0, 0], [1, 0], [1, 1], [0, 0.5], [0.5, 1]]  # vertices 0 and 2 get two UVs each
    uvt = [[0, 1, 2], [3, 4, 2]]
    return Mesh(v, t, uv=uv, uv_triangles=uvt)


def test_seam_split_keeps_originals_first_and_corner_uvs():
    m = two_triangles_with_seam()
    s = m.split_at_seams()
    assert len(s.vertices) == 6 and m.has_seams
    np.testing.assert_array_equal(s.source_vertex[:4], np.arange(4))
    np.testing.assert_array_equal(s.vertices, m.vertices[s.source_vertex])
    # every corner of every triangle keeps its position and its UV
    np.testing.assert_array_equal(s.vertices[s.triangles], m.vertices[m.triangles])
    np.testing.assert_array_equal(s.uv[s.triangles], m.uv[m.uv_triangles])


def test_mesh_without_seams_is_not_split():
    m = Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], uv=[[0, 0], [1, 0], [0, 1]])
    assert not m.has_seams and len(m.split_at_seams().vertices) == 3


def test_normals_and_areas():
    m = Mesh([[0, 0, 0], [2, 0, 0], [0, 2, 0]], [[0, 1, 2]])
    np.testing.assert_allclose(m.face_normals, [[0, 0, 1]])
    np.testing.assert_allclose(m.vertex_normals, [[0, 0, 1]] * 3)
    assert m.face_areas[0] == pytest.approx(2.0)


def test_with_vertices_keeps_topology_and_checks_shape():
    m = two_triangles_with_seam()
    moved = m.with_vertices(m.vertices + 1)
    assert moved.triangles is m.triangles and moved.uv is m.uv
    with pytest.raises(ValueError, match=r"vertices must have shape \(4, 3\)"):
        m.with_vertices(np.zeros((3, 3)))


@pytest.mark.parametrize("kwargs, match", [
    (dict(vertices=np.zeros((0, 3)), triangles=np.zeros((0, 3))), "vertices must have at least 1"),
    (dict(vertices=[[0, 0, 0]], triangles=np.zeros((0, 3), int)), "triangles must have at least 1"),
    (dict(vertices=[[0, 0, 0], [1, 0, 0], [0, 1, 0]], triangles=[[0, 1, 3]]), r"triangles must lie in \[0, 3\)"),
    (dict(vertices=[[0, 0, np.inf], [1, 0, 0], [0, 1, 0]], triangles=[[0, 1, 2]]), "vertices must be finite"),
    (dict(vertices=[[0, 0, 0], [1, 0, 0], [0, 1, 0]], triangles=[[0, 1, 2]], uv=[[0, 0]]), "one row per vertex"),
])
def test_bad_meshes_are_named(kwargs, match):
    with pytest.raises(ValueError, match=match):
        Mesh(**kwargs)
