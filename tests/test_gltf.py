
import numpy as np
import pytest
from conftest import grid_mesh, khronos_report

from faceanim.export import MorphSet, morphs_from_animation, write_glb
from faceanim.geometry import Mesh, read_mesh
from faceanim.geometry.animation import Animation
from faceanim.geometry.meshio import read_glb_json


def animated_grid(frames=30):
    mesh = grid_mesh(8)
    t = np.arange(frames)[:, None]
    bump = np.exp(-((mesh.vertices[:, :2] - 0.5) ** 2).sum(1) / 0.05)
    positions = mesh.vertices + np.stack([0 * bump, 0 * bump, bump], 1) * np.sin(t / 4)[:, :, None]
    positions[:, :, 0] += 0.1 * mesh.vertices[:, 1] * np.cos(t / 7)
    return Animation(mesh, positions, 25.0)


def decode(path):
    """Rebuild every frame's positions from a .glb's rest mesh, morph targets and weights animation."""
    import pygltflib

    gltf = pygltflib.GLTF2().load(str(path))
    blob = gltf.binary_blob()

    def read(index, width):
        accessor = gltf.accessors[index]
        view = gltf.bufferViews[accessor.bufferView]
        dtype = np.uint32 if accessor.componentType == 5125 else np.float32
        raw = np.frombuffer(blob, dtype=dtype, count=accessor.count * width, offset=view.byteOffset)
        return raw.reshape(accessor.count, width) if width > 1 else raw

    primitive = gltf.meshes[0].primitives[0]
    rest = read(primitive.attributes.POSITION, 3)
    targets = np.stack([read(t["POSITION"], 3) for t in primitive.targets])
    sampler = gltf.animations[0].samplers[0]
    times = read(sampler.input, 1)
    weights = read(sampler.output, 1).reshape(len(times), len(targets))
    return rest + np.einsum("tk,kvc->tvc", weights, targets), times


def test_animation_round_trips_through_morph_targets(tmp_path):
    animation = animated_grid()
    morphs = morphs_from_animation(animation, tolerance=1e-6)
    assert len(morphs.names) == 2  # a bump and a shear: two shapes make every frame
    write_glb(tmp_path / "a.glb", animation.mesh, morphs)
    frames, times = decode(tmp_path / "a.glb")
    np.testing.assert_allclose(frames, animation.positions, atol=1e-5)  # float32 in the file
    np.testing.assert_allclose(times, np.arange(30) / 25.0, atol=1e-6)
    assert np.abs(morphs.weights).max() <= 1 + 1e-12


def test_glb_passes_the_khronos_validator(tmp_path):
    animation = animated_grid()
    write_glb(tmp_path / "a.glb", animation.mesh, morphs_from_animation(animation))
    report = khronos_report(tmp_path / "a.glb")
    assert report["errors"] == 0 and report["warnings"] == 0, report["messages"]


def test_textured_mesh_with_seams_and_named_sliders(tmp_path):
    texture = np.random.default_rng(0).integers(0, 255, size=(16, 16, 3), dtype=np.uint8)
    mesh = Mesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]],
                uv=[[0, 0], [1, 0], [1, 1], [0, 0.5], [0.5, 1]], uv_triangles=[[0, 1, 2], [3, 4, 2]], texture=texture)
    lift = np.zeros((4, 3))
    lift[2, 2] = 1.0
    sliders = MorphSet(np.stack([lift, -lift]), ("AU01", "AU02"))
    write_glb(tmp_path / "s.glb", mesh, sliders)
    meta = read_glb_json(tmp_path / "s.glb")
    assert meta["meshes"][0]["extras"]["targetNames"] == ["AU01", "AU02"] and "animations" not in meta
    report = khronos_report(tmp_path / "s.glb")
    assert report["errors"] == 0 and report["warnings"] == 0, report["messages"]
    back = read_mesh(tmp_path / "s.glb")  # split at the seam for glTF, welded again on reading
    assert np.allclose(back.vertices, mesh.vertices) and np.array_equal(back.triangles, mesh.triangles)
    assert len(back.uv) == 6 and back.texture.shape == (16, 16, 3)
    corners = back.uv[back.uv_triangles]
    assert np.allclose(corners, mesh.uv[mesh.uv_triangles], atol=1e-6)  # every corner keeps its own UV


def test_morph_errors():
    with pytest.raises(ValueError, match="one name per target"):
        MorphSet(np.zeros((2, 4, 3)), ("a",))
    with pytest.raises(ValueError, match=r"weights must have shape \(T, 2\)"):
        MorphSet(np.zeros((2, 4, 3)), ("a", "b"), weights=np.zeros((5, 3)))


def test_animation_and_export_errors(tmp_path):
    mesh = grid_mesh(3)
    with pytest.raises(ValueError, match=r"positions must have shape \(T, 9, 3\)"):
        Animation(mesh, np.zeros((2, 4, 3)), 25.0)
    with pytest.raises(ValueError, match="fps must be positive, got 0"):
        Animation(mesh, np.zeros((2, 9, 3)), 0)
    with pytest.raises(ValueError, match="morph targets have 4 vertices, the mesh 9"):
        write_glb(tmp_path / "x.glb", mesh, MorphSet(np.zeros((1, 4, 3)), ("a",)))
    assert not (tmp_path / "x.glb").exists()
