import numpy as np
import pytest
from conftest import khronos_report, shared

from faceanim import pipeline, portrait
from faceanim.capture.avatar import AVATAR_PARTS
from faceanim.errors import InputError
from faceanim.geometry import read_mesh
from faceanim.geometry.meshio import glb_extras
from faceanim.geometry.topology import boundary_loops, component_labels
from faceanim.landmarks import FEATURE_POINT_LANDMARK
from faceanim.mpeg4 import fap_table
from faceanim.mpeg4.fapfile import read_fap
from faceanim.retarget.decode import animate_faps


@pytest.fixture(scope="module")
def astronaut():
    image, _ = portrait.portrait()
    landmarks = portrait.portrait_landmarks(image, "astronaut")
    return image, landmarks, portrait.avatar_target(image=image, landmarks=landmarks)


def test_avatar_is_opened_at_eyes_and_mouth_with_parts_behind(astronaut):
    _, _, target = astronaut
    mesh = target.mesh
    assert mesh.part_names == AVATAR_PARTS and set(np.unique(mesh.parts)) == {0, 1, 2, 3}
    skin = mesh.triangles[mesh.parts == 0]
    assert len(boundary_loops(skin)) == 4  # the outline, two eyes, the mouth
    normals = mesh.face_normals
    piece = component_labels(mesh)[mesh.triangles[:, 0]]
    mouth = mesh.parts == 2
    pieces, sizes = np.unique(piece[mouth], return_counts=True)
    fan = mouth & (piece == pieces[sizes.argmin()])  # the fan (80 triangles), not its lining (160)
    for faces in (mesh.parts == 1, fan, mesh.parts == 3):  # eyes, mouth and teeth face out of the face, behind the skin
        # (the mouth's fan's mean is the lowest: 0.50 on FaceMesh's landmarks, 0.49 on the Face Landmarker's)
        assert normals[faces, 2].mean() > 0.45
    # The mouth's lining, from the lips' inner edge back to the fan's rim, faces forward as every part does.
    assert (normals[mouth & ~fan, 2] >= 0).all() and (mouth & ~fan).sum() == 2 * fan.sum()


def test_avatar_points_and_fapu(astronaut):
    _, _, target = astronaut
    observed = {n for n, i in FEATURE_POINT_LANDMARK.items()}
    assert observed <= set(target.points)
    v = target.mesh.vertices
    assert v[target.points["3.5"], 0] > 0 > v[target.points["3.6"], 0]  # 3.5 is the left pupil (+x)
    assert target.mesh.parts[np.flatnonzero((target.mesh.triangles == target.points["3.5"]).any(axis=1))[0]] == 1
    # an adult face in centimetres: iris about 1.2 cm, mouth about 5 cm wide, eyes about 6 cm apart
    assert 0.8 < target.fapu.irisd0 < 1.6 and 4.0 < target.fapu.mw0 < 8.0 and 5.0 < target.fapu.es0 < 8.0


def test_texture_shows_the_photo_where_the_points_are(astronaut):
    image, landmarks, target = astronaut
    mesh = target.mesh
    h, w = mesh.texture.shape[:2]
    uv = mesh.uv[:468]
    rows = np.clip(((1 - uv[:, 1]) * h).astype(int), 0, h - 1)
    cols = np.clip((uv[:, 0] * w).astype(int), 0, w - 1)
    seen = mesh.texture[rows, cols].astype(float)
    px = (landmarks[:468, :2] * [image.shape[1], image.shape[0]]).astype(int)
    truth = image[px[:, 1], px[:, 0]].astype(float)
    error = np.abs(seen - truth).mean(axis=1)
    shuffled = np.abs(seen - truth[np.random.default_rng(0).permutation(468)]).mean(axis=1)
    assert np.median(error) < 12 and np.median(error) < 0.3 * np.median(shuffled)


def test_avatar_glb_carries_its_points_and_validates(tmp_path):
    out = tmp_path / "face.glb"
    target = pipeline.avatar(shared("videos", "single_face.jpg"), out)
    assert glb_extras(out)["points"] == target.points
    again = pipeline.load_target(out)  # no placement: the points come with the file
    assert again.points == target.points
    assert np.allclose(again.mesh.vertices, target.mesh.vertices, atol=1e-5)
    assert np.array_equal(again.mesh.triangles, target.mesh.triangles)
    assert read_mesh(out).texture is not None
    (tmp_path / "plain.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    assert glb_extras(tmp_path / "plain.obj") == {}  # other formats carry nothing, and are not opened as GLB
    report = khronos_report(out)
    assert report["errors"] == 0 and report["warnings"] == 0


def test_avatar_bad_input(tmp_path):
    blank = tmp_path / "blank.png"
    from PIL import Image

    Image.fromarray(np.full((200, 200, 3), 128, np.uint8)).save(blank)
    with pytest.raises(InputError, match="blank.png: the face tracker finds no face in it"):
        pipeline.avatar(blank, tmp_path / "face.glb")
    with pytest.raises(InputError, match="face.obj: this output is written as .glb"):
        pipeline.avatar(blank, tmp_path / "face.obj")
    assert not (tmp_path / "face.glb").exists()


def test_joy_fap_on_the_avatar_raises_and_widens_the_lip_corners(astronaut):
    _, _, target = astronaut
    table = fap_table()
    stream = read_fap(shared("xface", "Faps", "joy.fap"))
    animation = animate_faps(stream, target)
    for corner, side in (("8.3", "l"), ("8.4", "r")):
        raised = stream.values[:, table.number(f"raise_{side}_cornerlip_o") - 1] > 50
        widened = stream.values[:, table.number(f"stretch_{side}_cornerlip_o") - 1] > 50
        d = animation.positions[:, target.points[corner]] - target.mesh.vertices[target.points[corner]]
        outward = 1 if side == "l" else -1
        assert raised.sum() > 10 and (d[raised, 1] > 0.02).all()
        assert widened.sum() > 10 and (outward * d[widened, 0] > 0.02).all()
