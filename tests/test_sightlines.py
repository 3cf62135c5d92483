"""The teeth cover's sight lines (geometry.sightlines) on a known shape."""

import numpy as np
import trimesh

from faceanim.geometry.mesh import Mesh
from faceanim.geometry.sightlines import SightLines


def test_sight_lines_through_a_slab_give_how_far_its_front_is():
    """A 1 x 1 x 0.3 box seen along z: from behind it its front face is 1.15 ahead, from inside 0.15,
    from in front or beside it nothing; looking back from in front, the front face is 0.85 behind."""
    box = trimesh.creation.box(extents=(1.0, 1.0, 0.3))
    sight = SightLines(Mesh(np.asarray(box.vertices, dtype=np.float64), np.asarray(box.faces)), np.eye(3))
    points = np.array([[0, 0, 1.0], [0, 0, -1.0], [0, 0, 0.0], [2, 0, -1.0], [0.2, 0.1, -0.5]])
    np.testing.assert_allclose(sight.furthest(points, 1.0, 3.0), [0, 1.15, 0.15, 0, 0.65], atol=1e-12)
    np.testing.assert_allclose(sight.furthest(points, -1.0, 3.0), [0.85, 0, 0, 0, 0], atol=1e-12)
    np.testing.assert_allclose(sight.furthest(points, 1.0, 0.5), [0, 0, 0.15, 0, 0], atol=1e-12)

