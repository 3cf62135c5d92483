"""`faceanim decode` and `faceanim animate` end to end (real data; skipped without it)."""

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import khronos_report, shared
from test_gltf import decode as decode_glb

from faceanim.cli import main

pytest.importorskip("moderngl", reason="needs faceanim[render]")
pytest.importorskip("mediapipe", reason="needs faceanim[capture]")
av = pytest.importorskip("av", reason="needs faceanim[capture]")


def test_decode_joy_onto_ict_with_automatic_placement(tmp_path):
    mesh = shared("ict_facekit", "obj", "generic_neutral_mesh.obj")
    joy = shared("xface", "Faps", "joy.fap")
    out, preview = tmp_path / "joy.glb", tmp_path / "joy.mp4"
    assert main(["decode", str(joy), "--target", str(mesh), "-o", str(out), "--preview", str(preview)]) == 0
    report = khronos_report(out)
    assert report["errors"] == 0 and report["warnings"] == 0, report["messages"]
    frames, times = decode_glb(out)
    assert frames.shape[0] == 108 and abs(times[-1] - 107 / 25) < 1e-5
    with av.open(str(preview)) as container:
        assert sum(1 for _ in container.decode(video=0)) == 108


def test_decode_with_a_points_file_and_bad_inputs(tmp_path, capsys):
    mesh = shared("ict_facekit", "obj", "generic_neutral_mesh.obj")
    joy = shared("xface", "Faps", "joy.fap")
    landmarks = json.loads(shared("ict_facekit", "landmarks_multipie68.json").read_text())["multi_pie_68"]
    from faceanim.mpeg4.multipie import MULTIPIE68_OF_FEATURE_POINT

    (tmp_path / "p.json").write_text(json.dumps({n: landmarks[i] for n, i in MULTIPIE68_OF_FEATURE_POINT.items()}))
    assert main(["decode", str(joy), "--target", str(mesh), "--points", str(tmp_path / "p.json"),
                 "-o", str(tmp_path / "a.glb")]) == 0
    (tmp_path / "far.json").write_text(json.dumps({"8.3": 10 ** 6}))
    for args, message in (
            (["--points", str(tmp_path / "far.json"), "-o", str(tmp_path / "b.glb")], "names vertex 1000000"),
            (["-o", str(tmp_path / "b.obj")], "b.obj: this output is written as .glb"),
            (["-o", str(tmp_path / "nowhere" / "b.glb")], "does not exist"),
            (["--workers", "0", "-o", str(tmp_path / "b.glb")], "--workers must be a whole number from 1, got 0")):
        assert main(["decode", str(joy), "--target", str(mesh), *args]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and message in err[0], err
    assert not (tmp_path / "b.glb").exists()


def test_animate_a_video_onto_ict(tmp_path):
    mesh = shared("ict_facekit", "obj", "generic_neutral_mesh.obj")
    video = shared("videos", "d0.mp4")
    out = tmp_path / "d0.glb"
    assert main(["animate", str(video), "--target", str(mesh), "-o", str(out), "--fap", str(tmp_path / "d0.fap"),
                 "--preview", str(tmp_path / "d0.mp4")]) == 0
    frames, _ = decode_glb(out)
    assert frames.shape[0] == 78 and (tmp_path / "d0.fap").exists()
    with av.open(str(tmp_path / "d0.mp4")) as container:
        first = next(container.decode(video=0))
        assert first.width == 2 * first.height  # the source beside the target


def test_animate_takes_its_neutral_and_filter_from_the_command_line(tmp_path, capsys):
    """--neutral 20:30 makes frames 20-29 the rest: the avatar averaged over them is its rest mesh (to
    the second order of the jaw's small turns there; the eyeballs, which turn with the tracked gaze,
    are left out). The command's --no-filter gives what the pipeline gives unfiltered (to the .glb's
    morph-target precision), not what it gives filtered. An image as animate's neutral is one line on
    stderr, with nothing written."""
    from faceanim import pipeline
    from faceanim.inputs import load_target
    from faceanim.parts import face_parts

    video = shared("videos", "d0.mp4")
    unfiltered, _ = pipeline.animate(video, tmp_path / "u.glb", neutral="20:30", smoothing=False, progress=False)
    rest = unfiltered.mesh.vertices
    still = ~face_parts(load_target(None)).mask("eye_left", "eye_right")
    np.testing.assert_allclose(unfiltered.positions[20:30].mean(axis=0)[still], rest[still], atol=2e-3)
    assert np.abs(unfiltered.positions - rest).max() > 0.05  # yet the face does move
    filtered, _ = pipeline.animate(video, tmp_path / "f.glb", neutral="20:30", progress=False)
    out = tmp_path / "n.glb"
    assert main(["animate", str(video), "-o", str(out), "--neutral", "20:30", "--no-filter"]) == 0
    frames, _ = decode_glb(out)
    to_unfiltered = np.abs(frames - unfiltered.positions).max()
    assert to_unfiltered < 0.2 * np.abs(frames - filtered.positions).max(), to_unfiltered
    assert main(["animate", str(video), "-o", str(tmp_path / "x.glb"), "--neutral", "face.png"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "animate takes the neutral as FRAME or START:END" in err[0], err
    assert not (tmp_path / "x.glb").exists()


def test_pipeline_argument_errors(tmp_path):
    from faceanim import pipeline
    from faceanim.errors import InputError

    mesh = shared("ict_facekit", "obj", "generic_neutral_mesh.obj")
    with pytest.raises(InputError, match="give the control points once: --points or --fdp, not both"):
        pipeline.load_target(mesh, points=tmp_path / "p.json", fdp=tmp_path / "f.fdp")
    video = shared("videos", "d0.mp4")
    with pytest.raises(InputError, match="animate takes the neutral as FRAME or START:END"):
        pipeline.animate(video, tmp_path / "a.glb", target_mesh=mesh, neutral="face.png", progress=False)
    with pytest.raises(InputError, match="via must be motion or faps, got 'points'"):
        pipeline.animate(video, tmp_path / "a.glb", target_mesh=mesh, via="points", progress=False)
    assert not (tmp_path / "a.glb").exists()


def test_animate_falls_back_to_the_faps_for_a_target_sharing_few_points(tmp_path):
    import numpy as np

    from faceanim import pipeline
    from faceanim.geometry import read_mesh
    from faceanim.mpeg4 import Fapu
    from faceanim.retarget.decode import animate_faps
    from faceanim.target import Target

    mesh = read_mesh(shared("ict_facekit", "obj", "generic_neutral_mesh.obj"))
    landmarks = json.loads(shared("ict_facekit", "landmarks_multipie68.json").read_text())["multi_pie_68"]
    # seven feature points (chin, lip corners and middles, nose tip): too few to follow the motion
    points = {"2.1": landmarks[8], "8.3": landmarks[54], "8.4": landmarks[48], "8.1": landmarks[51],
              "8.2": landmarks[57], "9.3": landmarks[30], "2.2": landmarks[62]}
    target = Target(mesh, points, Fapu(irisd0=1.1, es0=6.0, ens0=4.0, mns0=2.5, mw0=4.5))
    with pytest.warns(UserWarning, match="shares only 7 control points .* driven through the FAPs"):
        animation, stream = pipeline.animate(shared("videos", "d0.mp4"), tmp_path / "a.glb", target=target,
                                             progress=False)
    np.testing.assert_allclose(animation.positions, animate_faps(stream, target).positions)


def test_decode_onto_the_default_avatar_with_obj_sequence_and_csv(tmp_path, capsys):
    import numpy as np

    from faceanim.geometry import read_mesh
    from faceanim.mpeg4.fapfile import read_fap

    joy = shared("xface", "Faps", "joy.fap")
    frames_dir, csv = tmp_path / "frames", tmp_path / "joy.csv"
    assert main(["decode", str(joy), "-o", str(tmp_path / "joy.glb"), "--obj-sequence", str(frames_dir),
                 "--csv", str(csv)]) == 0
    objs = sorted(frames_dir.glob("*.obj"))
    assert len(objs) == 108 and (frames_dir / "face.png").exists() and (frames_dir / "face.mtl").exists()
    first, moved = read_mesh(objs[0]), read_mesh(objs[60])
    assert first.texture is not None and first.triangles.shape == moved.triangles.shape
    assert decode_glb(tmp_path / "joy.glb")[0].shape[0] == 108
    assert np.abs(moved.vertices - first.vertices).max() > 0.1  # the sequence moves
    stream = read_fap(joy)
    lines = csv.read_text().splitlines()
    header = lines[0].split(",")
    assert len(lines) == 109 and header[:3] == ["frame", "timestamp", "success"] and "12_raise_l_cornerlip" in header
    assert lines[1].split(",")[:3] == ["1", "0.000", "1"]  # the .fap's frame 0 at 0 s, counted from 1
    column = header.index("12_raise_l_cornerlip")
    assert [float(r.split(",")[column]) for r in lines[1:]] == pytest.approx(stream.values[:, 11].tolist())
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "keep.txt").write_text("mine")
    assert main(["decode", str(joy), "-o", str(tmp_path / "b.glb"), "--obj-sequence", str(tmp_path / "full")]) == 2
    assert "full: exists and is not an empty folder" in capsys.readouterr().err
    assert not (tmp_path / "b.glb").exists() and (tmp_path / "full" / "keep.txt").read_text() == "mine"


def test_animate_without_a_preview_times_its_curves_by_the_video_and_spills_beside_the_output(tmp_path, monkeypatch):
    """Without --preview the tracked landmarks are let go once the motion is made; the --csv curves still
    carry the video's own times and found flags. The deformed frames are spilled in the output's folder
    (not the system's temporary folder, a tmpfs on many systems)."""
    import csv as csvlib
    import tempfile

    from faceanim.capture.track import track_video

    folders = []
    made = tempfile.TemporaryFile

    def recorded(*args, **kwargs):
        folders.append(kwargs.get("dir"))
        return made(*args, **kwargs)

    monkeypatch.setattr(tempfile, "TemporaryFile", recorded)
    video = shared("videos", "d0.mp4")
    curves = tmp_path / "d0.csv"
    assert main(["animate", str(video), "-o", str(tmp_path / "d0.glb"), "--csv", str(curves)]) == 0
    assert tmp_path in [None if f is None else Path(f) for f in folders]
    rows = list(csvlib.reader(open(curves)))
    track = track_video(video, progress=False)
    assert len(rows) == 1 + len(track)
    times = [float(r[1]) for r in rows[1:]]
    assert times == pytest.approx(track.times.tolist(), abs=1e-4)


def test_workers_on_the_command_line_set_the_processes_that_deform_the_frames(tmp_path, monkeypatch):
    """--workers reaches the deforming step as given; without it, the machine's default
    (:func:`~faceanim.geometry.animation.worker_count`, which the help's "at most 4" names)."""
    from faceanim import pipeline
    from faceanim.geometry.animation import MOST_WORKERS, spilled, worker_count

    asked = []

    def recorded(animation, **kwargs):
        asked.append(kwargs["workers"])
        return spilled(animation, **kwargs)

    monkeypatch.setattr(pipeline, "spilled", recorded)
    joy = shared("xface", "Faps", "joy.fap")
    for extra in (["--workers", "5"], []):  # 5: more than the default ever is
        assert main(["decode", str(joy), "-o", str(tmp_path / f"joy{len(extra)}.glb"), *extra]) == 0
    assert asked == [5, worker_count()]
    video = shared("videos", "d0.mp4")
    assert main(["animate", str(video), "-o", str(tmp_path / "d0.glb"), "--workers", "5"]) == 0
    assert asked[-1] == 5
    for command in ("decode", "animate"):
        assert f"at most {MOST_WORKERS})" in " ".join(command_help(command).split())


def command_help(command: str) -> str:
    import contextlib
    import io

    shown = io.StringIO()
    with contextlib.redirect_stdout(shown), pytest.raises(SystemExit):
        main([command, "--help"])
    return shown.getvalue()
