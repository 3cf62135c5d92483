import numpy as np
import pytest
from conftest import shared
from test_project import bumpy_sphere

from faceanim.geometry import Mesh
from faceanim.retarget import ControlPairs, DenseTransfer, SparseTransfer, transfer_expression


def shuffled(mesh, rng):
    order = rng.permutation(len(mesh.vertices))
    new_index = np.empty_like(order)
    new_index[order] = np.arange(len(order))
    return Mesh(mesh.vertices[order], new_index[mesh.triangles]), new_index


def stretched_past_truth(mesh, made, truth) -> int:
    """How many of ``mesh``'s edges the ``made`` positions stretch past 3 times their length in ``truth``
    (plus half a millimetre on ICT's scale): where neighbours took unlike motions."""
    e = mesh.edges
    made_length = np.linalg.norm(made[e[:, 0]] - made[e[:, 1]], axis=1)
    true_length = np.linalg.norm(truth[e[:, 0]] - truth[e[:, 1]], axis=1)
    return int((made_length > 3 * true_length + 0.05).sum())


def expression_of(mesh, rng):
    bump = np.exp(-((mesh.vertices - [1, 0, 0]) ** 2).sum(1) / 0.3)[:, None]
    return mesh.with_vertices(mesh.vertices + 0.2 * bump * rng.normal(size=3))


def test_clone_onto_a_shuffled_copy_is_exact():
    rng = np.random.default_rng(0)
    source = bumpy_sphere()
    target, new_index = shuffled(source, rng)
    ids = rng.choice(len(source.vertices), 12, replace=False)
    pairs = ControlPairs.checked(ids, new_index[ids], len(source.vertices), len(target.vertices))
    expression = expression_of(source, rng)
    out = transfer_expression(source, expression, target, pairs, method="clone")
    np.testing.assert_allclose(out.vertices[new_index], expression.vertices, atol=1e-9)
    assert out.triangles is target.triangles  # the target's own layout is kept


def test_a_vertex_the_source_does_not_reach_moves_with_its_neighbours():
    """A pocket in the target (a vertex pulled 0.4 deep and 0.35 aside, as inside a nostril) has no source
    surface near it: it takes the mean of its neighbours' motion, not the motion of the far place its
    projection lands on. Vertices the source reaches keep their exact landing."""
    from conftest import grid_mesh

    from faceanim.retarget.transfer import unreached_distance

    flat = grid_mesh(11)
    x, y = flat.vertices[:, 0], flat.vertices[:, 1]
    source = Mesh(np.c_[x, y, 0.3 * (x - 0.5) ** 2 - 0.2 * (y - 0.5) ** 2], flat.triangles)  # a saddle
    pocket = 60  # (0.5, 0.5), inside the grid
    moved = source.vertices.copy()
    moved[pocket] += [0.35, 0.0, -0.4]
    target = Mesh(moved, source.triangles)
    ids = np.array([0, 10, 110, 120, 5, 55, 65, 115])
    motion = np.zeros((len(source.vertices), 3))
    motion[:, 2] = source.vertices[:, 0]  # rises with x
    dense = DenseTransfer(source, target, ControlPairs(ids, ids), register=False, max_angle=180.0)
    assert np.linalg.norm([0.35, 0.4]) > unreached_distance(source.vertices[ids])
    assert np.flatnonzero(dense.unreached).tolist() == [pocket]
    out = dense(motion)
    neighbours = np.unique(source.edges[(source.edges == pocket).any(axis=1)])
    neighbours = neighbours[neighbours != pocket]
    np.testing.assert_allclose(out[pocket], motion[neighbours].mean(axis=0), atol=1e-9)  # 0.5 where it sits
    others = np.setdiff1d(np.arange(len(source.vertices)), np.r_[pocket, neighbours])
    np.testing.assert_allclose(out[others], motion[others], atol=1e-9)


def test_unreached_parts_without_a_reached_neighbour_keep_still():
    from scipy import sparse

    from faceanim.retarget.transfer import _filled_from_neighbours

    mesh = Mesh(np.r_[np.eye(3), np.eye(3) + 5], np.array([[0, 1, 2], [3, 4, 5]]))
    weights = sparse.csr_matrix(np.arange(36, dtype=float).reshape(6, 6))
    filled = _filled_from_neighbours(mesh, weights, np.array([False, False, False, True, True, True])).toarray()
    np.testing.assert_array_equal(filled[:3], weights.toarray()[:3])
    assert not filled[3:].any()


def test_mask_limits_motion():
    rng = np.random.default_rng(1)
    source = bumpy_sphere()
    target, new_index = shuffled(source, rng)
    ids = rng.choice(len(source.vertices), 12, replace=False)
    pairs = ControlPairs(ids, new_index[ids])
    expression = expression_of(source, rng)
    full = transfer_expression(source, expression, target, pairs)
    mask = np.zeros(len(target.vertices))
    mask[:50] = 0.5
    half = transfer_expression(source, expression, target, pairs, mask=mask)
    np.testing.assert_array_equal(half.vertices[50:], target.vertices[50:])
    np.testing.assert_allclose(half.vertices[:50] - target.vertices[:50],
                               0.5 * (full.vertices[:50] - target.vertices[:50]))
    with pytest.raises(ValueError, match=r"mask values must lie in \[0, 1\]"):
        transfer_expression(source, expression, target, pairs, mask=mask + 1)


def test_sparse_transfer_is_exact_at_its_controls_for_many_frames():
    mesh = bumpy_sphere()
    ids = np.arange(0, len(mesh.vertices), 7)
    frames = np.random.default_rng(2).normal(size=(3, len(ids), 3))
    moved = SparseTransfer(mesh, ids)(frames)
    assert moved.shape == (3, len(mesh.vertices), 3)
    np.testing.assert_allclose(moved[:, ids], frames, atol=1e-9)
    with pytest.raises(ValueError, match=r"displacements must have shape \(21, 3\) or \(T, 21, 3\)"):
        SparseTransfer(mesh, ids)(frames[:, :5])


def test_a_faded_transfer_gives_each_vertex_its_share_of_the_motion_in_float64_and_float32_alike():
    from faceanim.retarget.transfer import FAST_FRAMES

    mesh = bumpy_sphere()
    ids = np.arange(0, len(mesh.vertices), 7)
    frames = np.random.default_rng(3).normal(size=(FAST_FRAMES, len(ids), 3))
    transfer = SparseTransfer(mesh, ids)
    full = transfer(frames)  # long enough for the float32 operator, which is made here
    one = transfer(frames[:1])  # a single frame: the float64 product
    share = np.linspace(0.0, 1.0, len(mesh.vertices))
    transfer.fade(share)
    np.testing.assert_allclose(transfer(frames), full * share[None, :, None], atol=1e-5)  # not the stale float32
    np.testing.assert_allclose(transfer(frames[:1]), one * share[None, :, None], atol=1e-12)
    with pytest.raises(ValueError, match=r"share must lie in \[0, 1\]"):
        transfer.fade(np.full(len(mesh.vertices), 1.5))
    with pytest.raises(ValueError, match="share"):
        transfer.fade(np.ones(3))


@pytest.mark.parametrize("source_ids, target_ids, match", [
    ([0, 1, 2], [0, 1], "must pair up, got 3 source and 2 target ids"),
    ([0, 1, 1], [0, 1, 2], r"source ids must be distinct; repeated: \[1\]"),
    ([0, 1, 2], [0, 1, 999], r"target ids must lie in \[0, 144\), got 999"),
])
def test_control_pair_errors(source_ids, target_ids, match):
    with pytest.raises(ValueError, match=match):
        ControlPairs.checked(source_ids, target_ids, 144, 144)


def test_transfer_argument_errors():
    m = bumpy_sphere()
    pairs = ControlPairs(np.arange(4), np.arange(4))
    with pytest.raises(ValueError, match="method must be one of rbf, clone"):
        transfer_expression(m, m, m, pairs, method="blend")
    with pytest.raises(ValueError, match="same mesh"):
        transfer_expression(m, Mesh(m.vertices[:10], [[0, 1, 2]]), m, pairs)
    with pytest.raises(ValueError, match="at least 4 control pairs"):
        DenseTransfer(m, m, ControlPairs(np.arange(3), np.arange(3)))
    with pytest.raises(ValueError, match="metric must be one of"):
        SparseTransfer(m, [0, 1, 2, 3], metric="manhattan")


# ---- ICT-FaceKit: exact ground truth across identities (the benchmark's set-up, four expressions)

@pytest.fixture(scope="module")
def ict_case():
    shared("ict_facekit", "ict_deltas_full.npz")
    from ict_scenario import load_ict, relative_error, remade_face

    rng = np.random.default_rng(11)
    model = load_ict()
    A = model.identity(rng.normal(scale=1.5, size=100))
    B = model.identity(rng.normal(scale=1.5, size=100))
    target = remade_face(model, B, rng)
    names = ["jawOpen", "mouthSmile_L", "eyeBlink_R", "mouthRollLower"]
    deltas = model.expression_deltas[[model.expression_names.index(n) for n in names]]
    truth = np.stack([target.from_ict @ d for d in deltas])
    ids = model.landmarks
    return dict(model=model, source=model.mesh(A), target=target, deltas=deltas, truth=truth, ids=ids,
                tids=target.index_of[ids], score=relative_error)


def test_ict_clone_with_68_landmarks_meets_its_target(ict_case):
    c = ict_case
    rest = c["target"].mesh.vertices
    errors = {}
    for angle in (60.0, 180.0):
        dense = DenseTransfer(c["source"], c["target"].mesh, ControlPairs(c["ids"], c["tids"]), max_angle=angle)
        moved = np.stack([dense.matrix @ d for d in c["deltas"]])
        errors[angle] = c["score"](rest + moved, rest + c["truth"], rest)
    assert errors[60.0].max() < 0.3            # the ceiling for any expression
    # lip roll: the mouth's sides keep the lips apart even with the normal test off (without the sides it
    # was more than twice as far off at 180 degrees as at 60)
    assert errors[180.0][3] < 1.25 * errors[60.0][3]


def test_ict_clone_takes_no_motion_across_the_lids_or_lips(ict_case):
    """No target vertex takes motion from the other side of an eye opening or the mouth (the other lid or
    lip, the skin outside, the socket), judged by the ICT vertices the target vertex is made of (exact
    truth), but in the band left free at the mouth's corners."""
    from faceanim.retarget.contours import SIDE_CORNERS, SIDED, opening_sides
    from faceanim.retarget.correspondence import _part_with

    c = ict_case
    dense = DenseTransfer(c["source"], c["target"].mesh, ControlPairs(c["ids"], c["tids"]))  # registration cached
    part, kept, local = _part_with(c["source"], c["ids"])
    side = np.zeros(len(c["source"].vertices), dtype=np.int64)
    side[kept] = opening_sides(part, local, "ibug68", openings=SIDED["ibug68"], corners=SIDE_CORNERS["ibug68"])
    made_of = c["target"].from_ict
    truth = side[made_of.indices[made_of.indptr[:-1]]]  # the side of each target vertex's first ICT vertex
    weights = dense.matrix.tocoo()
    own = opening_sides(c["target"].mesh, c["tids"], "ibug68", openings=SIDED["ibug68"],
                        corners=SIDE_CORNERS["ibug68"])
    # and a vertex on a lip's (lid's) own line never takes the other lip's motion
    own_lines = opening_sides(c["target"].mesh, c["tids"], "ibug68", openings=SIDED["ibug68"],
                              corners=SIDE_CORNERS["ibug68"], sided_loop=True)
    changed = own_lines != own
    assert changed.sum() > 100 and (own[changed] == -1).all()  # only the lines' vertices take a side
    for sides in (own, own_lines, truth):
        across = (weights.data > 1e-9) & (side[weights.col] != sides[weights.row]) & (side[weights.col] != -1) & \
            (sides[weights.row] != -1)
        crossing = len(np.unique(weights.row[across]))
        if sides is not truth:
            assert crossing == 0  # never across the target's own sides
        else:  # nor across the true ones, but next to the lid lines, where the meshes' loops differ by an edge
            assert crossing < 0.005 * len(truth)  # 90 of 37,280 when written


def test_ict_clone_averaged_with_neighbours_leaves_the_lips_smooth(ict_case):
    """The landings averaged over about 3 mm (2 steps on this subdivided target) where they tear:
    fewer edges stretched well past the truth's (jagged inner lips), no larger error, and every row
    still sums to 1 (a translation of the source is carried exactly)."""
    from faceanim.retarget.transfer import default_smoothing_steps

    c = ict_case
    target = c["target"].mesh
    rest = target.vertices
    pairs = ControlPairs(c["ids"], c["tids"])
    assert default_smoothing_steps(target, rest[c["tids"]]) == 2
    made = {}
    for steps in (None, 0):
        dense = DenseTransfer(c["source"], target, pairs, smoothing_steps=steps)  # the registration is cached
        made[steps] = np.stack([dense.matrix @ d for d in c["deltas"]])
        if steps is None:
            np.testing.assert_allclose(dense.matrix.sum(axis=1), 1.0, atol=1e-9)
    jagged = {k: sum(stretched_past_truth(target, rest + m, rest + t) for m, t in zip(v, c["truth"], strict=True))
              for k, v in made.items()}
    error = {k: np.median(c["score"](rest + v, rest + c["truth"], rest)) for k, v in made.items()}
    assert jagged[None] < jagged[0], (jagged, error)
    assert error[None] <= error[0] * 1.01, (jagged, error)


def test_torn_edges_are_those_whose_landings_stretch_past_the_limit():
    from faceanim.retarget.transfer import TEAR_STRETCH, torn_edges

    vertices = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]])
    edges = np.array([[0, 1], [1, 2], [2, 3]])
    assert not torn_edges(vertices, vertices * 0.5 + 7, edges).any()  # a shrunk, moved copy: all as smooth
    landings = vertices.copy()
    landings[2] += [0, TEAR_STRETCH * 2, 0]  # vertex 2 lands far off its neighbours
    assert torn_edges(vertices, landings, edges).tolist() == [False, True, True]


def test_averaging_only_near_a_tear():
    """Rows more than ``steps`` rings from a torn edge keep their own landing; a copy landing on itself
    is not averaged at all."""
    from conftest import grid_mesh
    from scipy import sparse

    from faceanim.retarget.transfer import _averaged_where_torn

    grid = grid_mesh(11)
    V = len(grid.vertices)
    own = sparse.eye(V, format="csr")
    np.testing.assert_array_equal(_averaged_where_torn(grid, own, grid.vertices, 2, None).toarray(), np.eye(V))
    surface = grid.vertices.copy()
    middle = int(np.argmin(np.linalg.norm(grid.vertices - grid.vertices.mean(axis=0), axis=1)))
    surface[middle] += [0, 0, 1.0]  # the middle vertex lands far above its neighbours
    averaged = _averaged_where_torn(grid, own, surface, 2, None).toarray()
    np.testing.assert_allclose(averaged.sum(axis=1), 1.0)
    rings = np.full(V, np.inf)
    rings[middle] = 0
    for ring in range(1, 4):
        for a, b in grid.edges:
            for u, v in ((a, b), (b, a)):
                if rings[u] == ring - 1 and rings[v] > ring:
                    rings[v] = ring
    changed = np.flatnonzero(np.abs(averaged - np.eye(V)).sum(axis=1) > 0)
    assert set(changed) == set(np.flatnonzero(rings <= 2))  # the torn edges' ends and one ring more


@pytest.mark.parametrize("steps", [-1, 1.5, True, "2"])
def test_smoothing_steps_must_be_a_whole_number(steps):
    source = bumpy_sphere()
    pairs = ControlPairs.checked(np.arange(6), np.arange(6), len(source.vertices), len(source.vertices))
    with pytest.raises(ValueError, match=r"^smoothing_steps must be a whole number, 0 or more, got "):
        DenseTransfer(source, source, pairs, smoothing_steps=steps)


def test_no_averaging_on_a_coarse_mesh():
    from conftest import grid_mesh

    from faceanim.retarget.transfer import default_smoothing_steps

    grid = grid_mesh(6)  # edges 0.2 (diagonals 0.28), points spread about 0.5: a twentieth is 0.025
    assert default_smoothing_steps(grid, grid.vertices) == 0
    fine = grid_mesh(61)  # edges 1/60, corners 0.71 from the centre: 0.035 / 0.0167 rounds to 2
    assert default_smoothing_steps(fine, fine.vertices[[0, 60, 3660, 3720]]) == 2


def test_ict_surface_interpolation_beats_the_thesis_rbf(ict_case):
    c = ict_case
    rest = c["target"].mesh.vertices
    sparse = c["deltas"][:, c["ids"]]
    surface = SparseTransfer(c["target"].mesh, c["tids"])(sparse)
    thesis = SparseTransfer(c["target"].mesh, c["tids"], metric="euclidean", kernel="multiquadric")(sparse)
    ours = c["score"](rest + surface, rest + c["truth"], rest)
    theirs = c["score"](rest + thesis, rest + c["truth"], rest)
    assert np.median(ours) < 0.45 and (ours < theirs).all()


@pytest.mark.parametrize("method", ["clone", "rbf"])
def test_separate_parts_without_controls_keep_still(method):
    """A target's teeth or eyeballs (parts with no control pair) must not pick up the skin's motion."""
    rng = np.random.default_rng(6)
    source = bumpy_sphere()
    inner = Mesh(0.5 * source.vertices, source.triangles)  # a separate part inside the face
    target = Mesh(np.r_[source.vertices, inner.vertices], np.r_[source.triangles, source.triangles + 144])
    ids = rng.choice(144, 12, replace=False)
    expression = expression_of(source, rng)
    out = transfer_expression(source, expression, target, ControlPairs(ids, ids), method=method)
    np.testing.assert_array_equal(out.vertices[144:], inner.vertices)
    np.testing.assert_allclose(out.vertices[ids], expression.vertices[ids], atol=1e-9)  # the skin still moves
