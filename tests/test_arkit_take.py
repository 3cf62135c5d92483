"""ARKit-52 takes: the Face Landmarker shipped in the package, the Live Link Face CSV (columns, round
trip, bad files refused by line) and ``faceanim blendshapes`` on real videos (skipped without shared data)."""

import importlib.resources
import zipfile

import numpy as np
import pytest
from conftest import shared

from faceanim.cli import main
from faceanim.errors import FileFormatError
from faceanim.rig.arkit import ARKIT_NAMES
from faceanim.rig.livelink import (
    COLUMNS,
    Take,
    arkit_weights,
    read_livelink_csv,
    seconds_of,
    timecode,
    write_livelink_csv,
)

# Live Link Face's header, as the app writes it (and as the importers for Blender, Maya and Unreal read it).
LIVE_LINK_HEADER = (
    "Timecode,BlendShapeCount,EyeBlinkLeft,EyeLookDownLeft,EyeLookInLeft,EyeLookOutLeft,EyeLookUpLeft,"
    "EyeSquintLeft,EyeWideLeft,EyeBlinkRight,EyeLookDownRight,EyeLookInRight,EyeLookOutRight,EyeLookUpRight,"
    "EyeSquintRight,EyeWideRight,JawForward,JawRight,JawLeft,JawOpen,MouthClose,MouthFunnel,MouthPucker,"
    "MouthRight,MouthLeft,MouthSmileLeft,MouthSmileRight,MouthFrownLeft,MouthFrownRight,MouthDimpleLeft,"
    "MouthDimpleRight,MouthStretchLeft,MouthStretchRight,MouthRollLower,MouthRollUpper,MouthShrugLower,"
    "MouthShrugUpper,MouthPressLeft,MouthPressRight,MouthLowerDownLeft,MouthLowerDownRight,MouthUpperUpLeft,"
    "MouthUpperUpRight,BrowDownLeft,BrowDownRight,BrowInnerUp,BrowOuterUpLeft,BrowOuterUpRight,CheekPuff,"
    "CheekSquintLeft,CheekSquintRight,NoseSneerLeft,NoseSneerRight,TongueOut,HeadYaw,HeadPitch,HeadRoll,"
    "LeftEyeYaw,LeftEyePitch,LeftEyeRoll,RightEyeYaw,RightEyePitch,RightEyeRoll")


def random_take(T=90, fps=30.0, start=0.0, seed=0):
    rng = np.random.default_rng(seed)
    weights = rng.random((T, 52))
    weights[:, 5] = 0.0
    weights[:, 6] = 1.0
    return Take(start + np.arange(T) / fps, weights, rng.uniform(-0.6, 0.6, (T, 9)), fps)


# ---- the model inside the package


def test_the_face_landmarker_ships_inside_the_package():
    from faceanim.capture.tracker import DEFAULT_MODEL

    packaged = importlib.resources.files("faceanim.capture").joinpath("models", "face_landmarker.task")
    assert packaged.is_file() and DEFAULT_MODEL.is_file()
    assert DEFAULT_MODEL.resolve() == packaged.resolve()
    with zipfile.ZipFile(DEFAULT_MODEL) as bundle:  # detector, landmarks, blendshapes, geometry
        assert {"face_detector.tflite", "face_landmarks_detector.tflite", "face_blendshapes.tflite"} <= set(
            bundle.namelist())
    for side in ("LICENSE", "SOURCE"):
        assert importlib.resources.files("faceanim.capture").joinpath("models", side).is_file()
    assert "Apache License" in DEFAULT_MODEL.with_name("LICENSE").read_text()


def test_the_default_track_has_52_blendshapes_without_a_model_given():
    pytest.importorskip("mediapipe", reason="capture needs faceanim[capture]")
    from faceanim.capture.track import track_video

    photo = shared("mediapipe", "testdata", "sergey.png")  # a smiling portrait
    track = track_video(photo, progress=False)
    assert track.blendshapes.shape == (1, 52) and track.blendshape_names[0] == "_neutral"
    weights = dict(zip(ARKIT_NAMES, arkit_weights(track.blendshapes, track.blendshape_names)[0], strict=True))
    assert weights["mouthSmileLeft"] > 0.5 and weights["mouthSmileRight"] > 0.5 and weights["jawOpen"] < 0.3
    assert weights["tongueOut"] == 0.0  # MediaPipe does not score it


def test_the_tracker_hands_out_mediapipes_head_matrix_and_refuses_a_bad_bundle(tmp_path):
    pytest.importorskip("mediapipe", reason="capture needs faceanim[capture]")
    from PIL import Image

    from faceanim.capture.tracker import FaceTracker, TrackerOptions
    from faceanim.errors import InputError

    rgb = np.asarray(Image.open(shared("mediapipe", "testdata", "sergey.png")).convert("RGB"))
    with FaceTracker(TrackerOptions(static=True)) as tracker:
        assert tracker(rgb).shape == (478, 3) and tracker.blendshapes.shape == (52,)
        turn = tracker.matrix[:3, :3] / np.cbrt(np.linalg.det(tracker.matrix[:3, :3]))
        np.testing.assert_allclose(turn @ turn.T, np.eye(3), atol=1e-4)  # a rotation (canonical face -> camera)
        assert turn[2, 2] > 0.9  # a frontal portrait: the face looks at the camera
    (tmp_path / "fake.task").write_bytes(b"PK not a bundle")
    with pytest.raises(InputError, match="fake.task: not a MediaPipe face landmarker model"):
        FaceTracker(model=tmp_path / "fake.task")
    with pytest.raises(InputError, match="nothing.task: no such model file"):
        FaceTracker(model=tmp_path / "nothing.task")


# ---- the CSV's columns and timecodes


def test_the_header_is_live_links_in_its_order():
    assert ",".join(COLUMNS) == LIVE_LINK_HEADER
    assert [c[0].lower() + c[1:] for c in COLUMNS[2:54]] == list(ARKIT_NAMES)


@pytest.mark.parametrize("seconds, rate, text", [
    (0.0, 30, "00:00:00:00.000"), (0.04, 25, "00:00:00:01.000"), (1.02, 25, "00:00:01:00.500"),
    (3661.5, 60, "01:01:01:30.000"), (10 / 23.976, 24, "00:00:00:10.010"), (59.9999999, 30, "00:01:00:00.000"),
])
def test_timecodes_are_hours_minutes_seconds_frames_and_thousandths(seconds, rate, text):
    assert timecode(seconds, rate) == text
    assert abs(seconds_of(text, rate) - seconds) < 0.5e-3 / rate


def test_mediapipe_scores_map_onto_arkit_names():
    names = ("_neutral", "jawOpen", "eyeBlinkLeft", "mouthSmileRight")
    scores = np.array([[0.9, 0.5, 1.2, -0.1], [np.nan] * 4])
    weights = arkit_weights(scores, names)
    assert weights.shape == (2, 52) and np.isnan(weights[1]).all()
    at = {n: i for i, n in enumerate(ARKIT_NAMES)}
    assert weights[0, at["jawOpen"]] == 0.5 and weights[0, at["eyeBlinkLeft"]] == 1.0  # clipped to [0, 1]
    assert weights[0, at["mouthSmileRight"]] == 0.0 and weights[0].sum() == 1.5
    with pytest.raises(ValueError, match="'mouthSmile_L' is not one of ARKit's 52"):
        arkit_weights(scores, ("_neutral", "jawOpen", "mouthSmile_L", "x"))


# ---- round trip


@pytest.mark.parametrize("fps, start", [(30.0, 0.0), (25.0, 12.3), (29.97, 0.0), (60.0, 3599.5)])
def test_a_take_reads_back_as_it_was_written(tmp_path, fps, start):
    take = random_take(fps=fps, start=start)
    write_livelink_csv(tmp_path / "take.csv", take)
    back = read_livelink_csv(tmp_path / "take.csv")
    assert len(back) == len(take)
    np.testing.assert_allclose(back.weights, take.weights, atol=0.5e-6)
    np.testing.assert_allclose(back.pose, take.pose, atol=0.5e-6)
    np.testing.assert_allclose(back.times, take.times, atol=0.5e-3 / round(fps))
    assert abs(back.fps - fps) < 1e-3 * fps
    lines = (tmp_path / "take.csv").read_text().splitlines()
    assert lines[0] == LIVE_LINK_HEADER and all(line.split(",")[1] == "61" for line in lines[1:])


def test_a_take_from_another_tool_is_read_by_column_name(tmp_path):
    """camelCase names, columns in another order, no BlendShapeCount, missing shapes: read by name, 0 where absent."""
    (tmp_path / "other.csv").write_text("jawOpen,Timecode,HeadYaw\n0.25,00:00:01:00.000,0.1\n"
                                        "0.5,00:00:01:01.000,-0.1\n")
    take = read_livelink_csv(tmp_path / "other.csv", rate=60)
    np.testing.assert_allclose(take.weight("JawOpen"), [0.25, 0.5])
    np.testing.assert_allclose(take.times, [1.0, 1 + 1 / 60])
    assert take.fps == pytest.approx(60) and take.pose[:, 0].tolist() == [0.1, -0.1] and take.weights.sum() == 0.75


# ---- bad files


def good_lines():
    take = random_take(T=3)
    return [LIVE_LINK_HEADER] + [",".join([timecode(t, 30), "61", *(f"{v:.6f}" for v in row)])
                                 for t, row in zip(take.times, np.hstack([take.weights, take.pose]), strict=True)]


def replace_cell(lines, line, column, value):
    lines = list(lines)
    cells = lines[line - 1].split(",")
    cells[column] = value
    lines[line - 1] = ",".join(cells)
    return lines


@pytest.mark.parametrize("edit, match", [
    (lambda x: replace_cell(x, 1, 5, "EyeBlinkMiddle"), r"take\.csv:1: unknown column 'EyeBlinkMiddle' \(column 6\)"),
    (lambda x: replace_cell(x, 1, 5, "JawOpen"), r"take\.csv:1: column 'JawOpen' appears twice"),
    (lambda x: replace_cell(x, 3, 19, "1.5"), r"take\.csv:3: JawOpen 1\.5 is outside \[0, 1\]"),
    (lambda x: replace_cell(x, 2, 2, "-0.2"), r"take\.csv:2: EyeBlinkLeft -0\.2 is outside \[0, 1\]"),
    (lambda x: replace_cell(x, 4, 19, "wide"), r"take\.csv:4: JawOpen 'wide' is not a number"),
    (lambda x: replace_cell(x, 2, 19, "nan"), r"take\.csv:2: JawOpen nan is outside \[0, 1\]"),
    (lambda x: replace_cell(x, 3, 54, "inf"), r"take\.csv:3: HeadYaw inf is not a finite angle"),
    (lambda x: replace_cell(x, 2, 0, "12:00"), r"take\.csv:2: Timecode '12:00' is not HH:MM:SS:FF\.mmm"),
    (lambda x: replace_cell(x, 4, 0, "00:00:00:00.000"), r"take\.csv:4: Timecode .* is earlier than the row"),
    (lambda x: replace_cell(x, 2, 1, "61.5"), r"take\.csv:2: BlendShapeCount '61\.5' is not a count"),
    (lambda x: x[:2] + [x[2] + ",0.1"] + x[3:], r"take\.csv:3: has 64 values but the header names 63 columns"),
    (lambda x: x[:1], r"take\.csv:1: holds no rows after its header"),
    (lambda x: [], r"take\.csv:1: is empty"),
    (lambda x: [line.split(",", 1)[1] for line in x], r"take\.csv:1: has no Timecode column"),
])
def test_a_bad_take_is_refused_in_one_line_naming_file_and_line(tmp_path, edit, match):
    path = tmp_path / "take.csv"
    path.write_text("\n".join(edit(good_lines())) + "\n")
    with pytest.raises(FileFormatError, match=match) as caught:
        read_livelink_csv(path)
    assert "\n" not in str(caught.value)


def test_a_take_that_is_not_text_is_refused(tmp_path):
    path = tmp_path / "take.csv"
    path.write_bytes(b"Timecode,JawOpen\n\xff\xfe,0.5\n")
    with pytest.raises(FileFormatError, match="take.csv: is not UTF-8 text"):
        read_livelink_csv(path)


def test_a_take_out_of_range_cannot_be_made():
    with pytest.raises(ValueError, match=r"weights must lie in \[0, 1\], got 0 to 1.5"):
        Take(np.arange(2.0), np.r_[np.zeros(52), np.full(52, 1.5)].reshape(2, 52), np.zeros((2, 9)), 30.0)


# ---- faceanim blendshapes on real videos


@pytest.fixture(scope="module")
def d18_take(tmp_path_factory):
    pytest.importorskip("mediapipe", reason="capture needs faceanim[capture]")
    video = shared("videos", "d18.mp4")
    out = tmp_path_factory.mktemp("take") / "d18.csv"
    assert main(["blendshapes", str(video), "-o", str(out), "--neutral", "0:12"]) == 0
    return out


def test_blendshapes_writes_a_take_of_the_video_with_the_neutral_removed(d18_take, capsys):
    """d18: 'mouth wide open', at rest on frames 0-12 (the neutral given): JawOpen is 0 there after the
    neutral is taken off and peaks where the FAP encoder's open_jaw does."""
    take = read_livelink_csv(d18_take)
    assert len(take) == 216 and take.fps == pytest.approx(30, abs=0.01)
    np.testing.assert_allclose(take.times, np.arange(216) / 30, atol=2e-4)
    assert take.weights.min() >= 0 and take.weights.max() <= 1 and (take.weight("tongueOut") == 0).all()
    assert np.abs(take.weights[:12]).max() < 0.2  # the neutral's own frames are near 0 after removal
    jaw = take.weight("jawOpen")
    assert jaw.max() > 0.8 and (jaw[np.r_[48:60, 102:108]] < 0.2).all()  # closed again at rest
    assert np.abs(take.pose[:, :3]).max() < np.radians(20)  # a face looking at the camera


def test_mediapipes_left_is_the_subjects_left(d18_take):
    """ARKit's Left is the subject's own: the left eye looking out (to the subject's left) goes with its
    pupil turning that way (LeftEyeYaw > 0, measured from the landmarks in the head frame)."""
    take = read_livelink_csv(d18_take)
    left_out = take.weight("eyeLookOutLeft") - take.weight("eyeLookInLeft")
    right_in = take.weight("eyeLookInRight") - take.weight("eyeLookOutRight")
    # a check of the sign (the wrong eye or the wrong way gives a negative correlation); how closely the
    # two agree moves with the head frame: 0.58 / 0.54 with a plain head fit, 0.48 / 0.67 with the robust one
    assert np.corrcoef(left_out, take.pose[:, 3])[0, 1] > 0.4
    assert np.corrcoef(right_in, take.pose[:, 6])[0, 1] > 0.4


def test_blendshapes_prints_a_summary(tmp_path, capsys):
    pytest.importorskip("mediapipe", reason="capture needs faceanim[capture]")
    video = shared("videos", "d0.mp4")
    assert main(["blendshapes", str(video), "-o", str(tmp_path / "d0.csv")]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith(f"wrote {tmp_path / 'd0.csv'}: 78 frames at 25 fps (3.12 s), 52 ARKit shapes")
    assert out[1].split() == ["shape", "mean", "min", "max"] and out[2].split()[0].startswith("MouthSmile") or \
        any(line.split()[0].startswith("MouthSmile") for line in out[2:6])
    assert out[-1].startswith("head (degrees): yaw")
    assert read_livelink_csv(tmp_path / "d0.csv").weights.shape == (78, 52)


@pytest.mark.parametrize("arguments, message", [
    (["-o", "{tmp}/take.txt"], "-o {tmp}/take.txt: this output is written as .csv"),
    (["-o", "{tmp}/take.csv", "--neutral", "{tmp}/rest.png"], "blendshapes takes the neutral as FRAME or START:END"),
    (["-o", "{tmp}/take.csv", "--neutral", "500:600"], "--neutral 500:600: frames must lie in [0, 78)"),
    (["-o", "{tmp}/missing/take.csv"], "missing"),
])
def test_blendshapes_refuses_in_one_line_and_writes_nothing(tmp_path, capsys, arguments, message):
    pytest.importorskip("mediapipe", reason="capture needs faceanim[capture]")
    video = shared("videos", "d0.mp4")
    given = [a.format(tmp=tmp_path) for a in arguments]
    assert main(["blendshapes", str(video), *given]) == 2
    err = capsys.readouterr().err
    assert message.format(tmp=tmp_path) in err and len(err.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


def test_blendshapes_of_a_faceless_image_writes_nothing(tmp_path, capsys):
    pytest.importorskip("mediapipe", reason="capture needs faceanim[capture]")
    from PIL import Image

    Image.new("RGB", (64, 64), (120, 120, 120)).save(tmp_path / "grey.png")
    assert main(["blendshapes", str(tmp_path / "grey.png"), "-o", str(tmp_path / "take.csv")]) == 2
    assert "no face was found" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["grey.png"]


def test_blendshapes_of_a_track_saved_without_scores_is_refused(tmp_path, capsys):
    """A track saved before the Face Landmarker was faceanim's tracker has no scores: one line, nothing written."""
    pytest.importorskip("mediapipe", reason="capture needs faceanim[capture]")
    from dataclasses import replace

    from faceanim.capture.track import track_video

    track = track_video(shared("videos", "d0.mp4"), progress=False)
    replace(track, blendshapes=None, blendshape_names=()).save(tmp_path / "old.npz")
    assert main(["blendshapes", str(tmp_path / "old.npz"), "-o", str(tmp_path / "take.csv")]) == 2
    assert "old.npz: holds no blendshape scores" in capsys.readouterr().err
    assert not (tmp_path / "take.csv").exists()
    track.save(tmp_path / "new.npz")  # a track with scores is a source like its video
    assert main(["blendshapes", str(tmp_path / "new.npz"), "-o", str(tmp_path / "take.csv")]) == 0
    assert read_livelink_csv(tmp_path / "take.csv").weights.shape == (78, 52)


def test_frames_filled_across_a_gap_get_weights_between_their_neighbours(tmp_path):
    """A saved track whose face was lost for three frames (landmarks filled, no scores) gives a take with
    those frames in it, their weights on the line between the frames either side, as the capture fills
    them (``capture.scores.scores_across_filled_frames``)."""
    pytest.importorskip("mediapipe", reason="capture needs faceanim[capture]")
    from dataclasses import replace

    from faceanim.capture.track import track_video

    track = track_video(shared("videos", "d0.mp4"), progress=False)
    lost = np.arange(30, 33)
    valid, filled, scores = track.valid.copy(), track.filled.copy(), np.array(track.blendshapes)
    valid[lost], filled[lost], scores[lost] = False, True, np.nan
    replace(track, valid=valid, filled=filled, blendshapes=scores).save(tmp_path / "gap.npz")
    assert main(["blendshapes", str(tmp_path / "gap.npz"), "-o", str(tmp_path / "take.csv")]) == 0
    weights = read_livelink_csv(tmp_path / "take.csv").weights
    whole = read_livelink_csv(_take_of(track, tmp_path)).weights
    assert weights.shape == whole.shape == (78, 52) and np.isfinite(weights).all()
    share = ((lost - 29) / 4.0)[:, None]
    np.testing.assert_allclose(weights[lost], (1 - share) * whole[29] + share * whole[33], atol=1e-4)
    np.testing.assert_allclose(np.delete(weights, lost, axis=0), np.delete(whole, lost, axis=0), atol=1e-6)


def _take_of(track, folder):
    track.save(folder / "whole.npz")
    assert main(["blendshapes", str(folder / "whole.npz"), "-o", str(folder / "whole.csv")]) == 0
    return folder / "whole.csv"
