"""The mouth's inside told apart from the lips (faceanim.parts.mouth), and moved as a socket."""

from unittest import mock

import numpy as np
import pytest
import trimesh
from conftest import shared

from faceanim.geometry.mesh import Mesh
from faceanim.geometry.topology import open_edges
from faceanim.parts.mouth import RIM_LOOP, mouth_inside
from faceanim.target import Target

FORWARD = np.array([0.0, 0.0, 1.0])
WIDTH = 1.0  # the "mouth's width" on the unit ball: what is cut off must reach 0.2 behind the rims


def ringed_ball(height: float, names=RIM_LOOP[::2], *, open_back: bool = False):
    """A ball of radius 1 with the named rim points round the ring at ``height`` along +z (the face's
    forward), in order; with ``open_back`` the cap behind the ring is cut away (a mouth that opens onto
    a hole)."""
    ball = trimesh.creation.icosphere(subdivisions=4)
    vertices, triangles = np.asarray(ball.vertices), np.asarray(ball.faces)
    if open_back:
        triangles = triangles[(vertices[triangles][:, :, 2] > height).any(axis=1)]
    angles = np.linspace(0.0, 2 * np.pi, len(names), endpoint=False)
    across = np.sqrt(1.0 - height ** 2)
    ring = np.stack([across * np.cos(angles), across * np.sin(angles), np.full(len(names), height)], axis=1)
    # On an open ball the rims lie on the hole's edge, as a mouth's inner rims lie on its opening.
    candidates = np.unique(open_edges(triangles)) if open_back else np.unique(triangles)
    ids = candidates[np.argmin(np.linalg.norm(vertices[candidates][None] - ring[:, None], axis=2), axis=1)]
    mesh = Mesh(vertices, triangles)
    return mesh, Target(mesh, dict(zip(names, ids.tolist(), strict=True)), None)


def test_the_skin_cut_off_behind_the_rims_is_the_mouths_inside():
    mesh, target = ringed_ball(-0.5)
    skin = np.ones(len(mesh.vertices), dtype=bool)
    inside = mouth_inside(mesh, skin, target, FORWARD, WIDTH)
    z = mesh.vertices[:, 2]
    assert inside.any() and z[inside].max() < -0.5 + 0.1  # behind the ring, up to the loop's zigzag
    assert inside[z < -0.65].all()  # the whole back cap past the loop
    assert not inside[list(target.points.values())].any()  # the rims themselves stay skin
    # What is not skin (another part: here the back cap's pole) is never taken; the rest still is.
    partial = skin & (z > -0.9)
    inside = mouth_inside(mesh, partial, target, FORWARD, WIDTH)
    assert inside[(z < -0.65) & partial].all() and not inside[~partial].any()


@pytest.mark.parametrize("case", ["in front", "open", "too large", "no corner", "few points", "rim off the skin"])
def test_nothing_is_cut_off_where_there_is_no_closed_mouth_behind_the_rims(case):
    """A ring round the front (what it cuts off lies in front of the lips), a ring round a hole, a ring
    round the middle (what it cuts off is as large as the face: no mouth is), or a target without both
    inner corners (2.4, 2.5), with fewer than 6 rim points or with a rim point off the skin: nothing is
    the mouth's inside."""
    names = RIM_LOOP[::2]
    if case == "no corner":
        names = tuple(n for n in names if n != "2.4")
    if case == "few points":
        names = ("2.5", "2.7", "2.4", "2.3")
    height = {"in front": 0.5, "too large": -0.05}.get(case, -0.5)
    mesh, target = ringed_ball(height, names, open_back=case == "open")
    skin = np.ones(len(mesh.vertices), dtype=bool)
    if case == "rim off the skin":
        skin[target.points[names[1]]] = False
    assert not mouth_inside(mesh, skin, target, FORWARD, WIDTH).any()


def test_a_skin_that_is_all_rim_has_no_inside():
    """Six rim points that are the whole skin (a hexagon fanned from one corner): the loop leaves nothing
    to cut off, and nothing is, without an error."""
    angles = np.linspace(0.0, 2 * np.pi, 6, endpoint=False)
    mesh = Mesh(np.stack([np.cos(angles), np.sin(angles), np.zeros(6)], axis=1),
                np.array([[0, k, k + 1] for k in range(1, 5)]))
    names = [RIM_LOOP[k] for k in (0, 3, 6, 10, 13, 16)]  # both corners (2.5, 2.4) among them, in order
    target = Target(mesh, dict(zip(names, range(6), strict=True)), None)
    assert not mouth_inside(mesh, np.ones(6, dtype=bool), target, FORWARD, WIDTH).any()


@pytest.fixture(scope="module")
def wide_open_pair():
    """ICT's round trip, pair 100 (identity A's exact jawOpen at the points placed on it drives identity
    B, no video): the truth, B's rest, and B moved, with its mouth's inside cut off and without."""
    shared("ict_facekit")
    from ict_scenario import load_ict
    from roundtrip_ict import exact_run

    model = load_ict()
    A, B = model.random_identities(np.random.default_rng(100))
    opening = model.expression_deltas[list(model.expression_names).index("jawOpen")]
    deltas = np.stack([np.zeros_like(opening), opening])
    moved = exact_run(model, A, B, deltas)[1]
    with mock.patch("faceanim.parts.mouth_inside", lambda mesh, *_: np.zeros(len(mesh.vertices), dtype=bool)):
        lined = exact_run(model, A, B, deltas)[1]
    return B + opening, B, moved, lined


def test_a_wide_open_mouth_keeps_the_upper_lips_lining_up(wide_open_pair):
    """Cut off, the upper lip's lining (the skin behind its inner rim that the truth moves under 0.6 cm)
    stays near the truth; through the bag, the fold fill and the jaw's raise hung it over the open
    mouth, and the lower lip stopped short."""
    from ict_scenario import FACE_VERTICES

    truth, rest, moved, lined = wide_open_pair
    face = np.arange(len(rest)) < FACE_VERTICES
    behind_upper_rim = face & (np.linalg.norm(truth - rest, axis=1) < 0.6) & (rest[:, 1] < -2.9) & (rest[:, 1] > -3.1)
    behind_upper_rim &= (rest[:, 2] > 10.0) & (np.abs(rest[:, 0]) < 1.5)
    error = {k: np.median(np.linalg.norm(p[behind_upper_rim] - truth[behind_upper_rim], axis=1))
             for k, p in (("cut", moved), ("lined", lined))}
    assert behind_upper_rim.sum() > 10
    assert error["cut"] < 0.2 < 0.6 < error["lined"], error  # 0.06 against 0.91


@pytest.fixture(scope="module")
def ict_own_opening():
    """ICT's neutral with its control points placed, its parts, and its own jawOpen at those points."""
    shared("ict_facekit")
    from ict_scenario import load_ict

    from faceanim.parts import face_parts
    from faceanim.retarget.placement import auto_target

    model = load_ict()
    target = auto_target(model.mesh(model.neutral))
    opening = model.expression_deltas[list(model.expression_names).index("jawOpen")]
    return target, face_parts(target), opening


def test_the_mouths_inside_hangs_between_the_lips_and_the_gums(ict_own_opening, monkeypatch):
    """ICT's own jawOpen at its control points: the upper lip's lining (the inside that the truth moves
    under 0.6 cm) stays within about a millimetre of the truth, held by the gums deep inside. Hung from
    the rims alone it hangs from the lower lip too, through the back of the mouth (0.34 cm off)."""
    import faceanim.retarget.deform as deform

    target, parts, opening = ict_own_opening
    ids = np.unique(target.ids(list(target.points)))
    displacements = np.stack([np.zeros((len(ids), 3)), opening[ids]])
    truth = target.mesh.vertices + opening
    upper_lining = parts.mask("socket") & (np.linalg.norm(opening, axis=1) < 0.6)
    upper_lining[9409:] = False  # ICT's face; beyond it lies its separate mouth socket
    assert upper_lining.sum() > 50

    def off() -> float:
        moved = deform.deform_parts(target, parts, ids, displacements)[1]
        return float(np.median(np.linalg.norm(moved[upper_lining] - truth[upper_lining], axis=1)))

    held = off()
    monkeypatch.setattr(deform, "_GUM_DEPTH", np.inf)
    assert held < 0.15 < 0.25 < off(), held


def test_the_mouths_inside_rides_on_the_lip_it_is_joined_to(ict_own_opening):
    """Each rim vertex of the cut-off inside rides on a skin vertex it shares an edge with (across the
    face the upper lip's lining can lie nearer the lower lip's edge than the upper's)."""
    from faceanim.retarget.deform import PartsDeformer

    target, parts, _ = ict_own_opening
    deformer = PartsDeformer(target, parts, np.unique(target.ids(list(target.points))), relax=False)
    riders, corners, _ = deformer._riders
    mesh = target.mesh
    face_socket = parts.mask("socket") & (np.arange(len(mesh.vertices)) < 9409)
    rims = np.isin(riders, np.flatnonzero(face_socket))
    assert rims.sum() > 20
    edges = {tuple(e) for e in np.sort(mesh.edges, axis=1).tolist()}
    on = deformer.skin_ids[corners[rims, 0]]
    assert all(tuple(sorted((int(r), int(v)))) in edges for r, v in zip(riders[rims], on, strict=True))


def test_the_mouths_inside_turns_with_the_jaw_below_the_bite_and_in_front_of_the_turning_centre(ict_own_opening):
    """ICT's inside runs on into the throat: the floor of the mouth (below the bite, in front of the
    jaw's turning centre) has the jaw's full weight, the throat behind the centre none."""
    target, parts, _ = ict_own_opening
    inside = parts.mask("socket")
    depth = (target.mesh.vertices - parts.hinge) @ parts.axes[2]
    lower_lip = target.mesh.vertices[target.points["2.3"]]
    below = (lower_lip - target.mesh.vertices) @ parts.axes[1]
    floor = inside & (np.linalg.norm(target.mesh.vertices - lower_lip, axis=1) < 1.5) & (below > 0.3) & (depth > 1.0)
    throat = inside & (depth < -1.0)
    assert floor.sum() > 10 and throat.sum() > 10
    assert parts.jaw_weight[floor].min() > 0.9 and parts.jaw_weight[throat].max() == 0.0


def test_a_parts_file_keeps_what_it_calls_skin(ict_own_opening):
    """Given a parts file, nothing is cut off: the user said what the skin is."""
    from faceanim.parts import face_parts

    target, parts, _ = ict_own_opening
    labelled = face_parts(target, labels={"skin": [[0, 9408]]})
    assert parts.mask("socket")[:9409].any() and not labelled.mask("socket")[:9409].any()


def test_a_lip_rim_the_inside_borders_all_round_is_left_out_of_the_spread(tmp_path):
    """ICT identity pair 310: the mouth's inside, cut off, borders B's control mp88 on every side, so it
    lies on no skin triangle. The deformation leaves it out (it made the spread fail with "control_vertices
    must be distinct"), and the face still follows the jaw."""
    shared("ict_facekit")
    from ict_scenario import load_ict
    from roundtrip_ict import exact_run

    from faceanim import pipeline
    from faceanim.geometry import write_mesh
    from faceanim.parts import face_parts
    from faceanim.retarget.deform import PartsDeformer

    model = load_ict()
    A, B = model.random_identities(np.random.default_rng(310))
    write_mesh(tmp_path / "B.obj", model.mesh(B))
    target = pipeline.load_target(tmp_path / "B.obj")
    parts = face_parts(target)
    ids = np.unique(target.ids([n for n in target.points if n.startswith("mp")]))
    left_out = parts.mask("skin")[ids] & ~PartsDeformer(target, parts, ids).in_spread
    assert left_out.any()  # the case this test is for: a skin control on no skin triangle
    opening = model.expression_deltas[list(model.expression_names).index("jawOpen")]
    moved = exact_run(model, A, B, np.stack([np.zeros_like(opening), opening]))
    chin = np.argmin(opening[:, 1])  # the vertex the truth drops furthest
    np.testing.assert_allclose(moved[0], B, atol=1e-9)
    assert moved[1, chin, 1] - B[chin, 1] < 0.5 * opening[chin, 1] < 0, (moved[1, chin] - B[chin], opening[chin])
