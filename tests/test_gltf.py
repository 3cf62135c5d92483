
import numpy as np
import pytest
from conftest import grid_mesh, khronos_report

from faceanim.errors import FileFormatError
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


def read_animation(path):
    """A .glb's own data as the file holds it (metres): rest positions ``(S, 3)``, morph targets
    ``(K, S, 3)``, key times ``(N,)``, weights ``(N, K)``, triangle indices ``(F, 3)`` and the mesh's
    ``extras["faceanim"]``."""
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
    rest = read(primitive.attributes.POSITION, 3).astype(np.float64)
    targets = np.stack([read(t["POSITION"], 3) for t in primitive.targets]).astype(np.float64)
    sampler = gltf.animations[0].samplers[0]
    times = read(sampler.input, 1).astype(np.float64)
    weights = read(sampler.output, 1).reshape(len(times), len(targets)).astype(np.float64)
    triangles = read(primitive.indices, 1).reshape(-1, 3).astype(np.int64)
    return rest, targets, times, weights, triangles, (gltf.meshes[0].extras or {}).get("faceanim", {})


def decode(path):
    """Every frame's positions ``(N, S, 3)`` rebuilt from a .glb's rest mesh, morph targets and weights
    animation, in the model's own units (the file's metres divided by its ``metres_per_unit``), and the
    key times."""
    rest, targets, times, weights, _, extras = read_animation(path)
    return (rest + np.einsum("tk,kvc->tvc", weights, targets)) / extras.get("metres_per_unit", 1.0), times


def test_animation_round_trips_through_morph_targets(tmp_path):
    animation = animated_grid()
    morphs = morphs_from_animation(animation, tolerance=1e-6)
    # a bump and a shear, both swinging both ways: two modes, each split into its two signs
    assert morphs.names == ("shape00+", "shape00-", "shape01+", "shape01-")
    assert morphs.weights.min() == 0 and morphs.weights.max() == 1
    np.testing.assert_array_equal(morphs.weights.max(axis=0), 1.0)  # every target reaches its full size
    write_glb(tmp_path / "a.glb", animation.mesh, morphs)
    frames, times = decode(tmp_path / "a.glb")
    np.testing.assert_allclose(frames, animation.positions, atol=1e-5)  # float32 in the file
    np.testing.assert_allclose(times, np.arange(30) / 25.0, atol=1e-6)
    *_, weights, _, _ = read_animation(tmp_path / "a.glb")
    assert weights.min() >= 0 and weights.max() <= 1  # what a client reads, not only what was asked for


def replay(animation, morphs):
    return animation.mesh.vertices + np.einsum("tk,kvc->tvc", morphs.weights, morphs.targets)


def worst(a, b):
    return np.linalg.norm(a - b, axis=-1).max()


def test_a_signed_mode_becomes_two_targets_and_a_one_signed_mode_one():
    mesh = grid_mesh(5)
    lift = np.zeros((25, 3))
    lift[12, 2] = 1.0
    swing = np.sin(np.arange(40) / 5)[:, None, None] * lift  # up and down: the case Blender clamped
    morphs = morphs_from_animation(Animation(mesh, mesh.vertices + swing, 25.0))
    assert morphs.names == ("shape00+", "shape00-")
    up, down = morphs.weights.T
    assert not (up * down).any()  # never both at once
    wave = np.sin(np.arange(40) / 5)
    np.testing.assert_allclose(morphs.targets[0][12], [0, 0, wave.max()], atol=1e-12)  # each at its own peak
    np.testing.assert_allclose(morphs.targets[1][12], [0, 0, wave.min()], atol=1e-12)
    np.testing.assert_allclose(replay(Animation(mesh, mesh.vertices + swing, 25.0), morphs), mesh.vertices + swing,
                               atol=1e-12)
    envelope = np.sin(np.linspace(0, np.pi, 30))[:, None, None] * lift  # onset, apex, offset: rest at both ends
    one = morphs_from_animation(Animation(mesh, mesh.vertices + envelope, 25.0))
    assert len(one.names) == 1 and one.names[0][-1] in "+-" and one.weights[[0, -1], 0].max() == 0


def modes_animation(rng, frames=50, vertices=40, strengths=(1.0, 0.3, 0.05, 0.01, 0.002, 0.0004)):
    """Displacements made of known modes of falling strength, each with a signed time curve."""
    from faceanim.geometry import Mesh

    mesh = Mesh(rng.normal(size=(vertices, 3)), [[0, 1, 2]])
    curves = rng.normal(size=(frames, len(strengths))) * strengths
    shapes = rng.normal(size=(len(strengths), vertices, 3))
    return Animation(mesh, mesh.vertices + np.einsum("tk,kvc->tvc", curves, shapes), 25.0)


@pytest.mark.parametrize("frames", [50, 200])  # fewer frames than coordinates, and more (several chunks)
def test_mode_count_meets_the_tolerance_and_the_count_below_does_not(frames):
    """The streamed two-pass compression equals the truncated SVD of all frames at once, and picks the
    smallest count tried (1, 2, 3, 4, 6, ...) within the tolerance."""
    from faceanim.export.morphs import _COUNTS

    animation = modes_animation(np.random.default_rng(frames), frames=frames)
    size = np.ptp(animation.mesh.vertices, axis=0).max()
    d = (animation.positions - animation.mesh.vertices).reshape(frames, -1)
    U, S, Vt = np.linalg.svd(d, full_matrices=False)  # the plain loop the two passes stand in for

    def svd_error(k):
        shape = animation.positions.shape
        return worst((U[:, :k] * S[:k] @ Vt[:k]).reshape(shape), d.reshape(shape))

    for tolerance in (1e-2, 1e-3, 1e-4):
        morphs = morphs_from_animation(animation, tolerance=tolerance)
        modes = len({name[:-1] for name in morphs.names})
        assert morphs.max_error == pytest.approx(worst(replay(animation, morphs), animation.positions), abs=1e-12)
        below = max([c for c in _COUNTS if c < modes], default=0)
        assert modes in _COUNTS and morphs.max_error <= tolerance * size < svd_error(below)
        assert morphs.max_error == pytest.approx(svd_error(modes), rel=1e-6, abs=1e-9)  # the truncated SVD's own error
        assert morphs.weights.min() >= 0 and morphs.weights.max() <= 1
    capped = morphs_from_animation(animation, tolerance=0.0, max_modes=3)
    assert len({name[:-1] for name in capped.names}) == 3
    assert capped.max_error == pytest.approx(svd_error(3), rel=1e-6)


def test_no_motion_gives_no_targets():
    mesh = grid_mesh(3)
    morphs = morphs_from_animation(Animation(mesh, np.repeat(mesh.vertices[None], 4, axis=0), 25.0))
    assert morphs.names == () and morphs.weights.shape == (4, 0) and morphs.max_error == 0


def test_positions_are_written_in_metres_and_read_back_in_model_units(tmp_path):
    animation = animated_grid()
    centimetres = Animation(Mesh(animation.mesh.vertices * 30, animation.mesh.triangles),
                            animation.positions * 30, animation.fps)  # a 30 cm square
    morphs = morphs_from_animation(centimetres)
    write_glb(tmp_path / "cm.glb", centimetres.mesh, morphs, metres_per_unit=0.01)
    rest, targets, _, _, _, extras = read_animation(tmp_path / "cm.glb")
    assert extras["metres_per_unit"] == 0.01
    np.testing.assert_allclose(np.ptp(rest, axis=0)[:2], [0.3, 0.3], rtol=1e-6)  # metres in the file
    np.testing.assert_allclose(targets, morphs.targets * 0.01, atol=1e-8)
    accessor = read_glb_json(tmp_path / "cm.glb")["accessors"][0]
    assert accessor["max"][0] == pytest.approx(0.3, rel=1e-6)
    back = read_mesh(tmp_path / "cm.glb")
    np.testing.assert_allclose(back.vertices, centimetres.mesh.vertices, rtol=1e-6, atol=1e-6)  # centimetres again
    frames, _ = decode(tmp_path / "cm.glb")
    np.testing.assert_allclose(frames, centimetres.positions, atol=3e-5)


def labelled_grid():
    mesh = grid_mesh(6)
    parts = np.zeros(len(mesh.triangles), np.int64)
    parts[10:14], parts[30:] = 2, 1  # runs 0, 2, 0, 1
    return Mesh(mesh.vertices, mesh.triangles, parts=parts, part_names=("skin", "teeth", "eyes"))


def test_part_labels_travel_run_length_encoded(tmp_path):
    mesh = labelled_grid()
    write_glb(tmp_path / "p.glb", mesh)
    stored = read_glb_json(tmp_path / "p.glb")["meshes"][0]["extras"]["faceanim"]["parts"]
    assert stored == {"part_names": ["skin", "teeth", "eyes"], "part_runs": [[0, 10], [2, 4], [0, 16], [1, 20]]}
    back = read_mesh(tmp_path / "p.glb")
    np.testing.assert_array_equal(back.parts, mesh.parts)
    assert back.part_names == mesh.part_names
    np.testing.assert_array_equal(back.triangles, mesh.triangles)
    write_glb(tmp_path / "plain.glb", grid_mesh(3))
    assert read_mesh(tmp_path / "plain.glb").parts is None


def test_the_avatar_round_trips_with_its_parts_texture_and_units(tmp_path):
    pytest.importorskip("mediapipe", reason="needs faceanim[capture] to make the avatar")
    from faceanim.mpeg4 import metres_per_unit
    from faceanim.portrait import avatar_target

    target = avatar_target()
    mesh = target.mesh
    assert mesh.parts is not None and metres_per_unit(target.fapu) == 0.01  # a face in centimetres
    write_glb(tmp_path / "face.glb", mesh, extras={"points": dict(target.points)}, metres_per_unit=0.01)
    back = read_mesh(tmp_path / "face.glb")
    np.testing.assert_allclose(back.vertices, mesh.vertices, atol=1e-5)
    np.testing.assert_array_equal(back.triangles, mesh.triangles)
    np.testing.assert_array_equal(back.parts, mesh.parts)
    assert back.part_names == mesh.part_names == ("skin", "eyes", "mouth", "teeth")
    assert back.texture.shape == mesh.texture.shape
    assert np.ptp(read_animation_rest(tmp_path / "face.glb"), axis=0).max() < 0.3  # a head, not 16 m of one
    # the avatar read back from its .glb takes an expression like the avatar itself (its parts came along)
    from faceanim.cli import main

    a, b = tmp_path / "a.obj", tmp_path / "b.obj"
    assert main(["express", "--emotion", "joy", "--target", str(tmp_path / "face.glb"), "-o", str(a)]) == 0
    assert main(["express", "--emotion", "joy", "-o", str(b)]) == 0
    np.testing.assert_allclose(read_mesh(a).vertices, read_mesh(b).vertices, atol=1e-3)


def read_animation_rest(path):
    import pygltflib

    gltf = pygltflib.GLTF2().load(str(path))
    accessor = gltf.accessors[gltf.meshes[0].primitives[0].attributes.POSITION]
    return np.array([accessor.min, accessor.max])


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
    signed = np.zeros((3, 2))
    signed[1, 1] = -0.5
    with pytest.raises(ValueError, match=r"weights must lie within \[0, 1\] .*got -0.5 at frame 1, target 'b'"):
        MorphSet(np.zeros((2, 4, 3)), ("a", "b"), weights=signed)
    with pytest.raises(ValueError, match=r"weights must lie within \[0, 1\] .*got 1.5 at frame 0, target 'a'"):
        MorphSet(np.zeros((2, 4, 3)), ("a", "b"), weights=[[1.5, 0], [0, 0]])
    with pytest.raises(ValueError, match=r"default_weights must lie within \[0, 1\] .*got 2 at target 'b'"):
        MorphSet(np.zeros((2, 4, 3)), ("a", "b"), default_weights=[0, 2])
    rounded = MorphSet(np.zeros((1, 4, 3)), ("a",), weights=[[1 + 1e-12], [-1e-12]])  # rounding is clipped
    assert rounded.weights.max() == 1 and rounded.weights.min() == 0
    with pytest.raises(ValueError, match="max_modes must be a whole number of at least 1, got 0"):
        morphs_from_animation(animated_grid(), max_modes=0)
    with pytest.raises(ValueError, match="tolerance must be a non-negative number, got -1"):
        morphs_from_animation(animated_grid(), tolerance=-1)


def test_animation_and_export_errors(tmp_path):
    mesh = grid_mesh(3)
    with pytest.raises(ValueError, match=r"positions must have shape \(T, 9, 3\)"):
        Animation(mesh, np.zeros((2, 4, 3)), 25.0)
    with pytest.raises(ValueError, match="fps must be positive, got 0"):
        Animation(mesh, np.zeros((2, 9, 3)), 0)
    with pytest.raises(ValueError, match="morph targets have 4 vertices, the mesh 9"):
        write_glb(tmp_path / "x.glb", mesh, MorphSet(np.zeros((1, 4, 3)), ("a",)))
    assert not (tmp_path / "x.glb").exists()
    for unit in (0, -0.01, float("nan"), "cm"):
        with pytest.raises(ValueError, match="metres_per_unit must be a positive number"):
            write_glb(tmp_path / "x.glb", mesh, metres_per_unit=unit)
    with pytest.raises(ValueError, match="extras must not hold metres_per_unit: write_glb writes them itself"):
        write_glb(tmp_path / "x.glb", mesh, extras={"metres_per_unit": 1})
    assert not (tmp_path / "x.glb").exists()


def rewrite_extras(source, target, change):
    import pygltflib

    gltf = pygltflib.GLTF2().load(str(source))
    change(gltf.meshes[0].extras["faceanim"])
    gltf.save_binary(str(target))


@pytest.mark.parametrize("change, message", [
    (lambda e: e.update(metres_per_unit=-1), "extras faceanim.metres_per_unit must be a positive number, got -1"),
    (lambda e: e.update(metres_per_unit="cm"), "metres_per_unit must be a positive number, got 'cm'"),
    (lambda e: e["parts"].update(part_runs=[[0, 10]]), "does not label its 50 triangles with its 3 part names"),
    (lambda e: e["parts"].update(part_runs=[[5, 50]]), "does not label its 50 triangles with its 3 part names"),
    (lambda e: e["parts"].pop("part_names"), "must hold part_names and part_runs"),
])
def test_broken_faceanim_extras_are_named(tmp_path, change, message):
    write_glb(tmp_path / "p.glb", labelled_grid())
    rewrite_extras(tmp_path / "p.glb", tmp_path / "broken.glb", change)
    with pytest.raises(FileFormatError, match=message):
        read_mesh(tmp_path / "broken.glb")
