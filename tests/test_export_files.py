import numpy as np
import pytest
from test_gltf import animated_grid

from faceanim.errors import InputError
from faceanim.export import objseq, write_obj_sequence
from faceanim.geometry import Mesh, read_mesh
from faceanim.geometry.animation import Animation


def test_obj_sequence_replays_every_frame_with_one_material(tmp_path):
    animation = animated_grid(frames=5)
    mesh = animation.mesh
    textured = Mesh(mesh.vertices, mesh.triangles, uv=mesh.vertices[:, :2], texture=np.zeros((4, 4, 3), np.uint8))
    paths = write_obj_sequence(tmp_path / "seq", Animation(textured, animation.positions, animation.fps))
    assert [p.name for p in paths] == [f"frame_{t:05d}.obj" for t in range(5)]
    assert sorted(p.name for p in (tmp_path / "seq").iterdir() if p.suffix != ".obj") == ["face.mtl", "face.png"]
    for t, path in enumerate(paths):
        back = read_mesh(path)
        assert np.allclose(back.vertices, animation.positions[t], atol=1e-6) and back.texture is not None


def test_obj_sequence_appears_whole_or_not_at_all(tmp_path, monkeypatch):
    animation = animated_grid(frames=6)
    written = []

    def failing(mesh, **kwargs):
        if len(written) == 3:
            raise OSError("disk full")
        written.append(1)
        return "v 0 0 0\n"

    monkeypatch.setattr(objseq, "obj_text", failing)
    with pytest.raises(OSError, match="disk full"):
        write_obj_sequence(tmp_path / "seq", animation)
    assert list(tmp_path.iterdir()) == []  # neither the folder nor the hidden one it was built in
    (tmp_path / "taken").mkdir()
    (tmp_path / "taken" / "x").write_text("x")
    with pytest.raises(InputError, match="taken: exists and is not an empty folder"):
        write_obj_sequence(tmp_path / "taken", animation)
