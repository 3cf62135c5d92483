"""Capture end to end on real videos and photos (MediaPipe and PyAV; skipped without shared data)."""

import numpy as np
import pytest
from conftest import shared

from faceanim.cli import main
from faceanim.mpeg4 import fap_table
from faceanim.mpeg4.fapfile import read_fap

pytest.importorskip("mediapipe", reason="capture needs faceanim[capture]")
av = pytest.importorskip("av", reason="capture needs faceanim[capture]")


@pytest.fixture(scope="module")
def d18(tmp_path_factory):
    video = shared("videos", "d18.mp4")
    out = tmp_path_factory.mktemp("d18")
    assert main(["track", str(video), "-o", str(out / "t.npz"), "--overlay", str(out / "o.mp4"),
                 "--csv", str(out / "l.csv")]) == 0
    assert main(["encode", str(out / "t.npz"), "-o", str(out / "d18.fap")]) == 0
    return out


def test_d18_open_jaw_follows_the_mouth(d18):
    """d18: 'mouth wide open'. At rest (frames 0-12, 48-60, 102-108: lips closed, face relaxed, looked at)
    open_jaw is near zero; its peak falls on a frame where the lips are far apart."""
    from faceanim.capture.headframe import track_to_motion
    from faceanim.capture.track import Track

    stream = read_fap(d18 / "d18.fap")
    assert len(stream) == 216 and not stream.out_of_range().any()
    jaw = stream.values[:, fap_table().number("open_jaw") - 1]
    peak = int(jaw.argmax())
    assert jaw[peak] > 500
    rest = np.r_[0:12, 48:60, 102:108]
    assert np.abs(jaw[rest]).max() < 0.05 * jaw[peak]
    motion = track_to_motion(Track.load(d18 / "t.npz"))
    upper, lower = motion.index(["2.2", "2.3"])
    gap = (motion.neutral[upper, 1] + motion.displacements[:, upper, 1]
           - motion.neutral[lower, 1] - motion.displacements[:, lower, 1])
    assert gap[peak] > 0.6 * gap.max()


def test_track_outputs(d18):
    from faceanim.capture.track import Track

    track = Track.load(d18 / "t.npz")
    assert track.valid.all() and track.landmarks.shape == (216, 478, 3)
    with av.open(str(d18 / "o.mp4")) as container:
        assert sum(1 for _ in container.decode(video=0)) == 216
    rows = (d18 / "l.csv").read_text().splitlines()
    assert len(rows) == 217 and rows[0].startswith("frame,timestamp,success,filled,x0,y0")
    first, last = rows[1].split(","), rows[-1].split(",")
    assert first[:3] == ["1", f"{track.times[0]:.3f}", "1"] and last[:3] == ["216", f"{track.times[-1]:.3f}", "1"]


def test_fap_info_reports(d18, capsys):
    assert main(["fap-info", str(d18 / "d18.fap")]) == 0
    out = capsys.readouterr().out
    assert "216 frames at 30 fps" in out and "open_jaw" in out and "0 values out of range" in out


def test_fap_info_flags_out_of_range_values(tmp_path, capsys):
    mask = " ".join(["0", "0", "1"] + ["0"] * 65)
    (tmp_path / "a.fap").write_text(f"2.1 a 25 1\n{mask}\n0 99999\n")
    assert main(["fap-info", str(tmp_path / "a.fap")]) == 0
    assert "1 out of range" in capsys.readouterr().out


def write_video(path, frames):
    with av.open(str(path), mode="w") as container:
        stream = container.add_stream("libx264", rate=25)
        stream.width, stream.height, stream.pix_fmt = 64, 64, "yuv420p"
        for rgb in frames:
            for packet in stream.encode(av.VideoFrame.from_ndarray(rgb, format="rgb24")):
                container.mux(packet)
        for packet in stream.encode():
            container.mux(packet)


def bad_inputs(tmp_path):
    (tmp_path / "empty.mp4").write_bytes(b"")
    (tmp_path / "text.mp4").write_text("this is not a video\n")
    good = shared("videos", "d0.mp4").read_bytes()
    (tmp_path / "truncated.mp4").write_bytes(good[:3000])
    write_video(tmp_path / "noface.mp4", [np.full((64, 64, 3), 128, np.uint8)] * 10)
    return {"missing.mp4": "no such file", "empty.mp4": "the file is empty", "text.mp4": "not a video",
            "truncated.mp4": "truncated.mp4: ", "noface.mp4": "no face was found in any of its 10 frames"}


@pytest.mark.parametrize("command", ["encode", "track"])
def test_bad_videos_give_one_line_and_no_output(tmp_path, capsys, command):
    for name, message in bad_inputs(tmp_path).items():
        out = tmp_path / ("out.fap" if command == "encode" else "out.npz")
        assert main([command, str(tmp_path / name), "-o", str(out)]) == 2, name
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("faceanim: error: ") and message in err[0], (name, err)
        assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.endswith(".mp4")) == []


def test_several_faces_follow_the_chosen_one():
    """Two real faces side by side (MediaPipe's short-range detector finds only one of the five small faces
    in multi_face.jpg): the option picks which one is followed."""
    from PIL import Image

    from faceanim.capture.tracker import FaceTracker, TrackerOptions

    big = Image.open(shared("mediapipe", "testdata", "sergey.png")).convert("RGB").resize((400, 400))
    small = Image.open(shared("videos", "single_face.jpg")).convert("RGB").resize((255, 260))
    both = Image.new("RGB", (655, 400), (128, 128, 128))
    both.paste(big, (0, 0))
    both.paste(small, (400, 70))
    rgb = np.asarray(both)
    centre = {}
    for start in ("left", "right", "largest"):
        with FaceTracker(TrackerOptions(static=True, max_faces=4, start_face=start)) as tracker:
            assert len(tracker.all_faces(rgb)) == 2
            centre[start] = tracker(rgb)[:, 0].mean()
    assert centre["left"] < 0.5 < centre["right"] and centre["largest"] == centre["left"]


def test_dlib_photos_landmark_error():
    shared("dlib_faces", "training_with_face_landmarks.xml")
    import landmarks_dlib

    nme = np.array([row[3] for row in landmarks_dlib.evaluate()])
    # Measured 0.061 (issue 3 asks <= 0.06; these faces are 15-48 px between the eyes): a guard against
    # a worse mapping, not a claim that the target is met.
    assert np.isfinite(nme).all() and nme.mean() <= 0.062


def test_a_model_bundle_given_tracks_as_the_packaged_one(tmp_path):
    """sergey.png is a smiling portrait: tracked with a face_landmarker.task given by --model (the shared
    copy), the smile scores are high, its landmarks agree with the packaged model's, and the CSV carries
    the 52 scores."""
    from faceanim.capture.track import Track, track_video

    photo = shared("mediapipe", "testdata", "sergey.png")
    model = shared("mediapipe", "face_landmarker.task")
    assert main(["track", str(photo), "-o", str(tmp_path / "s.npz"), "--model", str(model),
                 "--csv", str(tmp_path / "s.csv")]) == 0
    tasks = Track.load(tmp_path / "s.npz")
    shapes = dict(zip(tasks.blendshape_names, tasks.blendshapes[0], strict=True))
    assert len(shapes) == 52 and shapes["mouthSmileLeft"] > 0.5 and shapes["mouthSmileRight"] > 0.5
    assert shapes["browInnerUp"] < 0.2 and shapes["jawOpen"] < 0.3
    mesh = track_video(photo, progress=False)
    interocular = np.linalg.norm(mesh.pixels()[0, 33] - mesh.pixels()[0, 263])
    assert np.linalg.norm(tasks.pixels()[0] - mesh.pixels()[0], axis=1).mean() < 0.05 * interocular
    assert "mouthSmileLeft" in (tmp_path / "s.csv").read_text().splitlines()[0]


def test_bad_model_file(tmp_path, capsys):
    (tmp_path / "fake.task").write_text("not a model")
    photo = shared("mediapipe", "testdata", "sergey.png")
    assert main(["track", str(photo), "-o", str(tmp_path / "s.npz"), "--model", str(tmp_path / "fake.task")]) == 2
    assert "fake.task: not a MediaPipe face landmarker model" in capsys.readouterr().err
    assert not (tmp_path / "s.npz").exists()


def test_neutral_choices(d18, tmp_path):
    """--neutral as a frame, a range and an image: the chosen rest is where FAPs are zero."""
    track = str(d18 / "t.npz")
    for spec in ("0", "48:60"):
        assert main(["encode", track, "-o", str(tmp_path / "n.fap"), "--neutral", spec, "--no-filter"]) == 0
        stream = read_fap(tmp_path / "n.fap")
        first = int(spec.split(":")[0])
        assert np.abs(stream.values[first, 2:22]).max() < 150  # jaw, lips, lids (FAPU counts) at their neutral
    photo = tmp_path / "rest.png"
    from PIL import Image

    from faceanim.capture.video import open_frames

    with open_frames(shared("videos", "d18.mp4")) as source:
        Image.fromarray(next(iter(source))[1]).save(photo)
    assert main(["encode", track, "-o", str(tmp_path / "i.fap"), "--neutral", str(photo), "--no-filter"]) == 0
    assert np.abs(read_fap(tmp_path / "i.fap").values[0, 2:19]).max() < 60  # frame 0 is that image
    assert main(["encode", track, "-o", str(tmp_path / "x.fap"), "--neutral", "500:600"]) == 2


def test_image_folder_is_a_sequence(tmp_path):
    from PIL import Image

    from faceanim.capture.track import track_video
    from faceanim.capture.video import open_frames

    with open_frames(shared("videos", "d0.mp4")) as source:
        for i, (_, rgb) in enumerate(source):
            if i >= 5:
                break
            Image.fromarray(rgb).save(tmp_path / f"frame{i:03d}.png")
    (tmp_path / "notes.txt").write_text("ignored")
    track = track_video(tmp_path, progress=False)
    assert len(track) == 5 and track.valid.all() and track.fps == 25.0
    np.testing.assert_allclose(track.times, np.arange(5) / 25.0)


def test_mediapipes_notices_are_silenced_by_two_threads_at_once_and_stderr_comes_back():
    """``animate`` builds the placement's graph while the video's runs in another thread. Each thread
    saving and restoring descriptor 2 on its own left it on /dev/null for good (every error after,
    and the final 'interrupted', went nowhere)."""
    import os
    import threading

    from faceanim.capture.tracker import _native_stderr

    before = os.fstat(2)
    null = os.stat(os.devnull)
    first_in, second_in, first_out = threading.Event(), threading.Event(), threading.Event()
    seen = {}

    def first():
        with _native_stderr.silenced():
            first_in.set()
            second_in.wait(5)
        first_out.set()

    def second():
        first_in.wait(5)
        with _native_stderr.silenced():
            second_in.set()
            first_out.wait(5)
            seen["inside"] = os.fstat(2)

    threads = [threading.Thread(target=first), threading.Thread(target=second)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(10)
    assert (seen["inside"].st_rdev, seen["inside"].st_ino) == (null.st_rdev, null.st_ino)  # still silenced
    after = os.fstat(2)
    assert (after.st_dev, after.st_ino) == (before.st_dev, before.st_ino)  # and back where it was
