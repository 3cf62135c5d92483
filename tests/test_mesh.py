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


def test_a_mesh_cannot_be_changed_in_place():
    vertices = np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0]], dtype=float)
    m = Mesh(vertices, [[0, 1, 2]], uv=[[0, 0], [1, 0], [0, 1]], texture=np.zeros((2, 2, 3), np.uint8),
             parts=[0], part_names=["skin"])
    for name in ("vertices", "triangles", "uv", "uv_triangles", "texture", "parts"):
        array = getattr(m, name)
        assert not array.flags.writeable, name
        with pytest.raises(ValueError, match="read-only"):
            array[0] = 1
    vertices[1] = [9, 9, 9]  # the caller's array is the caller's: the mesh kept a copy
    np.testing.assert_array_equal(m.vertices[1], [2, 0, 0])
    for name in ("face_normals", "face_areas", "vertex_normals", "edges"):  # cached values too
        with pytest.raises(ValueError, match="read-only"):
            getattr(m, name)[0] = 0
    split = m.split_at_seams()
    assert not (split.vertices.flags.writeable or split.uv.flags.writeable or split.source_vertex.flags.writeable)


def test_derived_data_cannot_go_stale():
    """The review's case: ``m.vertices[1] *= 3`` left ``face_areas`` stale. Now the write is refused,
    and new positions make a new mesh with its own cache."""
    m = Mesh([[0, 0, 0], [2, 0, 0], [0, 2, 0]], [[0, 1, 2]])
    assert m.face_areas[0] == pytest.approx(2.0)
    with pytest.raises(ValueError, match="read-only"):
        m.vertices[1] *= 3
    assert m.face_areas[0] == pytest.approx(2.0)
    np.testing.assert_array_equal(m.vertices[1], [2, 0, 0])
    bigger = m.with_vertices(m.vertices * [3, 1, 1])
    assert bigger.face_areas[0] == pytest.approx(6.0) and m.face_areas[0] == pytest.approx(2.0)


def test_the_cache_computes_once_and_is_the_one_place_derived_data_lives():
    m = Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    calls = []
    first = m._cached("answer", lambda: calls.append(1) or np.arange(3))
    assert m._cached("answer", lambda: calls.append(1) or np.arange(3)) is first and calls == [1]
    assert not first.flags.writeable
    assert m.face_normals is m.face_normals and "face_normals" in m._cache
    assert not {"face_normals", "answer"} & set(vars(m)) - {"_cache"}  # nothing written beside the cache


def test_an_owned_read_only_array_is_taken_without_a_copy():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=float)
    v.flags.writeable = False
    m = Mesh(v, [[0, 1, 2]])
    assert m.vertices is v
    assert Mesh(m.vertices, m.triangles).vertices is m.vertices  # meshes share their frozen arrays


def test_copies_and_pickles_stay_frozen():
    import copy
    import pickle

    m = two_triangles_with_seam()
    m.face_areas  # noqa: B018 - fill the cache
    for other in (pickle.loads(pickle.dumps(m)), copy.deepcopy(m)):
        np.testing.assert_array_equal(other.vertices, m.vertices)
        assert not (other.vertices.flags.writeable or other.uv.flags.writeable)
        np.testing.assert_allclose(other.face_areas, m.face_areas)
    assert pickle.loads(pickle.dumps(m))._cache == {}  # derived data is recomputed, not carried
