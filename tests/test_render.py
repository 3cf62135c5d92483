import numpy as np
import pytest

from faceanim.geometry import Mesh
from faceanim.render import Camera, front_camera, look_at

moderngl = pytest.importorskip("moderngl", reason="rendering needs faceanim[render]")


@pytest.fixture(scope="module")
def renderer():
    from faceanim.render.rasterizer import Renderer

    try:
        r = Renderer(96, 64)
    except RuntimeError as exc:
        pytest.skip(str(exc))
    yield r
    r.close()


def blob(point, size=0.02):
    """A tiny triangle pair (a square) centred at ``point``, facing +z."""
    p = np.asarray(point, dtype=float)
    corners = p + size * np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]])
    return Mesh(corners, [[0, 1, 2], [0, 2, 3]])


def test_look_at_and_projection():
    camera = Camera(look_at([0, 0, 5], [0, 0, 0]), 40.0, 96, 64)
    np.testing.assert_allclose(camera.project([[0, 0, 0]]), [[48, 32]])
    right, up = camera.project([[1, 0, 0], [0, 1, 0]])
    assert right[0] > 48 and up[1] < 32  # +x to the right, +y up (pixel rows go down)


@pytest.mark.parametrize("point", [(0.3, 0.2, 0.0), (-0.5, -0.3, 0.2), (0.0, 0.0, -0.4)])
def test_rendered_position_matches_the_camera_projection(renderer, point):
    camera = Camera(look_at([0.2, 0.1, 4], [0, 0, 0]), 30.0, 96, 64)
    image = renderer.render(blob(point), camera, colour=(255, 0, 0))
    ys, xs = np.nonzero((image[..., 0] > 100) & (image[..., 1] < 100))
    assert len(xs) > 0
    centre = np.array([xs.mean() + 0.5, ys.mean() + 0.5])  # pixel centres
    np.testing.assert_allclose(centre, camera.project([point])[0], atol=1.0)


def test_background_is_drawn_upright_behind_the_mesh(renderer):
    background = np.zeros((64, 96, 3), np.uint8)
    background[:32, :, 0] = 255  # top half red
    background[32:, :, 2] = 255  # bottom half blue
    camera = Camera(look_at([0, 0, 4], [0, 0, 0]), 30.0, 96, 64)
    image = renderer.render(blob((0, 0, 0)), camera, background=background)
    assert image[5, 5].tolist() == [255, 0, 0] and image[58, 5].tolist() == [0, 0, 255]
    assert image[32, 48, 0] != 255 or image[32, 48, 2] != 0  # the mesh covers the middle


def test_textured_mode_shows_the_texture(renderer):
    texture = np.zeros((8, 8, 3), np.uint8)
    texture[..., 1] = 255  # green
    square = Mesh([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], [[0, 1, 2], [0, 2, 3]],
                  uv=[[0, 0], [1, 0], [1, 1], [0, 1]], texture=texture)
    camera = front_camera(square.vertices, 96, 64)
    textured = renderer.render(square, camera, mode="textured")
    shaded = renderer.render(square, camera, mode="shaded")
    centre = textured[32, 48].astype(int)
    assert centre[1] > 150 and centre[0] < 30 and centre[2] < 30
    assert not np.array_equal(textured, shaded)
    wire = renderer.render(square, camera, mode="wireframe")
    assert (np.abs(wire.astype(int) - shaded.astype(int)).sum(axis=2) > 100).any()  # edges drawn


def test_render_errors(renderer):
    square = blob((0, 0, 0))
    with pytest.raises(ValueError, match="mode must be one of shaded, textured, wireframe"):
        renderer.render(square, front_camera(square.vertices, 96, 64), mode="toon")
    with pytest.raises(ValueError, match="camera is 10x10 but the renderer 96x64"):
        renderer.render(square, front_camera(square.vertices, 10, 10))
    with pytest.raises(ValueError, match=r"vertical_fov must be in \(0, 180\)"):
        Camera(np.eye(4), 0.0, 10, 10)


def test_part_colours_and_hidden_parts(renderer):
    left = np.array([[-1.0, -0.5, 0], [-0.1, -0.5, 0], [-0.1, 0.5, 0], [-1.0, 0.5, 0]])
    both = Mesh(np.r_[left, left * [-1, 1, 1]], [[0, 1, 2], [0, 2, 3], [4, 6, 5], [4, 7, 6]], parts=[0, 0, 1, 1],
                part_names=("skin", "overlay"))
    camera = Camera(look_at([0, 0, 4], [0, 0, 0]), 30.0, 96, 64)
    image = renderer.render(both, camera, part_colours={"skin": (0, 0, 255), "overlay": (255, 0, 0)})
    assert image[32, 30, 2] > image[32, 30, 0] and image[32, 66, 0] > image[32, 66, 2]  # blue left, red right
    hidden = renderer.render(both, camera, part_colours={"skin": (0, 0, 255), "overlay": None})
    assert hidden[32, 66].tolist() == [255, 255, 255]  # the overlay part is not drawn


def test_vertex_colours_paint_the_mesh_and_named_parts_keep_theirs(renderer):
    left = np.array([[-1.0, -0.5, 0], [-0.1, -0.5, 0], [-0.1, 0.5, 0], [-1.0, 0.5, 0]])
    both = Mesh(np.r_[left, left * [-1, 1, 1]], [[0, 1, 2], [0, 2, 3], [4, 6, 5], [4, 7, 6]], parts=[0, 0, 1, 1],
                part_names=("skin", "eye"))
    paint = np.array([[0, 255, 0]] * 4 + [[0, 0, 255]] * 4, dtype=np.uint8)
    camera = Camera(look_at([0, 0, 4], [0, 0, 0]), 30.0, 96, 64)
    image = renderer.render(both, camera, vertex_colours=paint, part_colours={"eye": (255, 0, 0)})
    assert image[32, 30].argmax() == 1  # the painted part shows its paint (green)
    assert image[32, 66].argmax() == 0  # the part named in part_colours keeps its colour (red)
    with pytest.raises(ValueError, match=r"vertex_colours must have shape \(8, 3\)"):
        renderer.render(both, camera, vertex_colours=paint[:4])


def test_light_from_above_shades_upward_faces_brighter(renderer):
    # two strips tilted 45 degrees, one facing up and toward the camera, one facing down and toward it
    up = np.array([[-1.0, 0.1, 0], [1.0, 0.1, 0], [1.0, 0.6, -0.5], [-1.0, 0.6, -0.5]])
    down = np.array([[-1.0, -0.1, 0], [1.0, -0.1, 0], [1.0, -0.6, -0.5], [-1.0, -0.6, -0.5]])
    mesh = Mesh(np.r_[up, down], [[0, 1, 2], [0, 2, 3], [4, 6, 5], [4, 7, 6]])
    camera = Camera(look_at([0, 0, 4], [0, 0, 0]), 30.0, 96, 64)
    frontal = renderer.render(mesh, camera).astype(int)
    assert abs(frontal[24, 48].sum() - frontal[40, 48].sum()) < 6  # lit from the camera: both alike
    above = renderer.render(mesh, camera, light=(0.0, 1.0, 0.0)).astype(int)
    assert above[24, 48].sum() > above[40, 48].sum() + 100  # lit from above: the upward strip is brighter


def test_unproject_inverts_project():
    camera = Camera(look_at([0.3, 0.2, 5], [0, 0, 0]), 35.0, 96, 64)
    points = np.random.default_rng(0).normal(size=(20, 3))
    distance = -(np.c_[points, np.ones(20)] @ camera.world_to_camera.T)[:, 2]
    np.testing.assert_allclose(camera.unproject(camera.project(points), distance), points, atol=1e-12)


def test_bad_background_and_video_left_half_written(renderer, tmp_path):
    square = blob((0, 0, 0))
    with pytest.raises(ValueError, match=r"background must be a \(64, 96, 3\) uint8 image, got \(10, 10, 3\)"):
        renderer.render(square, front_camera(square.vertices, 96, 64), background=np.zeros((10, 10, 3), np.uint8))
    pytest.importorskip("av", reason="video needs faceanim[capture]")
    from faceanim.render.video import video_writer

    with pytest.raises(RuntimeError, match="stopped"):
        with video_writer(tmp_path / "v.mp4", 25, 32, 32) as write:
            write(np.zeros((32, 32, 3), np.uint8))
            raise RuntimeError("stopped")
    assert list(tmp_path.iterdir()) == []  # nothing half-written


def test_letterbox_keeps_the_whole_frame():
    from faceanim.pipeline import _letterbox

    wide = np.full((360, 640, 3), 200, np.uint8)
    boxed = _letterbox(wide, 480)
    lit_rows = np.flatnonzero(boxed[:, 240, 0])
    assert boxed.shape == (480, 480, 3) and (boxed[240, [0, 479], 0] == 200).all()  # full width kept
    assert lit_rows.min() == 105 and lit_rows.max() == 374  # 270 rows, centred
