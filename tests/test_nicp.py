import numpy as np
import pytest
from conftest import grid_mesh

from faceanim.errors import InputError
from faceanim.geometry import Mesh, RbfWarp
from faceanim.geometry.fastop import Float32Operator
from faceanim.geometry.nicp import NicpOptions, register_surface
from faceanim.geometry.project import project_points
from faceanim.geometry.topology import submesh
from faceanim.retarget import ControlPairs, DenseTransfer
from faceanim.retarget.contours import matched_contours
from faceanim.retarget.correspondence import clear_cache, register_faces


def dome(n=24):
    """A smooth open cap (a quarter of a sphere), ``n x n`` vertices, 1 unit across."""
    grid = grid_mesh(n, size=1.2)
    u, v = grid.vertices[:, 0] - 0.6, grid.vertices[:, 1] - 0.6
    return Mesh(np.column_stack([u, v, np.sqrt(2.0 - u ** 2 - v ** 2) - 1.0]), grid.triangles)


def bend(points):
    """A smooth non-rigid deformation: a stretch along x, a bend along y and a shift."""
    x, y, z = points.T
    return np.stack([1.15 * x + 0.05 * y ** 2, y + 0.08 * np.sin(2 * x), z + 0.1 * x ** 2 - 0.05 * y + 0.2], -1)


def test_registration_onto_a_bent_copy_recovers_the_correspondence():
    source = dome()
    truth = bend(source.vertices)
    target = Mesh(truth, source.triangles[:, ::-1][:, ::-1])
    ids = np.array([0, 23, 552, 575, 287, 100, 470])
    reg = register_surface(source, target, source_landmarks=ids, target_points=truth[ids],
                           initial=source.vertices + RbfWarp(source.vertices[ids], truth[ids] - source.vertices[ids])(
                               source.vertices))
    error = np.linalg.norm(reg.vertices - truth, axis=1)
    spacing = np.median(np.linalg.norm(np.diff(source.vertices.reshape(24, 24, 3), axis=1), axis=2))
    assert np.sqrt((error ** 2).mean()) < 0.2 * spacing  # the correspondence, not only the surface
    assert reg.fit < 1e-3
    assert reg.landmark_error < 0.05 * spacing           # landmarks honoured


def test_the_reverse_term_covers_a_target_that_ends_where_the_source_runs_on():
    """The target is the middle of a bent dome; the source is the whole dome. Each target vertex pulls the
    source onto itself, so the registered source covers the target up to its border."""
    source = dome()
    truth = bend(source.vertices)
    grid = np.arange(576).reshape(24, 24)
    middle = np.zeros(576, dtype=bool)
    middle[grid[4:20, 4:20].ravel()] = True
    target, _ = submesh(Mesh(truth, source.triangles), middle)
    ids = grid[[5, 5, 18, 18, 12], [5, 18, 5, 18, 12]]
    start = source.vertices + RbfWarp(source.vertices[ids], truth[ids] - source.vertices[ids])(source.vertices)
    spacing = np.median(np.linalg.norm(np.diff(source.vertices.reshape(24, 24, 3), axis=1), axis=2))
    gaps = {}
    for weight in (0.0, 1.0):
        reg = register_surface(source, target, source_landmarks=ids, target_points=truth[ids], initial=start,
                               options=NicpOptions(reverse_weight=weight))
        gaps[weight] = project_points(Mesh(reg.vertices, source.triangles), target.vertices).distances.max()
        error = np.linalg.norm(reg.vertices[middle] - truth[middle], axis=1)
        assert np.sqrt((error ** 2).mean()) < 0.2 * spacing  # the correspondence still holds
    assert gaps[1.0] < 0.02 * spacing and gaps[1.0] < 0.5 * gaps[0.0]
    with pytest.raises(ValueError, match="reverse_weight must be >= 0, got -1"):
        NicpOptions(reverse_weight=-1.0)


def test_a_source_covering_part_of_the_target_lies_on_it():
    """A face-only source (the generic face) on a whole head: most of the target lies far from the
    registered source, but the source lies on the target, and the registration is taken."""
    source = dome()
    big = grid_mesh(72, size=3.6)  # three times as wide, the source's cap in its middle
    u, v = big.vertices[:, 0] - 1.8, big.vertices[:, 1] - 1.8
    target = Mesh(np.column_stack([u, v, np.sqrt(np.maximum(2.0 - u ** 2 - v ** 2, 0.0)) - 1.0]), big.triangles)
    ids = np.array([0, 23, 552, 575, 287])
    points = source.vertices[ids] + [0.01, 0.0, 0.0]
    reg = register_surface(source, target, source_landmarks=ids, target_points=points)
    assert reg.fit < 1e-3
    assert np.median(project_points(Mesh(reg.vertices, source.triangles), target.vertices).distances) > 0.3


def test_meshes_too_far_apart_without_landmarks_fail_with_the_residual():
    source = dome()
    target = source.with_vertices(source.vertices + [5.0, 0, 0])
    with pytest.raises(InputError, match=r"did not converge: half the target lies farther than [0-9.e+-]+ .*"
                                         r"give corresponding landmarks"):
        register_surface(source, target)


def test_inconsistent_landmarks_fail_with_the_residual():
    source = dome()
    target = source.with_vertices(bend(source.vertices))
    ids = np.array([0, 23, 552, 575])
    wrong = target.vertices[ids[::-1]] + [0, 0, 0.8]  # swapped corners, off the surface
    with pytest.raises(InputError, match=r"landmarks are [0-9.e+-]+ from their places .* control pairs mark the same"):
        register_surface(source, target, source_landmarks=ids, target_points=wrong)


def test_faint_landmarks_count_by_their_weight_in_the_convergence_test():
    """Many faintly weighted landmarks that cannot all be reached (a soft pull, like the eyelids' skin placed by
    relative height) do not fail a registration whose control landmarks hold; at full weight the same points do."""
    source = dome()
    target = source.with_vertices(bend(source.vertices))
    ids = np.array([0, 23, 552, 575, 300])
    soft = np.arange(24 * 12, 24 * 13)  # a row across the middle, pulled 0.1 off the surface
    points = np.r_[target.vertices[ids], target.vertices[soft] + [0, 0, 0.1]]
    landmarks = np.r_[ids, soft]
    reg = register_surface(source, target, source_landmarks=landmarks, target_points=points,
                           landmark_weights=np.r_[np.ones(len(ids)), np.full(len(soft), 0.001)])
    reached = np.linalg.norm(reg.vertices[landmarks] - points, axis=1)
    w = np.r_[np.ones(len(ids)), np.full(len(soft), 0.001)]
    assert reg.landmark_error == pytest.approx(np.sqrt((w * reached ** 2).sum() / w.sum()))
    radius = np.sqrt(((source.vertices - source.vertices.mean(0)) ** 2).sum(1).mean())
    assert np.sqrt((reached ** 2).mean()) > 0.02 * radius  # unweighted, the soft row alone would fail the test
    assert np.linalg.norm(reg.vertices[ids] - target.vertices[ids], axis=1).max() < 0.01  # the controls hold
    with pytest.raises(InputError, match=r"landmarks are [0-9.e+-]+ from their places \(weighted RMS"):
        register_surface(source, target, source_landmarks=landmarks, target_points=points)


def test_options_are_checked():
    with pytest.raises(ValueError, match="stiffness must be a non-empty schedule"):
        NicpOptions(stiffness=())
    with pytest.raises(ValueError, match=r"landmark_weight must be one number >= 0 or one per stiffness stage"):
        NicpOptions(stiffness=(2.0, 1.0), landmark_weight=(1.0, 2.0, 3.0))
    with pytest.raises(ValueError, match=r"source_landmarks must be vertex ids in \[0, 576\)"):
        register_surface(dome(), dome(), source_landmarks=[600], target_points=[[0, 0, 0]])


def test_face_registration_is_cached_per_pair_of_meshes():
    clear_cache()
    source = dome()
    target = source.with_vertices(bend(source.vertices))
    ids = np.array([0, 23, 552, 575, 287])
    first = register_faces(source, target, ids, ids)
    assert register_faces(source, target, ids, ids) is first
    moved = target.with_vertices(target.vertices + [0, 0, 0.01])  # other content, another registration
    assert register_faces(source, moved, ids, ids) is not first


def test_clone_through_the_registration_carries_motion_onto_a_bent_copy():
    source = dome()
    target = Mesh(bend(source.vertices), source.triangles)
    ids = np.array([0, 23, 552, 575, 287, 100, 470])
    dense = DenseTransfer(source, target, ControlPairs(ids, ids))
    motion = np.zeros_like(source.vertices)
    motion[:, 2] = 0.1 * np.exp(-((source.vertices[:, :2] ** 2).sum(1)) / 0.1)  # a smooth bump
    moved = dense(motion)
    assert np.abs(moved - motion).max() < 0.1 * np.abs(motion).max()


def test_contours_of_a_mesh_with_itself_land_on_their_own_vertices():
    source = dome(30)
    ids = np.random.default_rng(0).choice(len(source.vertices), 16, replace=False)
    vertices, points = matched_contours(source, source, ids, ids, "thesis16")
    assert len(vertices)
    np.testing.assert_allclose(points, source.vertices[vertices], atol=1e-12)


def test_float32_operator_within_its_stated_bounds():
    rng = np.random.default_rng(3)
    centres = rng.uniform(-1, 1, size=(60, 3))
    points = rng.uniform(-1.2, 1.2, size=(500, 3))
    M = RbfWarp(centres, np.zeros((60, 3))).operator(points)
    op = Float32Operator(M)
    x = rng.uniform(-2, 2, size=(40, 60, 3))
    error = np.abs(op(x) - np.einsum("nk,tkc->tnc", M, x))
    assert error.max() <= op.probable * 2 <= op.worst_case * 2
    # per output, the worst case scales with the row's own norm
    per_row = (op.worst_case / op.row_norms.max()) * op.row_norms * 2
    assert (error.max(axis=(0, 2)) <= per_row).all()
    assert op(x[0]).shape == (500, 3) and op(x[0]).dtype == np.float64
    with pytest.raises(ValueError, match=r"values must have shape \(60, C\) or \(T, 60, C\)"):
        op(x[:, :5])


def test_sparse_transfer_runs_long_motions_in_float32_within_the_bound():
    from test_project import bumpy_sphere

    from faceanim.retarget import SparseTransfer
    from faceanim.retarget.transfer import FAST_FRAMES

    mesh = bumpy_sphere()
    ids = np.arange(0, len(mesh.vertices), 7)
    spread = SparseTransfer(mesh, ids)
    frames = np.random.default_rng(4).normal(size=(FAST_FRAMES, len(ids), 3))
    fast = spread(frames)
    exact = np.einsum("vk,tkc->tvc", spread.operator, frames)
    assert np.abs(fast - exact).max() <= spread.fast.worst_case * np.abs(frames).max()
    assert spread.fast.worst_case < 1e-4  # a surface operator's rows are small: the guarantee is tight
    np.testing.assert_allclose(spread(frames[:2]), exact[:2], rtol=0, atol=1e-12)  # short runs: float64


def test_the_transfer_command_refuses_pairs_that_do_not_fit_and_writes_nothing(tmp_path):
    import json

    from faceanim import pipeline
    from faceanim.geometry import write_mesh

    source = dome()
    target = source.with_vertices(bend(source.vertices))
    for name, mesh in (("a.obj", source), ("b.obj", source), ("t.obj", target)):
        write_mesh(tmp_path / name, mesh)
    ids = [0, 23, 552, 575, 287]
    (tmp_path / "pairs.json").write_text(json.dumps({"source": ids, "target": [287, 575, 552, 23, 0]}))
    out = tmp_path / "out.obj"
    with pytest.raises(InputError, match=r"^the dense registration did not converge: .* landmarks are [0-9.e+-]+ "):
        pipeline.transfer(tmp_path / "a.obj", tmp_path / "b.obj", tmp_path / "t.obj", out,
                          correspondence=tmp_path / "pairs.json", method="clone")
    assert not out.exists()
