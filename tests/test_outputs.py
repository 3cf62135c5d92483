"""Nothing overwritten, nothing left half done: every output path checked before any work
(faceanim.outputs), a job's outputs all written or none (faceanim.atomic.output_group), one policy at
the command line for errors and interrupts, and odd values refused by name (issue 20)."""

import hashlib
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, grid_mesh, shared
from test_cli import write_transfer_files

from faceanim import atomic, pipeline
from faceanim.atomic import atomic_output, output_group
from faceanim.cli import main
from faceanim.errors import InputError
from faceanim.geometry import Mesh, write_mesh
from faceanim.geometry.obj import write_material
from faceanim.outputs import SEQUENCE_FOLDER, check_output_folder, check_outputs, is_ours, side_files


def snapshot(folder):
    """Every file under ``folder`` (hidden ones included) with the hash of its bytes."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "folder"
            for p in sorted(folder.rglob("*")) if not p.is_symlink()}


def one_error_line(capsys) -> str:
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("faceanim: error: "), err
    return lines[0]


# ---- the check itself


@pytest.mark.parametrize("argument, path, kind", [
    ("-o", "a.obj", ".glb"), ("--fap", "in.mp4", ".fap"), ("--preview", "j.glb", ".mp4"),
    ("--overlay", "o.avi", ".mp4"), ("--csv", "in.mp4", ".csv"), ("-o", "x.png", (".obj", ".glb", ".fap")),
])
def test_a_wrong_suffix_is_refused_naming_the_argument(tmp_path, argument, path, kind):
    choices = kind if isinstance(kind, str) else ", ".join(kind)
    with pytest.raises(InputError, match=f"^{argument} .*{path}: this output is written as {choices}$"):
        check_outputs({argument: (tmp_path / path, kind)})


def test_suffixes_are_compared_without_case(tmp_path):
    check_outputs({"-o": (tmp_path / "FACE.GLB", ".glb")})


def test_an_output_that_is_an_input_is_refused_however_it_is_spelled(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "in.mp4").write_bytes(b"video")
    (tmp_path / "sub").mkdir()
    os.symlink(tmp_path / "in.mp4", tmp_path / "link.mp4")
    os.link(tmp_path / "in.mp4", tmp_path / "hard.mp4")
    for spelled in ("in.mp4", "./in.mp4", str(tmp_path / "in.mp4"), "sub/../in.mp4", "link.mp4", "hard.mp4"):
        with pytest.raises(InputError, match=f"^--preview {re.escape(str(Path(spelled)))}: is also the input VIDEO; "
                                             "faceanim does not write over its inputs$"):
            check_outputs({"-o": ("o.glb", ".glb"), "--preview": (spelled, ".mp4")}, inputs={"VIDEO": "in.mp4"})
    # an input given through a symlink is caught from the other side too
    with pytest.raises(InputError, match="--overlay in.mp4: is also the input VIDEO"):
        check_outputs({"--overlay": ("in.mp4", ".mp4")}, inputs={"VIDEO": "link.mp4"})


def test_two_outputs_on_one_path_are_refused(tmp_path):
    with pytest.raises(InputError, match=r"--csv .*b\.csv: is also where -o goes; give each output its own path"):
        check_outputs({"-o": (tmp_path / "b.csv", ".csv"), "--csv": (tmp_path / "b.csv", ".csv")})
    with pytest.raises(InputError, match=r"-o .*me\.obj: its material .*me\.mtl is also the input --fdp"):
        check_outputs({"-o": (tmp_path / "me.obj", ".obj")}, inputs={"--fdp": tmp_path / "me.mtl"})


def test_the_folder_must_exist_be_a_folder_and_be_writable(tmp_path):
    with pytest.raises(InputError, match="^--preview .*p.mp4: the folder .*missing does not exist$"):
        check_outputs({"--preview": (tmp_path / "missing" / "p.mp4", ".mp4")})
    (tmp_path / "file").write_text("x")
    with pytest.raises(InputError, match="^-o .*x.glb: .*file is not a folder$"):
        check_outputs({"-o": (tmp_path / "file" / "x.glb", ".glb")})
    (tmp_path / "taken.glb").mkdir()
    with pytest.raises(InputError, match="^-o .*taken.glb: is a folder$"):
        check_outputs({"-o": (tmp_path / "taken.glb", ".glb")})


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="root may write in any folder")
def test_a_read_only_folder_is_refused_before_any_work(tmp_path, capsys):
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        (tmp_path / "in.mp4").write_bytes(b"not read")
        assert main(["track", str(tmp_path / "in.mp4"), "-o", str(locked / "t.npz")]) == 2
        line = one_error_line(capsys)
        assert "-o " in line and "is not writable" in line
    finally:
        locked.chmod(0o700)


def test_a_folder_that_cannot_be_written_in_is_named(tmp_path, monkeypatch):
    """Root may write anywhere, so the refusal is shown with the permission check made to say no."""
    from faceanim import outputs

    monkeypatch.setattr(outputs.os, "access", lambda *_: False)
    with pytest.raises(InputError, match="^--csv .*c.csv: the folder .* is not writable$"):
        check_outputs({"--csv": (tmp_path / "c.csv", ".csv")})
    with pytest.raises(InputError, match="^-o .*demo: the folder .* is not writable$"):
        check_output_folder("-o", tmp_path / "demo")


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs Linux's /proc, a folder no file can be made in")
def test_a_folder_where_no_file_can_be_made_is_refused_before_any_work(tmp_path, capsys):
    """/proc passes the permission check (root may write anywhere) yet takes no new file: the output
    used to fail after the work, naming the hidden temporary file."""
    fap = tmp_path / "f.fap"
    fap.write_text("not read: the output is refused first")
    assert main(["decode", str(fap), "-o", "/proc/faceanim-x.glb"]) == 2
    assert capsys.readouterr().err == "faceanim: error: -o /proc/faceanim-x.glb: no file can be made in /proc " \
                                      "(No such file or directory)\n"
    with pytest.raises(InputError, match="^-o /proc/faceanim-demo: no file can be made in /proc"):
        check_output_folder("-o", "/proc/faceanim-demo")


def test_the_sequence_folder_is_new_or_empty_and_holds_only_the_sequence(tmp_path):
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "keep.txt").write_text("mine")
    with pytest.raises(InputError, match="^--obj-sequence .*full: exists and is not an empty folder"):
        check_outputs({"--obj-sequence": (tmp_path / "full", SEQUENCE_FOLDER)})
    (tmp_path / "empty").mkdir()
    check_outputs({"--obj-sequence": (tmp_path / "empty", SEQUENCE_FOLDER)})
    with pytest.raises(InputError, match=r"^--preview .*p\.mp4: lies in --obj-sequence's folder .*empty, which "
                                         "holds only the OBJ sequence$"):
        check_outputs({"--obj-sequence": (tmp_path / "empty", SEQUENCE_FOLDER),
                       "--preview": (tmp_path / "empty" / "p.mp4", ".mp4")})


def test_a_link_to_an_empty_folder_is_refused_as_the_sequence_folder(tmp_path, capsys):
    """The finished sequence is renamed onto the path; onto a link to an empty folder that failed at the
    very end, after the .glb and --csv had been put in place ('Not a directory', exit 2)."""
    (tmp_path / "empty").mkdir()
    (tmp_path / "seq").symlink_to(tmp_path / "empty")
    with pytest.raises(InputError, match=r"^--obj-sequence .*seq: is a symbolic link"):
        check_outputs({"--obj-sequence": (tmp_path / "seq", SEQUENCE_FOLDER)})
    fap = shared("xface", "Faps", "test.fap")
    if fap.is_file():  # through the command: refused before any work, nothing written
        assert main(["decode", str(fap), "-o", str(tmp_path / "s.glb"), "--csv", str(tmp_path / "s.csv"),
                     "--obj-sequence", str(tmp_path / "seq")]) == 2
        assert "--obj-sequence" in one_error_line(capsys)
        assert sorted(p.name for p in tmp_path.iterdir()) == ["empty", "seq"]
        assert not any((tmp_path / "empty").iterdir())


def test_an_output_folder_exists_or_can_be_made(tmp_path):
    assert check_output_folder("-o", tmp_path / "new" / "deeper") == tmp_path / "new" / "deeper"
    (tmp_path / "file").write_text("x")
    with pytest.raises(InputError, match="^-o .*file: exists and is not a folder$"):
        check_output_folder("-o", tmp_path / "file")
    with pytest.raises(InputError, match="^-o .*inside: .*file is not a folder$"):
        check_output_folder("-o", tmp_path / "file" / "inside")


def test_non_paths_among_the_inputs_are_skipped(tmp_path):
    check_outputs({"-o": (tmp_path / "x.fap", ".fap")}, inputs={"--neutral": 12, "--target": None})


# ---- side files


def textured_grid() -> Mesh:
    mesh = grid_mesh(4)
    return Mesh(mesh.vertices, mesh.triangles, uv=mesh.vertices[:, :2], uv_triangles=mesh.triangles,
                texture=np.full((8, 8, 3), 200, np.uint8))


def test_side_files_are_named_after_the_obj_and_marked_as_ours(tmp_path):
    material, texture = side_files(tmp_path / "me.obj")
    assert (material.name, texture.name) == ("me.mtl", "me_texture.png")
    (tmp_path / "me.png").write_bytes(b"a user's photo")
    write_mesh(tmp_path / "me.obj", textured_grid())
    assert (tmp_path / "me.png").read_bytes() == b"a user's photo"  # a photo named like the OBJ is no side file
    assert is_ours(material) and is_ours(texture)
    assert "map_Kd me_texture.png" in material.read_text()
    assert not is_ours(tmp_path / "me.png") and not is_ours(tmp_path / "absent.mtl")
    write_mesh(tmp_path / "me.obj", textured_grid())  # its own side files are replaced without asking
    write_material(tmp_path, "face", np.zeros((2, 2, 3), np.uint8))  # an OBJ sequence's: face.mtl, face.png
    assert is_ours(tmp_path / "face.mtl") and is_ours(tmp_path / "face.png")


@pytest.mark.parametrize("which", [0, 1])
def test_a_side_file_faceanim_did_not_write_is_kept_unless_forced(tmp_path, which):
    side = side_files(tmp_path / "me.obj")[which]
    side.write_bytes(b"\x89PNG not ours" if side.suffix == ".png" else b"newmtl mine\n")
    before = side.read_bytes()
    what = ("material", "texture")[which]
    with pytest.raises(InputError, match=f"me.obj: its {what} would replace .*{side.name}, which faceanim did not "
                                         "write; move it away, or pass --force"):
        write_mesh(tmp_path / "me.obj", textured_grid())
    with pytest.raises(InputError, match=f"^-o .*me.obj: its {what} would replace"):
        check_outputs({"-o": (tmp_path / "me.obj", ".obj")})
    assert side.read_bytes() == before and not (tmp_path / "me.obj").exists()
    check_outputs({"-o": (tmp_path / "me.obj", ".obj")}, force=True)
    write_mesh(tmp_path / "me.obj", textured_grid(), force=True)
    assert is_ours(side)
    with pytest.raises(InputError, match="is also the input"):  # force never reaches an input
        check_outputs({"-o": (tmp_path / "me.obj", ".obj")}, inputs={"--target": side}, force=True)


# ---- the command line: overwrite cases, each refused before any work


@pytest.fixture
def inputs(tmp_path):
    """Stand-ins for the inputs (their content is never read: every case is refused first), and meshes
    and pairs for transfer."""
    (tmp_path / "in.mp4").write_bytes(b"the source video")
    (tmp_path / "joy.fap").write_text("the FAP file")
    (tmp_path / "j.glb").write_bytes(b"an earlier glTF")
    (tmp_path / "face.obj").write_text("the target mesh")
    os.symlink(tmp_path / "in.mp4", tmp_path / "link.mp4")
    write_transfer_files(tmp_path)
    return tmp_path


TRANSFER = ["transfer", "src.obj", "expr.ply", "tgt.glb", "--correspondence", "pairs.json"]


@pytest.mark.parametrize("argv, named", [
    (["animate", "in.mp4", "-o", "o.glb", "--fap", "in.mp4"], "--fap in.mp4: this output is written as .fap"),
    (["animate", "in.mp4", "-o", "o.glb", "--preview", "./in.mp4"], "--preview in.mp4: is also the input VIDEO"),
    (["animate", "in.mp4", "-o", "o.glb", "--csv", "c.csv", "--fap", "c.csv"], "--fap c.csv: this output is"),
    (["track", "in.mp4", "-o", "t.npz", "--csv", "in.mp4"], "--csv in.mp4: this output is written as .csv"),
    (["track", "in.mp4", "-o", "t.npz", "--overlay", "in.mp4"], "--overlay in.mp4: is also the input VIDEO"),
    (["track", "link.mp4", "-o", "t.npz", "--overlay", "in.mp4"], "--overlay in.mp4: is also the input VIDEO"),
    (["decode", "joy.fap", "-o", "j.glb", "--preview", "j.glb"], "--preview j.glb: this output is written as .mp4"),
    (["decode", "joy.fap", "-o", "joy.fap"], "-o joy.fap: this output is written as .glb"),
    (["decode", "joy.fap", "-o", "tgt.glb", "--target", "tgt.glb"], "-o tgt.glb: is also the input --target"),
    (["encode", "in.mp4", "-o", "in.mp4"], "-o in.mp4: this output is written as .fap"),
    (["express", "--au", "12:1", "--target", "face.obj", "-o", "./face.obj"], "-o face.obj: is also the input"),
    (["aus", "in.mp4", "-o", "in.mp4"], "-o in.mp4: this output is written as .csv"),
    (["avatar", "in.mp4", "-o", "in.mp4"], "-o in.mp4: this output is written as .glb"),
    ([*TRANSFER, "-o", "./tgt.glb"], "-o tgt.glb: is also the input TARGET_NEUTRAL"),
    ([*TRANSFER, "-o", "pairs.json"], "-o pairs.json: this output is written as .obj, .ply, .glb"),
    ([*TRANSFER, "-o", "src.obj"], "-o src.obj: is also the input SRC_NEUTRAL"),
])
def test_no_input_is_overwritten(inputs, monkeypatch, capsys, argv, named):
    monkeypatch.chdir(inputs)
    before = snapshot(inputs)
    assert main(argv) == 2
    assert named in one_error_line(capsys)
    assert snapshot(inputs) == before  # every input byte-identical, nothing new, no hidden file


def test_the_obj_sequence_folder_holds_nothing_else(inputs, monkeypatch, capsys):
    monkeypatch.chdir(inputs)
    (inputs / "frames").mkdir()
    before = snapshot(inputs)
    assert main(["decode", "joy.fap", "-o", "j2.glb", "--obj-sequence", "frames", "--preview", "frames/p.mp4"]) == 2
    assert "--preview frames/p.mp4: lies in --obj-sequence's folder frames" in one_error_line(capsys)
    assert snapshot(inputs) == before


def test_an_obj_output_keeps_a_material_it_did_not_write_unless_forced(inputs, monkeypatch, capsys):
    monkeypatch.chdir(inputs)
    (inputs / "me.mtl").write_text("newmtl mine\n")
    (inputs / "me.png").write_bytes(b"a user's photo")
    before = snapshot(inputs)
    assert main([*TRANSFER, "-o", "me.obj"]) == 2
    assert "-o me.obj: its material would replace me.mtl, which faceanim did not write" in one_error_line(capsys)
    assert snapshot(inputs) == before
    assert main([*TRANSFER, "-o", "me.obj", "--force"]) == 0
    assert (inputs / "me.obj").exists() and (inputs / "me.png").read_bytes() == b"a user's photo"


# ---- late failures are now early ones


@pytest.mark.parametrize("argv, named", [
    (["decode", "joy.fap", "-o", "j2.glb", "--preview", "missing_dir/p.mp4"],
     "--preview missing_dir/p.mp4: the folder missing_dir does not exist"),
    (["decode", "joy.fap", "-o", "j2.glb", "--csv", "missing_dir/c.csv"], "--csv missing_dir/c.csv: the folder"),
    (["animate", "in.mp4", "-o", "j2.glb", "--fap", "missing_dir/f.fap"], "--fap missing_dir/f.fap: the folder"),
    (["track", "in.mp4", "-o", "missing_dir/t.npz"], "-o missing_dir/t.npz: the folder missing_dir does not exist"),
    (["track", "in.mp4", "-o", "t.npz", "--overlay", "missing_dir/o.mp4"], "--overlay missing_dir/o.mp4: the"),
    (["encode", "in.mp4", "-o", "missing_dir/x.fap"], "-o missing_dir/x.fap: the folder missing_dir does not exist"),
    (["aus", "in.mp4", "-o", "missing_dir/a.csv"], "-o missing_dir/a.csv: the folder missing_dir does not exist"),
    ([*TRANSFER, "-o", "missing_dir/x.obj"], "-o missing_dir/x.obj: the folder missing_dir does not exist"),
    (["demo", "-o", "joy.fap"], "-o joy.fap: exists and is not a folder"),
])
def test_unusable_outputs_are_refused_before_any_work(inputs, monkeypatch, capsys, argv, named):
    """The inputs here are stand-ins no reader accepts: the output's one-line error, not the input's,
    shows that nothing was read, let alone tracked or written."""
    monkeypatch.chdir(inputs)
    before = snapshot(inputs)
    assert main(argv) == 2
    assert named in one_error_line(capsys)
    assert snapshot(inputs) == before


def writes_then(tmp_path, failure):
    """A stand-in for pipeline.encode that finishes its .fap and a CSV, then meets ``failure()``."""
    def encode(source, output, **_):
        with atomic_output(output) as tmp:
            tmp.write_text("new FAPs")
        with atomic_output(tmp_path / "curves.csv") as tmp:
            tmp.write_text("new curves")
        failure()
        raise AssertionError("not reached")
    return encode


def test_a_late_error_leaves_none_of_the_jobs_outputs(tmp_path, monkeypatch, capsys):
    (tmp_path / "x.fap").write_text("the earlier FAPs")

    def late():
        raise InputError("found late")

    monkeypatch.setattr(pipeline, "encode", writes_then(tmp_path, late))
    assert main(["encode", str(tmp_path / "in.mp4"), "-o", str(tmp_path / "x.fap")]) == 2
    assert one_error_line(capsys) == "faceanim: error: found late"
    assert snapshot(tmp_path) == {"x.fap": hashlib.sha256(b"the earlier FAPs").hexdigest()}


@pytest.mark.parametrize("number, status", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_an_interrupt_removes_the_jobs_outputs_and_temporary_files(tmp_path, monkeypatch, capsys, number, status):
    """The signal arrives after two outputs are finished and before the job ends: neither appears, no
    temporary file is left, the earlier file at -o is unchanged, one line, 128 + the signal's number;
    the handlers in place before are back afterwards."""
    (tmp_path / "x.fap").write_text("the earlier FAPs")
    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}

    def interrupted():
        os.kill(os.getpid(), number)
        time.sleep(30)  # the handler raises here

    monkeypatch.setattr(pipeline, "encode", writes_then(tmp_path, interrupted))
    assert main(["encode", str(tmp_path / "in.mp4"), "-o", str(tmp_path / "x.fap")]) == status
    assert capsys.readouterr().err == "faceanim: interrupted\n"
    assert snapshot(tmp_path) == {"x.fap": hashlib.sha256(b"the earlier FAPs").hexdigest()}
    assert {s: signal.getsignal(s) for s in before} == before


@pytest.mark.parametrize("number, status", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_an_interrupt_a_library_swallows_still_ends_the_job(tmp_path, monkeypatch, capsys, number, status):
    """trimesh's optional imports catch BaseException, so an interrupt raised while it is imported never
    reaches main; the job runs on to its end, but still leaves none of its outputs and says interrupted
    (it wrote them all and exited 0)."""
    (tmp_path / "x.fap").write_text("the earlier FAPs")

    def job(path):
        with atomic_output(tmp_path / "x.fap") as tmp:
            tmp.write_text("new FAPs")
        try:
            os.kill(os.getpid(), number)
            time.sleep(30)  # the handler raises here
        except BaseException:  # as trimesh does around its optional imports
            pass
        with atomic_output(tmp_path / "curves.csv") as tmp:
            tmp.write_text("new curves")
        return "a summary"

    monkeypatch.setattr(pipeline, "fap_info", job)
    assert main(["fap-info", str(tmp_path / "x.fap")]) == status
    assert capsys.readouterr() == ("", "faceanim: interrupted\n")
    assert snapshot(tmp_path) == {"x.fap": hashlib.sha256(b"the earlier FAPs").hexdigest()}


@pytest.mark.parametrize("number, status", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_an_error_a_library_raises_on_the_interrupt_still_ends_the_job_interrupted(tmp_path, monkeypatch, capsys,
                                                                                  number, status):
    """A library cut short mid-write by the interrupt raises its own error on the way out (zipfile closed
    with an entry half-written): the job ends interrupted, one line, no traceback, none of its outputs."""
    (tmp_path / "x.fap").write_text("the earlier FAPs")

    def job(path):
        with atomic_output(tmp_path / "x.fap") as tmp:
            tmp.write_text("new FAPs")
            try:
                os.kill(os.getpid(), number)
                time.sleep(30)  # the handler raises here
            except BaseException:
                raise ValueError("Can't close the ZIP file while there is an open writing handle on it. "
                                 "Close the writing handle before closing the zip.") from None
        return "a summary"

    monkeypatch.setattr(pipeline, "fap_info", job)
    assert main(["fap-info", str(tmp_path / "x.fap")]) == status
    assert capsys.readouterr() == ("", "faceanim: interrupted\n")
    assert snapshot(tmp_path) == {"x.fap": hashlib.sha256(b"the earlier FAPs").hexdigest()}


@pytest.mark.parametrize("after_the_interrupt", [False, True])
def test_an_error_not_raised_by_the_interrupt_is_a_bug_shown_as_one(tmp_path, monkeypatch, after_the_interrupt):
    """The same error with no interrupt, or after one that was swallowed (not in its context): a traceback."""
    def job(path):
        if after_the_interrupt:
            try:
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(30)  # the handler raises here
            except BaseException:
                pass
        raise ValueError("a contract broken by faceanim's own code")

    monkeypatch.setattr(pipeline, "fap_info", job)
    with pytest.raises(ValueError, match="contract broken"):
        main(["fap-info", str(tmp_path / "x.fap")])


@pytest.mark.parametrize("folder", [False, True])
def test_an_interrupt_the_moment_a_temporary_appears_leaves_nothing(tmp_path, monkeypatch, folder):
    """The signal lands just as the hidden temporary file (or folder) is made, before the caller has
    been handed it: it is removed all the same."""
    made = atomic._create

    def interrupted_after(tmp, *, folder):
        made(tmp, folder=folder)
        assert tmp.exists()
        raise KeyboardInterrupt

    monkeypatch.setattr(atomic, "_create", interrupted_after)
    writer = atomic.atomic_folder(tmp_path / "frames") if folder else atomic_output(tmp_path / "x.fap")
    with pytest.raises(KeyboardInterrupt):
        with writer:
            pass
    assert list(tmp_path.iterdir()) == []


def test_temporaries_take_the_usual_permissions(tmp_path):
    mask = os.umask(0o027)
    try:
        with atomic_output(tmp_path / "x.fap") as tmp:
            assert tmp.name.startswith(".x.fap.") and tmp.suffix == ".fap"
            tmp.write_text("FAPs")
        with atomic.atomic_folder(tmp_path / "frames") as work:
            assert work.name.startswith(".frames.")
    finally:
        os.umask(mask)
    assert (tmp_path / "x.fap").stat().st_mode & 0o777 == 0o640
    assert (tmp_path / "frames").stat().st_mode & 0o777 == 0o750


@pytest.mark.parametrize("number", [signal.SIGINT, signal.SIGTERM])
def test_the_viewer_stops_on_an_interrupt_with_status_0(tmp_path, monkeypatch, capsys, number):
    """Ctrl-C (or SIGTERM) is how the viewer stops: exit 0, no 'interrupted' (not taken for a job that
    swallowed its interrupt)."""
    write_mesh(tmp_path / "m.glb", grid_mesh())

    def serve_forever(self):
        os.kill(os.getpid(), number)
        time.sleep(30)  # the handler raises here

    monkeypatch.setattr("faceanim.viewer.ViewerServer.serve_forever", serve_forever)
    assert main(["view", str(tmp_path / "m.glb"), "--port", "0", "--no-browser"]) == 0
    out, err = capsys.readouterr()
    assert out.startswith("faceanim view: http://127.0.0.1:") and err == ""


def test_an_output_group_commits_together_and_nests(tmp_path):
    with output_group():
        with atomic_output(tmp_path / "a.txt") as tmp:
            tmp.write_text("a")
        assert not (tmp_path / "a.txt").exists()  # waits for the group
        with output_group():
            with atomic_output(tmp_path / "b.txt") as tmp:
                tmp.write_text("b")
        assert (tmp_path / "b.txt").read_text() == "b"  # an inner group (a step) is in place when it ends
    assert (tmp_path / "a.txt").read_text() == "a"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.txt"]


def test_a_folder_output_waits_for_its_group_whole_with_what_was_written_into_it(tmp_path):
    from faceanim.atomic import atomic_folder

    with output_group():
        with atomic_folder(tmp_path / "frames") as work:
            with atomic_output(work / "face.png") as tmp:  # written into the hidden folder at once
                tmp.write_bytes(b"png")
            (work / "frame_0.obj").write_text("v 0 0 0")
        assert not (tmp_path / "frames").exists()
    assert sorted(p.name for p in (tmp_path / "frames").iterdir()) == ["face.png", "frame_0.obj"]
    with pytest.raises(KeyboardInterrupt), output_group():
        with atomic_folder(tmp_path / "more") as work:
            (work / "frame_0.obj").write_text("v 0 0 0")
        raise KeyboardInterrupt
    assert sorted(p.name for p in tmp_path.iterdir()) == ["frames"]


@pytest.mark.parametrize("number, status", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_real_faceanim_interrupted_mid_job_leaves_nothing(tmp_path, number, status):
    """``faceanim track`` on a real video, signalled once its track is finished (its hidden temporary
    file exists) and while the overlay video is being drawn: exit 128 + the signal, one line, no
    traceback, and nothing in the folder (no output, no hidden temporary file)."""
    pytest.importorskip("mediapipe", reason="needs faceanim[capture]")
    pytest.importorskip("av", reason="needs faceanim[capture]")
    video = shared("videos", "d0.mp4")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")])}
    job = subprocess.Popen([sys.executable, "-m", "faceanim", "track", str(video), "-o", "t.npz",
                            "--overlay", "o.mp4", "--csv", "c.csv"], cwd=tmp_path, env=env,
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        while not any(p.name.startswith(".t.npz.") for p in tmp_path.iterdir()):
            assert job.poll() is None, job.communicate()
            time.sleep(0.01)
        job.send_signal(number)
        out, err = job.communicate(timeout=120)
    finally:
        if job.poll() is None:
            job.kill()
            job.communicate()
    assert (job.returncode, err, out) == (status, "faceanim: interrupted\n", "")
    assert list(tmp_path.iterdir()) == []


# ---- odd values


@pytest.mark.parametrize("args, message", [
    (["--fps", "0.4", "--frames", "5", "-o", "x.fap"], "--fps must be a number from 1 to 1000, got 0.4"),
    (["--fps", "1e300", "--frames", "5", "-o", "x.glb"], "--fps must be a number from 1 to 1000, got 1e+300"),
    (["--fps", "nan", "--frames", "5", "-o", "x.glb"], "--fps must be a number from 1 to 1000, got nan"),
    (["--fps", "inf", "-o", "x.glb"], "--fps must be a number from 1 to 1000, got inf"),
    (["--frames", "10001", "-o", "x.glb"], "--frames must be a whole number from 3 to 10000, got 10001"),
    (["--frames", "-5", "-o", "x.fap"], "--frames must be a whole number from 3 to 10000, got -5"),
])
def test_express_refuses_odd_frame_counts_and_rates(tmp_path, monkeypatch, capsys, args, message):
    monkeypatch.chdir(tmp_path)
    assert main(["express", "--au", "12:1", *args]) == 2
    assert message in one_error_line(capsys)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("value", ["nan", "inf", "-1", "2.5"])
def test_express_refuses_an_intensity_that_is_not_finite_or_in_range(tmp_path, capsys, value):
    assert main(["express", "--emotion", "joy", "--intensity", value, "-o", str(tmp_path / "x.glb")]) == 2
    assert f"--intensity for joy: intensity {float(value):g} is outside [0, 2]" in one_error_line(capsys)
    assert list(tmp_path.iterdir()) == []


def test_express_fap_says_how_a_fractional_rate_is_written(tmp_path):
    out = tmp_path / "smile.fap"
    with pytest.warns(UserWarning, match=r"--fps 29.97 is written to the .fap as 30"):
        assert main(["express", "--au", "12:1", "--frames", "4", "--fps", "29.97", "-o", str(out)]) == 0
    assert " 4 frames at 30 fps" in pipeline.fap_info(out)


@pytest.mark.parametrize("port", ["70000", "-1"])
def test_view_refuses_a_port_out_of_range(tmp_path, capsys, port):
    write_mesh(tmp_path / "m.glb", grid_mesh())
    assert main(["view", str(tmp_path / "m.glb"), "--port", port, "--no-browser"]) == 2
    assert f"--port must be between 0 and 65535, got {port}" in one_error_line(capsys)
