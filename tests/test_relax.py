"""Folds relaxed out of a deformed surface, and nothing else touched."""

import numpy as np
from conftest import grid_mesh

from faceanim.geometry.relax import FoldRelaxer


def test_a_fold_is_relaxed_and_a_frame_without_one_is_left_exactly_as_it_was():
    mesh = grid_mesh(12)
    rest = mesh.vertices
    smooth = rest + 0.05 * np.sin(rest[:, :1] * 3)  # a gentle wave: nothing turns over
    folded = rest.copy()
    centre = np.argmin(np.linalg.norm(rest[:, :2] - 0.5, axis=1))
    folded[centre, :2] += [0.2, 0.2]  # one vertex pulled over its neighbours
    relaxer = FoldRelaxer(rest, mesh.triangles)
    assert relaxer.turned(folded).any()
    out, left = relaxer(np.stack([smooth, folded]))
    np.testing.assert_array_equal(out[0], smooth)
    assert left.tolist() == [0, 0] and not relaxer.turned(out[1]).any()
    far = np.linalg.norm(rest[:, :2] - rest[centre, :2], axis=1) > 0.75
    np.testing.assert_array_equal(out[1, far], folded[far])  # only the fold's neighbourhood moved


def test_a_fold_is_relaxed_over_a_base_motion_and_pinned_vertices_stay_where_they_are_given():
    """The fill replaces only the residual over the base: with the whole sheet lifted and shifted by
    the base, the relaxed fold keeps that motion far from it, and a pinned vertex next to the fold
    stays exactly where it was given."""
    mesh = grid_mesh(12)
    rest = mesh.vertices
    shift = np.array([0.3, -0.2, 0.5])
    base = rest + shift
    centre = np.argmin(np.linalg.norm(rest[:, :2] - 0.5, axis=1))
    folded = base.copy()
    folded[centre, :2] += [0.2, 0.2]
    neighbour = np.argsort(np.linalg.norm(rest - rest[centre], axis=1))[1]
    pinned = np.zeros((1, len(rest)), dtype=bool)
    pinned[0, neighbour] = True
    relaxer = FoldRelaxer(rest, mesh.triangles)
    out, left = relaxer(folded[None], base[None], pinned)
    assert left.tolist() == [0] and not relaxer.turned(out[0]).any()
    np.testing.assert_array_equal(out[0, neighbour], folded[neighbour])
    np.testing.assert_allclose(out[0, centre], base[centre], atol=0.05)  # the fill follows the base, not the rest


def test_a_fold_the_pins_hold_stays_unless_they_yield_and_then_only_pins_near_it_are_freed():
    """The folded vertex itself is pinned: held pins cannot relax it; yielding pins free those
    near the fold (it relaxes), and a pinned vertex far from it stays exactly where it was given."""
    mesh = grid_mesh(12)
    rest = mesh.vertices
    centre = np.argmin(np.linalg.norm(rest[:, :2] - 0.5, axis=1))
    far = np.argmax(np.linalg.norm(rest[:, :2] - rest[centre, :2], axis=1))
    folded = rest.copy()
    folded[centre, :2] += [0.2, 0.2]
    folded[far, 2] += 0.1  # a pinned vertex away from the fold, given off the rest
    pinned = np.zeros((1, len(rest)), dtype=bool)
    pinned[0, [centre, far]] = True
    relaxer = FoldRelaxer(rest, mesh.triangles)
    held, left_held = relaxer(folded[None], None, pinned)
    assert left_held[0] > 0
    np.testing.assert_array_equal(held[0, centre], folded[centre])
    out, left = relaxer(folded[None], None, pinned, pins_yield=True)
    assert left[0] == 0 and not relaxer.turned(out[0]).any()
    np.testing.assert_array_equal(out[0, far], folded[far])
