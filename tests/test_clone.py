"""The speaker clone's appearance (issue 18): camera, blending weights, colour model, textures,
rendering, and the jobs' refusals (faceanim.speaker.camera, appearance, colour, texturing, clone;
faceanim.speakerclone)."""

import numpy as np
import pytest
from conftest import shared

from faceanim.capture.metric import canonical_face
from faceanim.cli import main
from faceanim.errors import FileFormatError, InputError
from faceanim.landmarks import landmark_names
from faceanim.motion import Motion
from faceanim.mpeg4 import Fapu
from faceanim.speaker import build_model, mobile_names, read_speaker, write_speaker
from faceanim.speaker.appearance import (
    blend_weights,
    has_appearance,
    influence_of,
    lip_indices,
    posture_points,
    read_appearance,
    write_appearance,
)
from faceanim.speaker.camera import (
    fit_camera,
    fit_video_camera,
    fit_video_camera_runs,
    from_rigid,
    moved,
    project,
    read_camera,
    register_rigid,
    rigid_of_pose,
    to_rigid,
    write_camera,
)
from faceanim.speaker.colour import ColourModel, lip_and_skin
from faceanim.speaker.texturing import (
    MAX_STATIC,
    MAX_TRIANGLES,
    appearance_from_runs,
    build_appearance,
    lip_mask_uv,
    synthesis_triangles,
    texel_map,
)
from faceanim.speakerclone import read_motion_csv, read_parameters_csv, write_motion_csv

FAPU = Fapu(irisd0=1.0, es0=6.4, ens0=4.4, mns0=2.0, mw0=5.2)
# A camera in the tracker's convention: normalised screen coordinates, u right, v down, w the depth.
CAMERA = np.array([[1.6, 0.0, 0.5, 0.0], [0.0, -1.6, 0.5, 0.0], [0.0, 0.0, 1.0, 0.0]])
# The head turned to face the camera (half a turn about y), 40 cm in front of it.
FACING = to_rigid(np.diag([-1.0, 1.0, -1.0]), [0.0, 0.0, 40.0])


def synthetic_model(seed=0, frames=60):
    """A speaker model of MediaPipe's canonical face (cm) whose mobile points move by a known linear
    model of 6 parameters; the model, its frames' head-frame points (T, 468, 3) and parameters."""
    rng = np.random.default_rng(seed)
    neutral = canonical_face().vertices
    names = landmark_names(len(neutral))
    stand_in = Motion(names, neutral, np.zeros((1, len(names), 3)), np.eye(4)[None], 25.0, FAPU)
    index = stand_in.index(mobile_names(stand_in))
    vectors = rng.normal(scale=0.05, size=(6, len(index), 3))
    vectors[0, :, 1] -= 0.2  # the first opens the jaw
    parameters = rng.normal(size=(frames, 6))
    parameters[:, 0] = np.abs(parameters[:, 0])
    d = np.zeros((frames, len(names), 3))
    d[:, index] = np.einsum("tk,kpc->tpc", parameters, vectors)
    motion = Motion(names, neutral, d, np.tile(np.eye(4), (frames, 1, 1)), 25.0, FAPU)
    model = build_model(motion)
    return model, neutral + d


def scene(width=320, height=320):
    """A smooth colour image with a red patch where the synthetic head's mouth projects."""
    y, x = np.mgrid[0:height, 0:width] / max(width, height)
    image = np.stack([150 + 40 * np.sin(6 * x), 130 + 40 * np.cos(5 * y), 110 + 30 * np.sin(4 * (x + y))], axis=-1)
    mouth = project(CAMERA, moved(canonical_face().vertices[[13, 14]], FACING)).mean(axis=0) * [width, height]
    lips = np.exp(-(((x * max(width, height) - mouth[0]) / 30) ** 2 + ((y * max(width, height) - mouth[1]) / 12) ** 2))
    image += lips[..., None] * np.array([60.0, -70.0, -50.0])
    return np.clip(image, 0, 255).astype(np.uint8)


@pytest.fixture(scope="module")
def clone():
    """A synthetic model, its points per frame, a still scene as every frame, and the appearance made from
    them with the head facing the camera (rigid motion FACING, camera CAMERA)."""
    model, points = synthetic_model()
    T, width, height = len(points), 320, 320
    pose = np.tile(np.eye(4), (T, 1, 1))
    R, t = from_rigid(FACING)
    pose[:, :3, :3], pose[:, :3, 3] = R, t
    landmarks = project(CAMERA, moved(points, np.tile(FACING, (T, 1))))
    image = scene(width, height)
    appearance, fit = build_appearance(model, names=landmark_names(468), points=points, landmarks=landmarks,
                                       pose=pose, valid=np.ones(T, bool), width=width, height=height,
                                       read_frames=lambda idx: [image for _ in idx])
    return model, appearance, fit, image


# ---- the camera


def test_the_camera_fit_recovers_a_known_camera_exactly():
    rng = np.random.default_rng(1)
    K = np.array([[1.3, 0.01, 0.48], [0.0, -1.25, 0.52], [0.0, 0.0, 1.0]])
    R, _ = from_rigid(np.r_[rng.normal(scale=0.2, size=3), 0, 0, 0])
    P = K @ np.c_[R, [0.5, -1.0, 2.0]]
    X = rng.normal(scale=5.0, size=(200, 3)) + [0, 0, 50]
    fitted = fit_camera(X, project(P, X))
    truth = P / np.linalg.norm(P)
    assert np.allclose(fitted, truth, atol=1e-9)
    assert np.abs(project(fitted, X) - project(P, X)).max() < 1e-10
    with pytest.raises(ValueError, match="at least 6 points"):
        fit_camera(X[:5], project(P, X[:5]))
    flat = X.copy()
    flat[:, 2] = 50.0
    with pytest.raises(ValueError, match="plane or a line"):
        fit_camera(flat, project(P, flat), refine=False)


def test_the_video_camera_and_rigid_motion_are_recovered_from_a_synthetic_capture():
    rng = np.random.default_rng(2)
    points = np.tile(canonical_face().vertices, (8, 1, 1))
    rigid = np.tile(FACING, (8, 1)) + np.c_[rng.normal(scale=0.1, size=(8, 3)), rng.normal(size=(8, 3))]
    R, t = from_rigid(rigid)
    pose = np.tile(np.eye(4), (8, 1, 1))
    pose[:, :3, :3], pose[:, :3, 3] = 1.02 * R, 1.02 * t  # a scaled pose: the same image
    landmarks = project(CAMERA, moved(points, rigid))
    fit = fit_video_camera(points, landmarks, pose, np.ones(8, bool), 640, 480)
    assert np.allclose(fit.camera, CAMERA / np.linalg.norm(CAMERA), atol=1e-8)
    for got in (fit.rigid, rigid_of_pose(pose)):  # rotation vectors near a half turn may wrap: compare matrices
        assert np.allclose(from_rigid(got)[0], R, atol=1e-9) and np.allclose(from_rigid(got)[1], t, atol=1e-9)
    assert fit.median_px < 1e-6 and fit.worst_point_px < 1e-6


def test_the_head_is_registered_on_the_landmarks_through_the_camera():
    """A capture's pose a few degrees and millimetres off: register_rigid finds the motion that puts the
    points on their landmarks, and the camera fit with ``register`` reports it and no error."""
    rng = np.random.default_rng(4)
    T = 5
    points = np.tile(canonical_face().vertices, (T, 1, 1))
    truth = np.tile(FACING, (T, 1)) + np.c_[rng.normal(scale=0.05, size=(T, 3)), rng.normal(size=(T, 3))]
    landmarks = project(CAMERA, moved(points, truth))
    off = truth + np.c_[rng.normal(scale=0.05, size=(T, 3)), rng.normal(scale=0.3, size=(T, 3))]
    found = register_rigid(CAMERA, points, landmarks, off)
    for got, want in zip(found, truth, strict=True):
        assert np.allclose(from_rigid(got)[0], from_rigid(want)[0], atol=1e-8)
        assert np.allclose(from_rigid(got)[1], from_rigid(want)[1], atol=1e-6)
    pose = np.tile(np.eye(4), (T, 1, 1))
    pose[:, :3, :3], pose[:, :3, 3] = from_rigid(off)
    plain = fit_video_camera(points, landmarks, pose, np.ones(T, bool), 640, 480)
    fit = fit_video_camera_runs(_in_runs(points, landmarks, 2), pose, np.ones(T, bool), 640, 480,
                                register=np.arange(468))
    assert plain.median_px > 1.0 and fit.median_px < plain.median_px / 4, (plain.median_px, fit.median_px)
    nan = np.full((1, 6), np.nan)
    assert np.isnan(register_rigid(CAMERA, points[:1], landmarks[:1], nan)).all()  # no start: left as it was


def _in_runs(points, landmarks, size):
    """``runs()`` of :func:`appearance_from_runs`: the arrays cut into runs of ``size`` frames."""
    return lambda: ((start, points[start:start + size], landmarks[start:start + size])
                    for start in range(0, len(points), size))


def test_the_camera_fit_over_runs_of_frames_equals_the_held_one():
    rng = np.random.default_rng(3)
    T = 11
    points = np.tile(canonical_face().vertices, (T, 1, 1)) + rng.normal(scale=0.02, size=(T, 468, 3))
    rigid = np.tile(FACING, (T, 1)) + np.c_[rng.normal(scale=0.1, size=(T, 3)), rng.normal(size=(T, 3))]
    R, t = from_rigid(rigid)
    pose = np.tile(np.eye(4), (T, 1, 1))
    pose[:, :3, :3], pose[:, :3, 3] = R, t
    landmarks = project(CAMERA, moved(points, rigid)) + rng.normal(scale=1e-3, size=(T, 468, 2))
    valid = np.ones(T, bool)
    valid[4] = False
    points[4] = np.nan
    points[7, :30] = np.nan  # some points of a frame missing: the even spread counts finite pairs only
    for frames, max_points in ((None, 20000), (np.arange(1, 10), 700)):  # every pair; every 5th or so
        held = fit_video_camera(points, landmarks, pose, valid, 640, 480, frames=frames, max_points=max_points)
        streamed = fit_video_camera_runs(_in_runs(points, landmarks, 3), pose, valid, 640, 480, frames=frames,
                                         max_points=max_points)
        assert np.allclose(streamed.camera, held.camera, rtol=0, atol=1e-12)
        assert np.array_equal(streamed.rigid, held.rigid, equal_nan=True)
        for name in ("median_px", "worst_frame_px", "worst_point_px"):
            assert abs(getattr(streamed, name) - getattr(held, name)) < 1e-9


def test_the_appearance_from_runs_of_frames_equals_the_held_one(clone):
    model, appearance, fit, image = clone
    _, points = synthetic_model()
    T = len(points)
    pose = np.tile(np.eye(4), (T, 1, 1))
    pose[:, :3, :3], pose[:, :3, 3] = from_rigid(FACING)
    landmarks = project(CAMERA, moved(points, np.tile(FACING, (T, 1))))
    streamed, streamed_fit = appearance_from_runs(
        model, names=landmark_names(468), runs=_in_runs(points, landmarks, 7), pose=pose, valid=np.ones(T, bool),
        width=320, height=320, read_frames=lambda idx: [image for _ in idx])
    assert np.array_equal(streamed.key_frames, appearance.key_frames)
    assert np.abs(streamed.textures.astype(int) - appearance.textures.astype(int)).max() <= 1  # rounding
    assert np.allclose(streamed.lip_textures, appearance.lip_textures, atol=1e-3)
    assert np.allclose(streamed.camera, fit.camera, atol=1e-12)
    assert np.allclose(streamed.key_parameters, appearance.key_parameters, atol=1e-9)
    assert np.allclose(streamed_fit.rigid, fit.rigid, atol=1e-12)


def test_camera_files_round_trip_and_refuse_what_is_not_3x4(tmp_path):
    write_camera(tmp_path / "cam.txt", CAMERA)
    assert np.allclose(read_camera(tmp_path / "cam.txt"), CAMERA)
    (tmp_path / "bad.txt").write_text("1 0 0\n0 1 0\n0 0 1\n")
    with pytest.raises(FileFormatError, match="3 lines of 4 numbers"):
        read_camera(tmp_path / "bad.txt")
    (tmp_path / "word.txt").write_text("1 0 0 x\n")
    with pytest.raises(FileFormatError, match="3 lines of 4 numbers"):
        read_camera(tmp_path / "word.txt")
    with pytest.raises(InputError, match="no such file"):
        read_camera(tmp_path / "none.txt")


# ---- the blending weights


def test_blending_weights_sum_to_one_are_one_hot_at_a_key_and_continuous(clone):
    model, appearance, _, _ = clone
    keys = appearance.key_points
    assert np.allclose(appearance.weights(keys), np.eye(len(keys)))
    path = np.linspace(-0.5, 1.5, 2001)
    a = appearance.key_parameters
    postures = posture_points(model, a[0] + path[:, None] * (a[1] - a[0]) + 0.3 * np.sin(3 * path)[:, None] * (
        a[2] - a[0]))
    w = appearance.weights(postures)
    assert w.shape == (len(path), len(keys))
    assert np.allclose(w.sum(axis=1), 1.0) and (w >= 0).all()
    assert np.abs(np.diff(w, axis=0)).max() < 0.02  # no jumps along a fine path
    near = keys[1] + 1e-7
    assert np.allclose(appearance.weights(near), [0, 1, 0], atol=1e-6)  # continuous at the key itself


def test_blend_weights_handle_coincident_keys_and_influence():
    assert np.allclose(blend_weights([0.0, 0.0, 1.0], [1.0, 1.0, 1.0]), [0.5, 0.5, 0.0])
    wide = blend_weights([1.0, 1.0], [2.0, 1.0])
    assert np.allclose(wide, [2 / 3, 1 / 3])
    keys = np.zeros((3, 4, 3))
    keys[1] += 1.0
    keys[2] += 3.0
    c = influence_of(keys)
    assert np.isclose(c.mean(), 1.0) and c[2] > c[0]  # the far key reaches further


# ---- the colour model


def _lip_and_skin_image(rng, size=64):
    image = np.empty((size, size, 3))
    image[:] = [205, 150, 125]
    lips = np.zeros((size, size), bool)
    lips[26:38, 16:48] = True
    lips[30:34, 22:42] = False  # the mouth's opening
    image[lips] = [175, 70, 80]
    image[30:34, 22:42] = [40, 20, 25]
    image += rng.normal(scale=6.0, size=image.shape)
    return np.clip(image, 0, 255).astype(np.uint8), lips


def test_the_colour_model_separates_lip_and_skin_and_follows_a_lighting_change():
    rng = np.random.default_rng(3)
    image, lips = _lip_and_skin_image(rng)
    inner, skin = lip_and_skin(lips)
    assert not (skin & lips).any() and not skin[30:34, 22:42].any()  # the ring leaves the mouth's opening out
    model = ColourModel.fit(image[inner], image[skin])
    p = model.probability(image)
    assert p.dtype == np.float32 and p.shape == lips.shape
    assert np.median(p[inner]) > 0.99 and np.median(p[skin]) < 0.01
    assert ((p[inner] > 0.5).mean() > 0.97) and ((p[skin] < 0.5).mean() > 0.97)
    darker = np.clip(0.55 * image.astype(float) * [1.0, 0.9, 1.1] + 12, 0, 255).astype(np.uint8)
    stale = model.probability(darker)
    assert (stale[skin] > 0.5).mean() > 0.5  # the learnt model calls the darker skin lip
    adapted = model.adapted(darker, lips)
    q = adapted.probability(darker)
    assert ((q[inner] > 0.5).mean() > 0.97) and ((q[skin] < 0.5).mean() > 0.97)
    with pytest.raises(ValueError, match="lip_mask must have shape"):
        model.adapted(darker, lips[:10])
    with pytest.raises(ValueError, match="at least 10"):
        ColourModel.fit(image[inner][:3], image[skin])


# ---- textures and rendering


def test_the_synthesis_mesh_keeps_within_the_originals_bounds(clone):
    model, appearance, _, _ = clone
    used = np.unique(appearance.triangles)
    P = len(model.names)
    assert len(appearance.triangles) <= MAX_TRIANGLES and (used >= P).sum() <= MAX_STATIC
    assert (used < P).sum() == P  # every mobile point is drawn
    assert np.array_equal(appearance.triangles, synthesis_triangles(model))
    assert set(map(tuple, appearance.triangles)) <= set(map(tuple, model.triangles))
    assert appearance.textures.shape == (3, 512, 512, 3)


def test_texel_map_covers_a_triangle_with_its_area():
    uv = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    face, bary = texel_map(uv, np.array([[0, 1, 2]]), 64)
    assert abs((face == 0).mean() - 0.5) < 0.02
    assert np.allclose(bary[face == 0].sum(axis=1), 1.0)


def test_the_appearance_round_trips_through_the_speaker_file(clone, tmp_path):
    model, appearance, _, _ = clone
    write_speaker(tmp_path / "m.npz", model)
    assert read_appearance(tmp_path / "m.npz") is None and not has_appearance(tmp_path / "m.npz")
    write_appearance(tmp_path / "m.npz", appearance, tmp_path / "m.npz")
    assert has_appearance(tmp_path / "m.npz")
    back = read_appearance(tmp_path / "m.npz")
    for name in ("uv", "key_parameters", "key_points", "textures", "lip_textures", "influence", "camera", "triangles",
                 "key_frames", "key_rigid", "lip_outer", "lip_inner"):
        assert np.array_equal(getattr(back, name), getattr(appearance, name)), name
    assert back.key_names == ("rest", "open", "rounded") and back.frame_size == appearance.frame_size
    assert np.allclose(back.colour.direction, appearance.colour.direction)
    assert read_speaker(tmp_path / "m.npz").names == model.names  # still a model


def test_lip_textures_are_the_colour_models_probability_of_the_textures(clone):
    _, appearance, _, _ = clone
    for texture, lips in zip(appearance.textures, appearance.lip_textures, strict=True):
        assert np.allclose(appearance.colour.probability(texture), lips)
    mask = lip_mask_uv(appearance.uv, appearance.lip_outer, appearance.lip_inner, appearance.size)
    assert lips[mask].mean() > lips[~mask].mean() + 0.3


@pytest.mark.parametrize("blend", ["shader", "cpu"])
def test_a_clone_rendered_at_a_key_posture_reproduces_its_key_frame(clone, blend):
    pytest.importorskip("moderngl")
    from faceanim.speaker.clone import CloneRenderer

    model, appearance, fit, image = clone
    assert np.allclose(fit.camera, CAMERA / np.linalg.norm(CAMERA), atol=1e-7)
    outer, _ = lip_indices(model.names + model.static_names, landmark_names(468))
    with CloneRenderer(model, appearance, blend=blend) as renderer:
        for q in range(3):
            points = posture_points(model, appearance.key_parameters[q:q + 1])[0]
            made, covered = renderer.render(appearance.key_parameters[q], appearance.key_rigid[q], mask=True)
            lips = project(CAMERA, moved(points[outer], appearance.key_rigid[q])) * 320
            (x0, y0), (x1, y1) = lips.min(axis=0).astype(int) - 6, lips.max(axis=0).astype(int) + 6
            box = (slice(y0, y1), slice(x0, x1))
            assert covered[box].all()
            error = np.abs(made[box].astype(float) - image[box]).mean()
            assert error < 2.0, (q, error)
        over = renderer.render(appearance.key_parameters[0], background=image, wireframe=True)
        assert over.shape == image.shape and not np.array_equal(over, image)


# ---- the jobs' files and refusals


def test_parameter_and_motion_csvs_read_back_and_refuse_wrong_columns(tmp_path):
    rigid = np.tile(FACING, (3, 1))
    write_motion_csv(tmp_path / "m.csv", rigid)
    assert np.allclose(read_motion_csv(tmp_path / "m.csv"), rigid)
    (tmp_path / "p.csv").write_text("frame,timestamp,a,b\n0,0,1.5,\n1,0.04,2,3\n")
    got = read_parameters_csv(tmp_path / "p.csv", 2)
    assert got[0, 0] == 1.5 and np.isnan(got[0, 1]) and got[1].tolist() == [2.0, 3.0]
    with pytest.raises(FileFormatError, match=r"p.csv:1: has 4 columns; .* need 8"):
        read_parameters_csv(tmp_path / "p.csv", 6)
    (tmp_path / "q.csv").write_text("frame,timestamp,a,b\n0,0,1\n")
    with pytest.raises(FileFormatError, match=r"q.csv:2: has 3 columns"):
        read_parameters_csv(tmp_path / "q.csv", 2)


@pytest.fixture(scope="module")
def files(clone, tmp_path_factory):
    model, appearance, _, image = clone
    folder = tmp_path_factory.mktemp("clone")
    write_speaker(folder / "bare.npz", model)
    write_appearance(folder / "bare.npz", appearance, folder / "textured.npz")
    rows = ["frame,timestamp," + ",".join(model.parameter_names)]
    rows += [f"{t},{t / 25},{','.join(str(v) for v in appearance.key_parameters[t % 3])}" for t in range(6)]
    (folder / "p.csv").write_text("\n".join(rows) + "\n")
    from PIL import Image

    Image.fromarray(image).save(folder / "back.png")
    return folder


def test_speaker_render_writes_a_video(files, capsys):
    pytest.importorskip("moderngl")
    av = pytest.importorskip("av")
    out = files / "out.mp4"
    assert main(["speaker", "render", "--model", str(files / "textured.npz"), "--params", str(files / "p.csv"),
                 "--background", str(files / "back.png"), "--wireframe", "-o", str(out)]) == 0
    assert "6 frames" in capsys.readouterr().out
    with av.open(str(out)) as container:
        assert sum(1 for _ in container.decode(video=0)) == 6


@pytest.mark.parametrize("case, match", [
    ("bare", "has no textures"),
    ("camera", "3 lines of 4 numbers"),
    ("columns", "has 4 columns; the speaker model's parameters need 8"),
])
def test_speaker_render_refuses_bad_input_in_one_line_and_writes_nothing(files, capsys, tmp_path, case, match):
    model, params = files / "textured.npz", files / "p.csv"
    extra = []
    if case == "bare":
        model = files / "bare.npz"
    elif case == "camera":
        (tmp_path / "cam.txt").write_text("1 0 0\n0 1 0\n0 0 1\n")
        extra = ["--camera", str(tmp_path / "cam.txt")]
    else:
        params = tmp_path / "p.csv"
        params.write_text("frame,timestamp,a,b\n0,0,1,2\n")
    out = tmp_path / "out.mp4"
    assert main(["speaker", "render", "--model", str(model), "--params", str(params), *extra, "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert match in err and len(err.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == ([tmp_path / "cam.txt"] if case == "camera" else
                                        [params] if case == "columns" else [])


def test_speaker_textures_and_render_on_a_real_clip(tmp_path, capsys):
    pytest.importorskip("moderngl")
    video = shared("videos", "speech_man.mp4")
    model = tmp_path / "man.npz"
    assert main(["speaker", "build", str(video), "-o", str(model), "--frames", "0:87"]) == 0
    assert main(["speaker", "textures", str(video), "--model", str(model), "-o", str(model), "--frames", "0:87",
                 "--camera-out", str(tmp_path / "cam.txt"), "--motion-out", str(tmp_path / "m.csv")]) == 0
    out = capsys.readouterr().out
    assert "3 textures of 512x512" in out
    appearance = read_appearance(model)
    assert appearance.key_frames.max() < 87 and len(set(appearance.key_frames.tolist())) == 3
    assert np.allclose(read_camera(tmp_path / "cam.txt"), appearance.camera)
    # the job streams its capture; the same capture held whole in memory gives the same textures
    from faceanim.inputs import captured_source
    from faceanim.speakerclone import _frames_of

    capture = captured_source(video, folder=tmp_path, floor=False)  # as the job captures
    motion = capture.motion
    held, _ = build_appearance(read_speaker(model), names=motion.names, points=motion.neutral + motion.displacements,
                               landmarks=capture.landmarks[:][..., :2], pose=motion.pose, valid=motion.valid,
                               width=capture.width, height=capture.height,
                               read_frames=lambda idx: _frames_of(video, idx), frames=np.arange(87))
    assert np.array_equal(held.key_frames, appearance.key_frames)
    assert np.abs(held.textures.astype(int) - appearance.textures.astype(int)).max() <= 1
    assert np.allclose(held.camera, appearance.camera, atol=1e-9)
    assert main(["speaker", "analyse", str(video), "--model", str(model), "-o", str(tmp_path / "a.fap"),
                 "--params-csv", str(tmp_path / "p.csv")]) == 0
    assert main(["speaker", "render", "--model", str(model), "--params", str(tmp_path / "p.csv"), "--motion",
                 str(tmp_path / "m.csv"), "--background", str(video), "-o", str(tmp_path / "r.mp4")]) == 0
    assert (tmp_path / "r.mp4").stat().st_size > 0


def test_the_lips_of_a_frame_adapt_the_colour_model(clone):
    from faceanim.speaker.texturing import lip_mask_frame

    model, appearance, _, image = clone
    points = posture_points(model, appearance.key_parameters[:1])[0]
    lips = lip_mask_frame(appearance, points, appearance.key_rigid[0], 320, 320)
    assert lips.sum() > 50
    outer = np.zeros_like(lips)
    from skimage.draw import polygon2mask

    at = project(CAMERA, moved(points[appearance.lip_outer], appearance.key_rigid[0])) * 320 - 0.5
    outer = polygon2mask(lips.shape, at[:, ::-1])
    assert (lips <= outer).all()  # inside the outer contour, the opening left out
    adapted = appearance.colour.adapted(image, lips)
    p = adapted.probability(image)
    inner, skin = lip_and_skin(lips)
    assert p[inner].mean() > p[skin].mean() + 0.3
