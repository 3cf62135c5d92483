"""The command line's one policy for what goes wrong (issue 20): faceanim's declared errors
(InputError, FileFormatError) and the operating system's are one line and exit 2, an interrupt is one
line and 130 (also while faceanim is still importing), and anything else, a plain ValueError included,
is a bug that shows its traceback. Each case a user reached with a plain ValueError (a traceback once
the CLI stopped turning every ValueError into a line) is here: exit 2, one line naming the file or
argument, nothing written."""

import dataclasses
import json
import os
import struct
import subprocess
import sys

import numpy as np
import pytest
from conftest import ROOT, grid_mesh, shared
from test_cli import write_transfer_files

from faceanim.cli import main
from faceanim.errors import FileFormatError, InputError
from faceanim.geometry import read_mesh, write_mesh


def refused(capsys, argv, *, names: str, says: str, outputs=()):
    """Run ``argv``; it must exit 2 with one line on stderr that names ``names`` and says ``says``,
    and leave none of ``outputs``."""
    assert main([str(a) for a in argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("faceanim: error: "), err
    assert str(names) in err[0] and says in err[0], err[0]
    for path in outputs:
        assert not os.path.exists(path), path
    return err[0]


# ---- the policy itself


def test_a_plain_value_error_is_a_bug_and_shows_its_traceback(tmp_path, monkeypatch, capsys):
    """The CLI once printed every ValueError as one line, so a fault in faceanim looked like the user's."""
    from faceanim import pipeline

    def broken(path):
        raise ValueError("weights must have shape (3,), got (4,)")

    monkeypatch.setattr(pipeline, "fap_info", broken)
    with pytest.raises(ValueError, match="weights must have shape"):
        main(["fap-info", str(tmp_path / "a.fap")])
    assert "faceanim: error" not in capsys.readouterr().err


def test_a_declared_error_is_one_line_and_exit_2(tmp_path, monkeypatch, capsys):
    from faceanim import pipeline

    def bad_file(path):
        raise FileFormatError(path, "header must be '<version> <name> <fps> <frame count>'", 1)

    monkeypatch.setattr(pipeline, "fap_info", bad_file)
    refused(capsys, ["fap-info", tmp_path / "a.fap"], names=tmp_path / "a.fap:1", says="header must be")


def test_an_interrupt_before_the_job_is_one_line_and_130(monkeypatch, capsys):
    """Ctrl-C while the parser or the job's modules load (before the job's own handlers are set)."""
    import faceanim.cli

    def interrupted():
        raise KeyboardInterrupt

    monkeypatch.setattr(faceanim.cli, "_parser", interrupted)
    assert main(["fap-info", "a.fap"]) == 130
    assert capsys.readouterr().err == "faceanim: interrupted\n"


def test_importing_the_command_loads_nothing_heavy_so_an_interrupt_in_the_imports_is_caught(tmp_path):
    """The entry point (``faceanim.cli:main``) is imported before ``main`` runs: were numpy and scipy
    imported then (0.3 s), a Ctrl-C there would print a traceback. Here the interrupt lands in numpy's
    import, as a Ctrl-C in the first moments would, through the command's own entry point."""
    code = """
import builtins, sys
import faceanim.cli
assert not {"numpy", "scipy", "faceanim.geometry"} & set(sys.modules), sorted(sys.modules)
real = builtins.__import__
def importing(name, *args, **kwargs):
    if name == "numpy" or name.startswith("numpy."):
        raise KeyboardInterrupt
    return real(name, *args, **kwargs)
builtins.__import__ = importing
sys.exit(faceanim.cli.main(["fap-info", sys.argv[1]]))
"""
    (tmp_path / "a.fap").write_text("2.1 a 25 1\n" + " ".join(["0"] * 68) + "\n0\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src") + os.pathsep + os.environ.get("PYTHONPATH", "")}
    done = subprocess.run([sys.executable, "-c", code, str(tmp_path / "a.fap")], capture_output=True, text=True,
                          env=env, timeout=120)
    assert (done.returncode, done.stderr) == (130, "faceanim: interrupted\n")


# ---- cases a user reached with a plain ValueError, now declared


def test_generic_route_with_two_feature_points_on_one_vertex(tmp_path, capsys):
    from faceanim.generic import generic_target

    target = generic_target()
    write_mesh(tmp_path / "face.obj", target.mesh)
    points = {n: i for n, i in target.points.items() if not n.startswith("mp")}
    points["2.1"] = points["2.2"]
    (tmp_path / "points.json").write_text(json.dumps(points))
    out = tmp_path / "e.obj"
    argv = ["express", "--au", "12:1", "--target", tmp_path / "face.obj", "--points", tmp_path / "points.json",
            "-o", out]
    refused(capsys, [*argv, "--route", "generic"], names=tmp_path / "points.json",
            says=f"2.2 and 2.1 share vertex {points['2.2']}", outputs=[out])
    assert main([str(a) for a in argv]) == 0  # the direct route places its muscles by the points as they are


@pytest.fixture(scope="module")
def portrait_track():
    """The Track of a real portrait (one frame with a face)."""
    from faceanim.capture.track import track_video

    return track_video(shared("mediapipe", "testdata", "sergey.png"))


def _track_of(track, frames: int, face_at, **changes):
    """A Track of ``frames`` frames holding ``track``'s face at the frames ``face_at`` (none elsewhere)."""
    from faceanim.capture.track import Track

    fields = {f.name: getattr(track, f.name) for f in dataclasses.fields(track)}
    landmarks = np.full((frames, *track.landmarks.shape[1:]), np.nan)
    valid = np.zeros(frames, bool)
    landmarks[face_at], valid[face_at] = track.landmarks[0], True
    fields.update(landmarks=landmarks, valid=valid, filled=np.zeros(frames, bool), times=np.arange(frames) / 25.0,
                  fps=25.0, blendshapes=None, blendshape_names=())
    fields.update(changes)
    return Track(**fields)


@pytest.mark.parametrize("command", ["encode", "aus"])
def test_a_saved_track_without_a_face(tmp_path, capsys, portrait_track, command):
    """relaxed_window's 'no usable frame to choose a neutral from' was the message (a video without a face
    is refused when tracked; a saved .npz was not)."""
    _track_of(portrait_track, 12, []).save(tmp_path / "t.npz")
    out = tmp_path / ("t.fap" if command == "encode" else "t.csv")
    refused(capsys, [command, tmp_path / "t.npz", "-o", out], names=tmp_path / "t.npz",
            says="holds no frame with a face (12 frames)", outputs=[out])


def test_a_face_in_one_frame_between_gaps_is_its_own_neutral(tmp_path, capsys, portrait_track):
    """The automatic neutral once chose frames without a face (the face's one frame had no speed, and
    so no score) and the command said 'the neutral frames 0:1 hold no tracked face'."""
    from faceanim.mpeg4.fapfile import read_fap

    _track_of(portrait_track, 12, [6]).save(tmp_path / "t.npz")
    assert main(["encode", str(tmp_path / "t.npz"), "-o", str(tmp_path / "t.fap")]) == 0
    stream = read_fap(tmp_path / "t.fap")
    assert stream.mask[6].any() and not stream.mask[:6].any() and not stream.mask[7:].any()
    # The one face is the face at rest: its FAPs are (near) zero; a count or two is left where the FAP is
    # not a change from rest (the eyes' gaze).
    assert np.abs(stream.values[6]).max() <= 2


def test_a_frame_rate_a_fap_cannot_hold_names_the_output(tmp_path, capsys, portrait_track):
    """write_fap's refusal of a rate that rounds to 0 (a saved track at 0.3 fps) was a plain ValueError."""
    from faceanim.capture.track import Track

    fields = {f.name: getattr(portrait_track, f.name) for f in dataclasses.fields(portrait_track)}
    Track(**{**fields, "fps": 0.3}).save(tmp_path / "slow.npz")
    out = tmp_path / "slow.fap"
    refused(capsys, ["encode", tmp_path / "slow.npz", "-o", out], names=out,
            says="a .fap holds a whole frame rate from 1 to 1000; 0.3 fps rounds to 0", outputs=[out])


def test_write_fap_refuses_a_rate_naming_the_file(tmp_path):
    from faceanim.mpeg4.fapstream import FapStream

    stream = FapStream(np.zeros((2, 68)), np.zeros((2, 68), bool), fps=0.4)
    with pytest.raises(InputError, match=r"a\.fap: a \.fap holds a whole frame rate from 1 to 1000; 0\.4 fps"):
        from faceanim.mpeg4.fapfile import write_fap

        write_fap(tmp_path / "a.fap", stream)
    assert not (tmp_path / "a.fap").exists()


@pytest.mark.parametrize("value", ["1e300", "-1e300", str(2**31), "99999999999"])
def test_a_fap_value_beyond_32_bits_is_refused_naming_file_and_line(tmp_path, capsys, value):
    """1e300 decoded into NaN vertices (numpy's overflow warnings, then a glTF of NaN, exit 0)."""
    mask = " ".join(["0", "0", "1"] + ["0"] * 65)
    (tmp_path / "a.fap").write_text(f"2.1 a 25 2\n{mask}\n0 100\n{mask}\n1 {value}\n")
    out = tmp_path / "a.glb"
    for argv in (["decode", tmp_path / "a.fap", "-o", out], ["fap-info", tmp_path / "a.fap"],
                 ["plot", tmp_path / "a.fap", "-o", tmp_path / "a.png"]):
        refused(capsys, argv, names=tmp_path / "a.fap:5", says=f"value {value} is beyond 32 bits",
                outputs=[out, tmp_path / "a.png"])


def test_the_largest_32_bit_fap_value_is_read(tmp_path):
    from faceanim.mpeg4.fapfile import read_fap

    mask = " ".join(["0", "0", "1"] + ["0"] * 65)
    (tmp_path / "a.fap").write_text(f"2.1 a 25 1\n{mask}\n0 {-(2**31 - 1)}\n")
    assert read_fap(tmp_path / "a.fap").values[0, 2] == -(2**31 - 1)


@pytest.fixture
def transfer_files(tmp_path):
    write_transfer_files(tmp_path)
    return tmp_path


def _transfer(folder, *, source="src.obj", expression="expr.ply", pairs="pairs.json"):
    return ["transfer", folder / source, folder / expression, folder / "tgt.glb", "-o", folder / "out.obj",
            "--correspondence", folder / pairs]


def test_clone_with_fewer_than_4_pairs(transfer_files, capsys):
    pairs = json.loads((transfer_files / "pairs.json").read_text())
    (transfer_files / "three.json").write_text(json.dumps({k: v[:3] for k, v in pairs.items()}))
    argv = _transfer(transfer_files, pairs="three.json")
    refused(capsys, argv, names=transfer_files / "three.json", says="the clone method needs at least 4 pairs, got 3",
            outputs=[transfer_files / "out.obj"])
    assert main([str(a) for a in [*argv, "--method", "rbf"]]) == 0


@pytest.mark.parametrize("how, says", [("coincident", "coincident centres: 0 and 1"),
                                       ("flat", "may lie in a plane or line")])
def test_clone_with_source_control_points_that_cannot_carry_a_warp(transfer_files, capsys, how, says):
    pairs = json.loads((transfer_files / "pairs.json").read_text())
    source = read_mesh(transfer_files / "src.obj")
    vertices = source.vertices.copy()
    if how == "coincident":
        vertices[pairs["source"][1]] = vertices[pairs["source"][0]]
    else:
        vertices[:, 2] = 0.0
    write_mesh(transfer_files / "bad.obj", source.with_vertices(vertices))
    write_mesh(transfer_files / "bad_expr.obj", source.with_vertices(vertices + 0.01))
    refused(capsys, _transfer(transfer_files, source="bad.obj", expression="bad_expr.obj"),
            names=transfer_files / "pairs.json", says=says, outputs=[transfer_files / "out.obj"])


@pytest.mark.parametrize("rows, says", [
    ("1,0,0,1,1,1e308\n2,0,0.04,1,1,-1e308\n", "AU01 reaches 1e+308 in magnitude"),
    ("1,0,1e308,1,1,1\n2,0,-1e308,1,1,2\n", "time (s) reaches 1e+308 in magnitude"),
    ("1,0,0,1,1,nan\n2,0,0.04,1,1,1e301\n", "AU01 reaches 1e+301 in magnitude"),
], ids=["values", "times", "one value"])
def test_a_curve_no_axis_can_scale(tmp_path, capsys, rows, says):
    """matplotlib's 'arange: cannot compute length' was the message."""
    pytest.importorskip("matplotlib")
    (tmp_path / "aus.csv").write_text("frame,face_id,timestamp,confidence,success,AU01_r\n" + rows)
    refused(capsys, ["plot", tmp_path / "aus.csv", "-o", tmp_path / "aus.png"], names=tmp_path / "aus.csv",
            says=says, outputs=[tmp_path / "aus.png"])


# ---- faceanim view: the model must be a complete glTF binary


def _glb(tmp_path):
    from faceanim.export import write_glb

    path = tmp_path / "grid.glb"
    write_glb(path, grid_mesh(4))
    return path.read_bytes()


def _declared(data: bytes, length: int) -> bytes:
    return data[:8] + struct.pack("<I", length) + data[12:]


CUT = {  # a change to a .glb's bytes, and what the viewer says of the result
    "cut short": (lambda d: d[:-16], "its header declares {n} bytes, the file holds {less}"),
    "bytes after its end": (lambda d: d + b"\0\0\0\0", "its header declares {n} bytes, the file holds {more}"),
    "version 1": (lambda d: d[:4] + struct.pack("<I", 1) + d[8:], "version 1; the viewer shows glTF 2"),
    "last chunk cut": (lambda d: _declared(d[:len(d) - 4], len(d) - 4), "declares"),
    "a stray tail": (lambda d: _declared(d + b"\0\0\0", len(d) + 3), "a chunk header at byte {n} is cut short"),
    "no chunk": (lambda d: _declared(d[:12], 12), "it holds no chunk"),
    "header cut": (lambda d: d[:8], "no glTF header"),
    "first chunk not JSON": (lambda d: d[:16] + b"BIN\0" + d[20:], "its first chunk is not JSON"),
}


@pytest.mark.parametrize("case", ["cut short", "bytes after its end", "version 1", "last chunk cut", "a stray tail"])
def test_view_refuses_a_model_that_is_not_a_complete_glb(tmp_path, capsys, case):
    """A .glb cut short (a copy in progress, a full disk) was served, and failed in the browser unsaid.
    (A file without a glTF header or JSON chunk is refused before, when its JSON is read.)"""
    change, says = CUT[case]
    data = _glb(tmp_path)
    (tmp_path / "model.glb").write_bytes(change(data))
    err = refused(capsys, ["view", tmp_path / "model.glb", "--port", "0", "--no-browser"],
                  names=tmp_path / "model.glb", says="is not a complete glTF binary")
    assert says.format(n=len(data), less=len(data) - 16, more=len(data) + 4) in err, err


@pytest.mark.parametrize("case", list(CUT))
def test_the_server_refuses_a_model_that_is_not_a_complete_glb(tmp_path, case):
    from faceanim.viewer import ViewerFiles, ViewerServer

    change, says = CUT[case]
    data = _glb(tmp_path)
    (tmp_path / "model.glb").write_bytes(change(data))
    message = says.format(n=len(data), less=len(data) - 16, more=len(data) + 4)
    with pytest.raises(FileFormatError, match=r"model\.glb: is not a complete glTF binary \(") as caught:
        ViewerServer(ViewerFiles(tmp_path / "model.glb"), port=0)
    assert message in str(caught.value)


def test_the_server_checks_the_model_it_opened(tmp_path):
    """The check reads the descriptor the server serves from, not the path again."""
    from faceanim.viewer import ViewerFiles, ViewerServer

    data = _glb(tmp_path)
    (tmp_path / "model.glb").write_bytes(data[:-8])
    with pytest.raises(FileFormatError, match=r"model\.glb: is not a complete glTF binary"):
        ViewerServer(ViewerFiles(tmp_path / "model.glb"), port=0)
    (tmp_path / "model.glb").write_bytes(data)
    with ViewerServer(ViewerFiles(tmp_path / "model.glb"), port=0) as server:
        assert server.port > 0


# ---- saved tracks that no capture can use, and a neutral window given before the length is known


def _saved_track(path, landmarks, valid):
    from faceanim.capture.track import Track

    Track(landmarks, valid, np.zeros(len(valid), bool), np.arange(len(valid)) / 25.0, 25.0, 64, 64).save(path)
    return path


def test_a_saved_track_with_a_flat_face_is_one_line(tmp_path, capsys):
    """Such a track reached the head frame's fit: 'SVD did not converge', a traceback."""
    landmarks = np.random.default_rng(0).random((5, 478, 3))
    landmarks[2, :, :2] = 0.5  # every landmark of frame 2 on one pixel
    flat = _saved_track(tmp_path / "flat.npz", landmarks, np.ones(5, bool))
    refused(capsys, ["aus", flat, "-o", tmp_path / "f.csv"], names=flat, says="frame 2's landmarks do not span",
            outputs=[tmp_path / "f.csv"])
    landmarks[2, :, 0] = np.linspace(0.2, 0.8, 478)  # on a line: no area either
    line = _saved_track(tmp_path / "line.npz", landmarks, np.ones(5, bool))
    refused(capsys, ["encode", line, "-o", tmp_path / "l.fap"], names=line, says="frame 2's landmarks do not span")


@pytest.mark.skipif(not shared("videos", "d0.mp4").exists(), reason="needs ../shared/data/videos/d0.mp4")
def test_a_neutral_window_is_checked_before_tracking_and_again_against_the_length(tmp_path, capsys):
    video = shared("videos", "d0.mp4")
    said = refused(capsys, ["encode", video, "-o", tmp_path / "a.fap", "--neutral", "5:5"], names="--neutral 5:5",
                   says="START < END", outputs=[tmp_path / "a.fap"])
    assert "4611686018427387904" not in said  # no made-up length in the message
    refused(capsys, ["encode", video, "-o", tmp_path / "b.fap", "--neutral", "100000:100010"],
            names="--neutral 100000:100010", says="frames must lie in [0, ", outputs=[tmp_path / "b.fap"])
