"""The face's openings (mouth, eyes) on ICT-FaceKit's head, whose parts are known by vertex range."""

import numpy as np
import pytest
from conftest import shared

from faceanim.retarget.contours import OPENINGS, SIDE_CORNERS, opening_rims, opening_sides
from faceanim.retarget.correspondence import _part_with

MOUTH_SOCKET = (11248, 13294)   # ICT-FaceKit's vertex ranges (its README)
EYE_SOCKETS = ((13678, 14062), (13294, 13678))  # right, left: the order of OPENINGS["ibug68"][1:]
FACE = 9409


@pytest.fixture(scope="module")
def ict_head():
    shared("ict_facekit", "ict_deltas_full.npz")
    from ict_scenario import load_ict, remade_face

    model = load_ict()
    head = model.mesh(model.neutral)
    part, kept, local = _part_with(head, model.landmarks)  # the skin with its sockets, as the registration sees it
    face = remade_face(model, model.neutral, np.random.default_rng(0))  # the face region alone, re-made
    return dict(model=model, part=part, kept=kept, local=local, face=face)


def _rim(model, lo, hi):
    """ICT face vertices that share a triangle with the socket ``[lo, hi)``: where the face region ends."""
    t = model.mesh(model.neutral).triangles
    mixed = t[(t < FACE).any(axis=1) & ((t >= lo) & (t < hi)).any(axis=1)]
    return np.unique(mixed[mixed < FACE])


def test_sides_of_the_openings_on_a_head_with_its_sockets(ict_head):
    h = ict_head
    side = np.full(len(h["model"].neutral), -9)
    side[h["kept"]] = opening_sides(h["part"], h["local"], "ibug68")
    assert len(OPENINGS["ibug68"]) == 3
    for k, (lo, hi) in enumerate((MOUTH_SOCKET, *EYE_SOCKETS)):
        inside = np.isin(side[lo:hi], (2 * k + 1, 2 * k + 2))
        assert inside.mean() > 0.99                     # the socket lies inside its opening
        assert {2 * k + 1, 2 * k + 2} <= set(side[lo:hi].tolist())  # and takes both lips' (lids') sides
    lm = h["model"].landmarks
    assert (side[lm[[48, 51, 54, 57, 33, 8, 19]]] == 0).all()  # outer lips, nose, chin, brow: outside
    assert (side[lm[60:68]] == -1).all()                # the inner lip points are on the mouth's loop
    face = side[:FACE]
    assert (face > 0).mean() < 0.1                      # the face itself is outside, but for the inner lips and lids
    lined = np.full(len(h["model"].neutral), -9)
    lined[h["kept"]] = opening_sides(h["part"], h["local"], "ibug68", sided_loop=True)
    assert (lined[lm[61:64]] == 1).all() and (lined[lm[65:68]] == 2).all()  # each lip's line takes its lip's side
    assert (lined[lm[[60, 64]]] == -1).all()            # the corners, where the lines meet, stay on both
    assert (lined[lined != side] > 0).all() and (side[lined != side] == -1).all()  # nothing else changes


def test_a_face_without_sockets_has_the_sides_of_the_head_it_was_cut_from(ict_head):
    """The face region alone (re-triangulated, subdivided, shuffled) ends at open rims inside the lips and
    lids; its vertices take the sides of the ICT vertices they are made of."""
    h = ict_head
    face = h["face"]
    tids = face.index_of[h["model"].landmarks]
    tside = opening_sides(face.mesh, tids, "ibug68")
    truth = np.full(len(h["model"].neutral), -9)
    truth[h["kept"]] = opening_sides(h["part"], h["local"], "ibug68")
    # the side of each target vertex is the side of the ICT vertices it is made of (exact: same surface)
    made_of = face.from_ict.tocoo()
    fits = (truth[made_of.col] == tside[made_of.row]) | (truth[made_of.col] == -1) | (tside[made_of.row] == -1)
    agree = np.zeros(len(tside), dtype=bool)
    agree[made_of.row[fits]] = True
    assert agree.mean() > 0.995
    assert set(tside.tolist()) == set(range(-1, 7))


def test_rims_of_the_same_face_lie_on_its_own_border(ict_head):
    """The full head against its own face region: the rim found inside each eye on the head is the face
    region's border there (where its skin meets the eye sockets), and lands on its own place."""
    h = ict_head
    face = h["face"]
    model = h["model"]
    vertices, points = opening_rims(h["part"], face.mesh, h["local"], face.index_of[model.landmarks],
                                            "ibug68")
    ict = h["kept"][vertices]
    rim = np.concatenate([_rim(model, lo, hi) for lo, hi in EYE_SOCKETS])
    to_rim = np.linalg.norm(model.neutral[ict][:, None] - model.neutral[rim][None], axis=2).min(axis=1)
    spacing = np.linalg.norm(model.neutral[rim][:, None] - model.neutral[rim][None], axis=2)
    np.fill_diagonal(spacing, np.inf)
    edge = np.median(spacing.min(axis=1))
    assert np.isin(ict, rim).mean() > 0.6 and to_rim.max() < 2 * edge  # on the rim, or a ring from it
    assert np.median(np.linalg.norm(points - model.neutral[ict], axis=1)) < 0.01  # cm: lands on its own place


def test_the_lips_sides_differ_between_triangulations_only_at_the_corners(ict_head):
    """The head and its own face region re-made (one surface, two triangulations) split the inner lips into
    upper and lower alike but behind the mouth's corners, where the split follows the edges; the band of
    ``corners`` leaves that patch to both sides and changes nothing else."""
    h = ict_head
    face, lm = h["face"], h["model"].landmarks
    tids = face.index_of[lm]
    mouth = (OPENINGS["ibug68"][0],)
    made_of = face.from_ict.tocoo()
    ends = face.mesh.vertices[tids[[60, 64]]]
    width = np.linalg.norm(ends[1] - ends[0])
    to_corner = np.linalg.norm(face.mesh.vertices[:, None] - ends[None], axis=2).min(axis=1) / width
    labels = {}
    for band in (0.0, SIDE_CORNERS["ibug68"][2]):
        tside = opening_sides(face.mesh, tids, "ibug68", openings=mouth, corners=[band])
        truth = np.full(len(h["model"].neutral), -9)
        truth[h["kept"]] = opening_sides(h["part"], h["local"], "ibug68", openings=mouth, corners=[band])
        differ = (truth[made_of.col] > 0) & (tside[made_of.row] > 0) & (truth[made_of.col] != tside[made_of.row])
        rows = np.unique(made_of.row[differ])
        assert len(rows) and to_corner[rows].max() < 0.1  # 192 differ when written, all within 0.08 widths
        labels[band] = tside
    band = SIDE_CORNERS["ibug68"][2]
    inside = labels[0.0] > 0
    assert (labels[band][inside & (to_corner < band)] == -1).all()
    assert (labels[band][inside & (to_corner >= band)] == labels[0.0][inside & (to_corner >= band)]).all()
    assert (labels[band][~inside] == labels[0.0][~inside]).all()
    with pytest.raises(ValueError, match="corners must hold one non-negative float per opening"):
        opening_sides(face.mesh, tids, "ibug68", openings=mouth, corners=[0.1, 0.2])


def test_band_coordinates_on_a_flat_lid_with_known_lines():
    """A flat sheet facing +z: the lid line along y = 0 from x = 0 to 3, the brow along y = 2. ``u`` is the
    place across the eye (x / 3), ``v`` the height between the lines (y / 2), exactly."""
    from faceanim.geometry.mesh import Mesh
    from faceanim.retarget.contours import _band_coordinates

    xs, ys = np.meshgrid(np.linspace(-1, 4, 11), np.linspace(-1, 3, 9))
    vertices = np.c_[xs.ravel(), ys.ravel(), np.zeros(xs.size)]
    n = xs.shape[1]
    quads = [(r * n + c, r * n + c + 1, (r + 1) * n + c + 1, (r + 1) * n + c)
             for r in range(xs.shape[0] - 1) for c in range(n - 1)]
    triangles = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    mesh = Mesh(vertices, triangles)
    at = {(x, y): i for i, (x, y) in enumerate(zip(xs.ravel().round(3), ys.ravel().round(3), strict=True))}
    lid = [np.array([at[(0.0, 0.0)], at[(0.5, 0.0)], at[(1.0, 0.0)]]), np.array([at[(1.0, 0.0)], at[(3.0, 0.0)]])]
    brow = [np.array([at[(-0.5, 2.0)], at[(1.5, 2.0)], at[(3.5, 2.0)]])]
    ids = np.array([at[(0.0, 0.0)], at[(3.0, 0.0)]])
    u, v, front = _band_coordinates(mesh, ids, [lid, brow], (0, 1, 0, 1), np.array([0.0, 0.0, 1.0]))
    assert np.allclose(u, vertices[:, 0] / 3) and np.allclose(v, vertices[:, 1] / 2) and front.all()


def test_lid_bands_of_the_same_face_land_on_their_own_places(ict_head):
    """The full head against its own face region: the lid skin placed by height between lid and brow lands
    where it is, and none of it comes from the eye sockets' walls (which face forward too, 2 cm behind)."""
    from faceanim.retarget.contours import lid_bands

    h = ict_head
    model = h["model"]
    vertices, points = lid_bands(h["part"], h["face"].mesh, h["local"], h["face"].index_of[model.landmarks],
                                 "ibug68")
    ict = h["kept"][vertices]
    assert len(ict) > 100 and (ict < FACE).all()
    assert np.median(np.linalg.norm(points - model.neutral[ict], axis=1)) < 0.01  # cm


def test_crease_line_finds_a_known_valley():
    """Skin rising forward from the lid line with a fold (a Gaussian valley 0.12 cm wide) at a height that
    rises across the eye, 0.7 to 0.9 cm: the crease found lies on it."""
    from faceanim.retarget.contours import _crease_line

    rng = np.random.default_rng(0)
    u, rise = rng.uniform(0, 1, 20000), rng.uniform(0, 2, 20000)
    fold = 0.7 + 0.2 * u
    depth = 0.3 * rise - 0.15 * np.exp(-((rise - fold) ** 2) / (2 * 0.12 ** 2))
    found = _crease_line(u, rise, depth, np.full(len(u), 2.0), np.ones(len(u), dtype=bool))
    inner = (u > 0.05) & (u < 0.95)
    assert np.abs(found[inner] - fold[inner]).max() < 0.05  # cm


def test_lid_bands_between_brow_and_crease_of_the_same_face_land_on_their_own_places(ict_head):
    """As above, with each lid vertex landed halfway between its place by height between lid and brow and its
    place by height between lid and crease: on the same face both are where it is."""
    from faceanim.retarget.contours import lid_bands

    h = ict_head
    model = h["model"]
    vertices, points = lid_bands(h["part"], h["face"].mesh, h["local"], h["face"].index_of[model.landmarks],
                                 "ibug68", upper="mean")
    ict = h["kept"][vertices]
    assert len(ict) > 100 and (ict < FACE).all()
    assert np.median(np.linalg.norm(points - model.neutral[ict], axis=1)) < 0.02  # cm
