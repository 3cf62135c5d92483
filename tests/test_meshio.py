import numpy as np
import pytest
from conftest import shared

from faceanim.errors import FileFormatError, InputError
from faceanim.geometry import Mesh, read_mesh, write_mesh

OBJ = """# a quad, a pentagon, negative indices and a UV seam
mtllib none.mtl
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 2 0.5 0
v 2 1 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vt 0.5 0.5
usemtl skin
f 1/1 2/2 3/3 4/4
usemtl lips
f -5/5 -2/1 -1/2 3/3 -3/4
"""


def test_obj_quads_and_ngons_are_fanned_in_file_order(tmp_path):
    path = tmp_path / "a.obj"
    path.write_text(OBJ)
    m = read_mesh(path)
    np.testing.assert_array_equal(m.vertices[:, 0], [0, 1, 1, 0, 2, 2])
    np.testing.assert_array_equal(m.triangles, [[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 2], [1, 2, 3]])
    np.testing.assert_array_equal(m.uv_triangles[2], [4, 0, 1])
    assert m.part_names == ("skin", "lips") and m.parts.tolist() == [0, 0, 1, 1, 1]
    assert m.has_seams  # vertex 2 (index 1) has UVs (1,0) and (0.5,0.5)


@pytest.mark.parametrize("text, match", [
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", r"a.obj:4: vertex index 4 is out of range"),
    ("v 0 0 0\nv 1 x 0\n", r"a.obj:2: vertex has a non-numeric token"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", r"a.obj:4: face needs at least 3 corners"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 a\n", r"a.obj:4: vertex index 'a' is not an integer"),
    ("v 0 0 0\n", r"a.obj: has no faces"),
    ("", r"a.obj: is empty"),
    ("v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", r"a.obj:1: vertex has a non-finite coordinate in '0 0 nan'"),
])
def test_malformed_obj_names_file_and_line(tmp_path, text, match):
    path = tmp_path / "a.obj"
    path.write_text(text)
    with pytest.raises(FileFormatError, match=match):
        read_mesh(path)


@pytest.mark.parametrize("name", ["a.obj.gz", "A.OBJ.GZ", "a.Obj.Gz"])
def test_a_gzipped_obj_is_read_whatever_the_case_of_its_suffix(tmp_path, name):
    import gzip

    (tmp_path / name).write_bytes(gzip.compress(OBJ.encode()))
    (tmp_path / "plain.obj").write_text(OBJ)
    np.testing.assert_array_equal(read_mesh(tmp_path / name).triangles, read_mesh(tmp_path / "plain.obj").triangles)


def test_missing_file_and_unknown_format(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        read_mesh(tmp_path / "none.obj")
    with pytest.raises(InputError, match="unknown mesh format '.stl'"):
        read_mesh(tmp_path / "x.stl")


def textured_mesh():
    rng = np.random.default_rng(0)
    tex = rng.integers(0, 255, size=(8, 16, 3), dtype=np.uint8)
    v = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]
    return Mesh(v, [[0, 1, 2], [0, 2, 3]], uv=[[0, 0], [1, 0], [1, 1], [0, 0.5], [0.5, 1]],
                uv_triangles=[[0, 1, 2], [3, 4, 2]], texture=tex)


@pytest.mark.parametrize("suffix", [".obj", ".glb"])
def test_round_trip_keeps_order_seams_and_texture(tmp_path, suffix):
    m = textured_mesh()
    write_mesh(tmp_path / f"m{suffix}", m)
    back = read_mesh(tmp_path / f"m{suffix}")
    np.testing.assert_allclose(back.vertices, m.vertices, atol=1e-6)
    np.testing.assert_array_equal(back.triangles, m.triangles)
    np.testing.assert_allclose(back.uv[back.uv_triangles], m.uv[m.uv_triangles], atol=1e-6)
    np.testing.assert_array_equal(back.texture, m.texture)


def test_ply_round_trip_keeps_vertex_order(tmp_path):
    m = textured_mesh()
    write_mesh(tmp_path / "m.ply", m)
    back = read_mesh(tmp_path / "m.ply")
    np.testing.assert_allclose(back.vertices, m.vertices, atol=1e-6)
    np.testing.assert_array_equal(back.triangles, m.triangles)


def test_failed_write_leaves_nothing(tmp_path):
    with pytest.raises(InputError, match="cannot write mesh format"):
        write_mesh(tmp_path / "m.stl", textured_mesh())
    assert list(tmp_path.iterdir()) == []


def test_ict_neutral_loads_with_order_quads_and_materials():
    path = shared("ict_facekit", "obj", "generic_neutral_mesh.obj")
    m = read_mesh(path)
    assert m.vertices.shape == (26719, 3)
    assert len(m.triangles) == 2 * 25836 + 548  # quads split in two, triangles kept
    assert len(m.part_names) == 12 and "M_Face" in m.part_names
    first_v = [float(x) for x in next(line for line in open(path) if line.startswith("v ")).split()[1:]]
    np.testing.assert_array_equal(m.vertices[0], first_v)
    # ICT's face area is vertices 0-9408, material M_Face (one head triangle also uses only face vertices)
    face_part = m.part_names.index("M_Face")
    in_face_area = m.triangles.max(axis=1) < 9409
    assert (m.parts[in_face_area] == face_part).sum() == in_face_area.sum() - 1 == 18460


def test_mediapipe_canonical_obj_pairs_uvs_through_faces():
    m = read_mesh(shared("mediapipe", "canonical_face_model.obj"))
    assert m.vertices.shape == (468, 3) and m.triangles.shape == (898, 3)
    assert not m.has_seams  # v and vt indices differ, but each vertex has one UV
    uv = m.split_at_seams().uv
    assert uv[10, 1] > 0.85 and uv[152, 1] < 0.1  # forehead at the top of the texture, chin at the bottom
    assert abs(uv[33, 1] - uv[263, 1]) < 1e-6 and uv[33, 0] < 0.5 < uv[263, 0]  # eye corners mirror
