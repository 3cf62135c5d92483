"""The Target type: immutable and checked however it is made."""

import copy
import pickle

import numpy as np
import pytest
from conftest import grid_mesh

from faceanim.errors import InputError
from faceanim.mpeg4 import Fapu
from faceanim.target import Target

FAPU = Fapu(irisd0=1.0, es0=6.0, ens0=4.0, mns0=2.0, mw0=5.0)


def test_points_are_a_read_only_mapping_of_names_to_ints():
    mine = {"2.1": np.int64(3), "8.3": 7}
    target = Target(grid_mesh(4), mine, FAPU)
    assert dict(target.points) == {"2.1": 3, "8.3": 7} and type(target.points["2.1"]) is int
    with pytest.raises(TypeError):
        target.points["2.1"] = 5
    mine["2.1"] = 0  # the caller's dict stays the caller's
    assert target.points["2.1"] == 3
    assert not target.mesh.vertices.flags.writeable
    assert target.ids(["8.3", "2.1"]).tolist() == [7, 3]


@pytest.mark.parametrize("args, error, match", [
    (("mesh", {"2.1": 0}, FAPU), TypeError, "mesh must be a Mesh, got str"),
    ((None, [("2.1", 0)], FAPU), TypeError, "points must map names to vertex ids, got list"),
    ((None, {"2.1": 16}, FAPU), ValueError, r"points\['2.1'\] must lie in \[0, 16\), got 16"),
    ((None, {"2.1": -1}, FAPU), ValueError, r"points\['2.1'\] must lie in \[0, 16\), got -1"),
    ((None, {"2.1": 1.5}, FAPU), TypeError, r"points\['2.1'\] must be an integer vertex id, got 1.5"),
    ((None, {"2.1": True}, FAPU), TypeError, r"points\['2.1'\] must be an integer vertex id, got True"),
    ((None, {2.1: 0}, FAPU), TypeError, "points must be named by strings, got 2.1"),
    ((None, {"2.1": 0}, (1, 2, 3, 4, 5)), TypeError, "fapu must be a Fapu or None, got tuple"),
])
def test_a_target_made_directly_is_checked_naming_the_field(args, error, match):
    mesh = grid_mesh(4)
    with pytest.raises(error, match=match):
        Target(mesh if args[0] is None else args[0], *args[1:])


def test_from_points_still_names_the_file():
    with pytest.raises(InputError, match="p.json: point 2.1 names vertex 99, but the mesh has vertices 0-15"):
        Target.from_points(grid_mesh(4), {"2.1": 99}, FAPU, source="p.json")
    with pytest.raises(InputError, match="p.json: point 2.1 names vertex True"):
        Target.from_points(grid_mesh(4), {"2.1": True}, FAPU, source="p.json")


def test_copies_and_pickles_of_a_target_stay_frozen():
    target = Target(grid_mesh(4), {"2.1": 3}, FAPU)
    for other in (pickle.loads(pickle.dumps(target)), copy.deepcopy(target)):
        assert dict(other.points) == {"2.1": 3} and other.fapu == FAPU
        assert not other.mesh.vertices.flags.writeable
        with pytest.raises(TypeError):
            other.points["2.1"] = 4


def test_the_mouths_width_is_the_distance_between_its_corners_whatever_way_they_lie():
    mesh = grid_mesh(3)  # vertices on a unit grid in the z = 0 plane
    a, b = 0, len(mesh.vertices) - 1  # opposite corners: (0, 0) and (1, 1)
    target = Target(mesh, {"8.3": int(a), "8.4": int(b)}, None)
    assert target.mouth_width == pytest.approx(np.linalg.norm(mesh.vertices[a] - mesh.vertices[b]))
    assert target.mouth_width > abs(mesh.vertices[a, 0] - mesh.vertices[b, 0])  # not across the face only
    assert Target(mesh, {"8.3": int(a)}, None).mouth_width == 0.0
