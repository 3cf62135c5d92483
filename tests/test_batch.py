"""faceanim batch (faceanim.manifest, faceanim.dataset): inputs and manifests, and a small batch on a
local Ray instance with a corrupt file."""

import csv
import json
import re
import sys

import numpy as np
import pytest
from conftest import shared

from faceanim.cli import main
from faceanim.errors import FileFormatError, InputError
from faceanim.manifest import collect_videos, read_manifest
from faceanim.rig.livelink import read_livelink_csv


def test_files_folders_globs_and_manifests(tmp_path):
    for name in ("a.mp4", "b.MOV", "notes.txt"):
        (tmp_path / name).write_text("x")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "c.mp4").write_text("x")
    assert [v.name for v in collect_videos([tmp_path])] == ["a", "b"]  # a folder: its videos, not deeper
    assert [v.name for v in collect_videos([str(tmp_path / "**" / "*.mp4")])] == ["a", "c"]
    assert [v.name for v in collect_videos([tmp_path / "a.mp4", tmp_path / "a.mp4"])] == ["a"]  # once
    (tmp_path / "m.csv").write_text("path,name,neutral,no_filter\na.mp4,first,0:5,yes\nsub/c.mp4,,,\n")
    first, second = read_manifest(tmp_path / "m.csv")
    assert (first.path, first.name, first.neutral, first.smoothing) == (tmp_path / "a.mp4", "first", "0:5", False)
    assert (second.path, second.name, second.neutral, second.smoothing) == (tmp_path / "sub" / "c.mp4", "c", None,
                                                                              True)
    (tmp_path / "m.jsonl").write_text(json.dumps({"path": "a.mp4", "no_filter": True}) + "\n\n"
                                      + json.dumps({"path": "missing.mp4"}) + "\n")
    videos = read_manifest(tmp_path / "m.jsonl")
    assert [v.smoothing for v in videos] == [False, True] and videos[1].path == tmp_path / "missing.mp4"


@pytest.mark.parametrize(("manifest", "text", "message"), [
    ("m.csv", "file,name\na.mp4,x\n", r"m.csv: has no path column \(its header is file, name\)"),
    ("m.csv", "path,fps\na.mp4,3\n", r"m.csv:2: unknown option 'fps'; a manifest's columns are path, name"),
    ("m.csv", "path,name\n,x\n", r"m.csv:2: no path"),
    ("m.csv", "path,no_filter\na.mp4,maybe\n", r"m.csv:2: no_filter must be true or false, got 'maybe'"),
    ("m.jsonl", '{"path": "a.mp4", "speed": 2}\n', r"m.jsonl:1: unknown option 'speed'"),
    ("m.jsonl", '{"name": "a"}\n', r"m.jsonl:1: has no path"),
    ("m.jsonl", "[1, 2]\n", r"m.jsonl:1: each line must be a JSON object"),
    ("m.jsonl", "{oops\n", r"m.jsonl:1: is not JSON"),
])
def test_a_bad_manifest_is_refused_naming_it(tmp_path, manifest, text, message):
    (tmp_path / manifest).write_text(text)
    with pytest.raises(InputError, match=message):
        collect_videos([tmp_path / manifest])


def test_bad_inputs_are_refused_before_any_work(tmp_path):
    (tmp_path / "x").mkdir()
    (tmp_path / "x" / "d0.mp4").write_text("x")
    (tmp_path / "y").mkdir()
    (tmp_path / "y" / "d0.mp4").write_text("x")
    with pytest.raises(InputError, match="would both write outputs named 'd0'; give one a name in a manifest"):
        collect_videos([tmp_path / "x", tmp_path / "y"])
    with pytest.raises(InputError, match="missing.mp4: no such file or folder"):
        collect_videos([tmp_path / "missing.mp4"])
    with pytest.raises(InputError, match=r"nothing\*.mp4: matches no file"):
        collect_videos([str(tmp_path / "nothing*.mp4")])
    (tmp_path / "bin.csv").write_bytes(b"\xff\xfe\x00")
    with pytest.raises(FileFormatError, match="is not a UTF-8 text manifest"):
        collect_videos([tmp_path / "bin.csv"])


@pytest.mark.parametrize(("extra", "message"), [
    (["--do", "encode,blend"], r"--do takes encode, aus, blendshapes, animate, plot \(comma-separated\), got blend"),
    (["--do", "aus,plot"], r"--do plot draws each video's FAPs: ask for encode too \(--do encode,plot\)"),
    (["--address", "ray://127.0.0.1:1"], "--address ray://127.0.0.1:1: no Ray cluster answers there"),
    (["--address", "nowhere"], "--address nowhere: give ray://HOST:PORT, HOST:PORT or auto"),
    (["--workers", "0"], "--workers must be a whole number from 1, got 0"),
    (["-o", "FILE"], "-o .*afile: exists and is not a folder"),
])
def test_bad_arguments_are_one_line_and_write_nothing(tmp_path, capsys, extra, message):
    pytest.importorskip("ray", reason="faceanim batch runs on Ray (the batch extra)")
    (tmp_path / "v.mp4").write_text("x")
    (tmp_path / "afile").write_text("mine")
    out = str(tmp_path / "afile") if "FILE" in extra else str(tmp_path / "out")
    args = ["batch", str(tmp_path / "v.mp4"), "-o", out] + [a for a in extra if a not in ("-o", "FILE")]
    assert main(args) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("faceanim: error: ")
    assert re.search(message, err[0])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "v.mp4"]
    assert (tmp_path / "afile").read_text() == "mine"


def test_a_small_batch_on_local_ray_with_a_corrupt_file(tmp_path, capsys):
    pytest.importorskip("ray", reason="faceanim batch runs on Ray (the batch extra)")
    pytest.importorskip("mediapipe", reason="capture needs faceanim[capture]")
    d0 = shared("videos", "d0.mp4")
    (tmp_path / "broken.mp4").write_bytes(d0.read_bytes()[:2000])  # a cut-off file: not a video FFmpeg reads
    (tmp_path / "blank.png").write_bytes(_blank_png())  # readable, but no face
    manifest = tmp_path / "list.csv"
    manifest.write_text(f"path,name\n{d0},smiles\nbroken.mp4,\nblank.png,\n")
    out = tmp_path / "out"
    steps = "encode,aus,blendshapes,plot"
    assert main(["batch", str(manifest), "-o", str(out), "--do", steps, "--workers", "2"]) == 0
    printed = capsys.readouterr().out
    assert "3 videos: 1 done, 0 skipped (outputs there), 2 failed" in printed
    assert sorted(p.name for p in out.iterdir()) == ["batch_summary.csv", "smiles.fap", "smiles_aus.csv",
                                                     "smiles_curves.png", "smiles_take.csv"]
    assert (out / "smiles_curves.png").read_bytes().startswith(b"\x89PNG")  # the FAPs as faceanim plot draws them
    rows = {r["name"]: r for r in csv.DictReader(open(out / "batch_summary.csv"))}
    smiles = rows["smiles"]
    assert smiles["success"] == "1" and smiles["frames"] == "78" and smiles["tracked"] == "1.0000"
    assert smiles["outputs"] == "smiles.fap smiles_aus.csv smiles_take.csv smiles_curves.png" and smiles["error"] == ""
    assert rows["broken"]["success"] == "0" and "broken.mp4" in rows["broken"]["error"]
    assert rows["blank"]["success"] == "0" and "no face was found" in rows["blank"]["error"]
    assert all("\n" not in r["error"] for r in rows.values())
    # the same outputs as the single command, and a re-run skips what is there
    assert main(["encode", str(d0), "-o", str(tmp_path / "single.fap")]) == 0
    assert (tmp_path / "single.fap").read_text().split("\n", 1)[1] == (out / "smiles.fap").read_text().split("\n", 1)[1]
    # the Live Link take from the shared capture is the one faceanim blendshapes writes
    assert main(["blendshapes", str(d0), "-o", str(tmp_path / "single_take.csv")]) == 0
    single, batch = read_livelink_csv(tmp_path / "single_take.csv"), read_livelink_csv(out / "smiles_take.csv")
    assert len(batch) == 78 and np.array_equal(single.times, batch.times)
    assert np.array_equal(single.weights, batch.weights) and np.array_equal(single.pose, batch.pose)
    assert (tmp_path / "single_take.csv").read_text() == (out / "smiles_take.csv").read_text()
    before = (out / "smiles.fap").stat().st_mtime_ns
    assert main(["batch", str(manifest), "-o", str(out), "--do", steps, "--workers", "1"]) == 0
    assert "3 videos: 0 done, 1 skipped (outputs there), 2 failed" in capsys.readouterr().out
    assert (out / "smiles.fap").stat().st_mtime_ns == before


def _blank_png() -> bytes:
    import io

    from PIL import Image

    buffer = io.BytesIO()
    Image.new("RGB", (64, 64), (120, 120, 120)).save(buffer, format="PNG")
    return buffer.getvalue()


def test_leftover_temporaries_are_removed_and_nothing_else(tmp_path):
    from faceanim.dataset import remove_leftovers
    from faceanim.manifest import Video

    video = Video(tmp_path / "smiles.mp4", "smiles")
    ours = [".smiles.fap.k2x_9abq.fap", ".smiles_take.csv.00000000.csv", ".batch_summary.csv.abcdefgh.csv",
            ".faceanim-probe-zz_1y2x3"]
    theirs = [".smiles.fap.notes", ".smiles.fap.k2x_9abq.fap.bak", ".other.fap.k2x_9abq.fap",
              ".smiles.glb.k2x_9abq.glb", "smiles.fap.k2x_9abq.fap", ".smiles.fap.K2X_9ABQ.fap", ".hidden"]
    for name in ours + theirs:
        (tmp_path / name).write_text("x")
    (tmp_path / ".smiles_aus.csv.k2x_9abq.csv").mkdir()  # a folder by that name: not a file faceanim left
    removed = remove_leftovers(tmp_path, [video], ("encode", "aus", "blendshapes"))
    assert sorted(p.name for p in removed) == sorted(ours)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(theirs + [".smiles_aus.csv.k2x_9abq.csv"])


def test_the_temporaries_faceanim_makes_are_the_leftovers_it_knows(tmp_path):
    """Names made the way faceanim makes them (an output's hidden temporary, a folder probe), not written
    out by hand: a batch stopped mid-write has them removed."""
    from faceanim import atomic
    from faceanim.dataset import remove_leftovers
    from faceanim.manifest import Video
    from faceanim.outputs import probe_path

    made: list = []
    for _ in range(20):
        atomic._make_temporary(made, tmp_path / "smiles.fap", ".fap", folder=False)
        probe_path(tmp_path).write_text("x")
    removed = remove_leftovers(tmp_path, [Video(tmp_path / "smiles.mp4", "smiles")], ("encode",))
    assert len(removed) == 40 and list(tmp_path.iterdir()) == []


def test_progress_over_videos_and_frames(tmp_path):
    import io

    pytest.importorskip("ray", reason="faceanim batch runs on Ray (the batch extra)")
    pytest.importorskip("mediapipe", reason="capture needs faceanim[capture]")
    pytest.importorskip("tqdm", reason="bars are drawn by tqdm")
    from faceanim.dataset import run_batch
    from faceanim.progress import Progress

    d0 = shared("videos", "d0.mp4")
    (tmp_path / "broken.mp4").write_bytes(b"not a video")
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / ".d0.fap.a1b2c3d4.fap").write_text("half a file")  # left by a run stopped mid-write
    shown = io.StringIO()
    result = run_batch([d0, tmp_path / "broken.mp4"], tmp_path / "out", do="encode", workers=2,
                       progress=Progress(shown, bars=True))
    assert [v.status for v in result.videos] == ["done", "failed"]
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["batch_summary.csv", "d0.fap"]
    drawn = shown.getvalue()
    assert "encode on 2 videos: 100%" in drawn and "2/2" in drawn  # the videos' bar, at its end
    assert "frames tracked: 78 frames" in drawn  # every frame of d0 reported by its task
    quiet = io.StringIO()  # off a terminal: one line, no bar
    run_batch([d0], tmp_path / "out", do="encode", workers=1, progress=Progress(quiet))
    assert quiet.getvalue() == "faceanim: encode on 1 videos (1 videos)...\n"


def test_an_interrupted_batch_leaves_no_temporary_file(tmp_path):
    import os
    import signal
    import subprocess
    import sys
    import time

    pytest.importorskip("ray", reason="faceanim batch runs on Ray (the batch extra)")
    pytest.importorskip("mediapipe", reason="capture needs faceanim[capture]")
    d10 = shared("videos", "d10.mp4")
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    batch = subprocess.Popen([sys.executable, "-m", "faceanim", "batch", str(d10), "-o", str(out), "--do",
                              "encode,aus,blendshapes,animate", "--workers", "1"],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while batch.poll() is None and time.monotonic() < deadline:  # until a worker is writing an output
        if any(p.name.startswith(".d10.") for p in out.iterdir()):
            break
        time.sleep(0.02)
    assert batch.poll() is None, batch.communicate()
    assert any(p.name.startswith(".d10.") for p in out.iterdir()), "no output was being written"
    os.kill(batch.pid, signal.SIGINT)
    _, err = batch.communicate(timeout=60)
    assert batch.returncode == 128 + signal.SIGINT, err
    assert err.strip().splitlines()[-1] == "faceanim: interrupted"
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]  # no output, no temporary, the user's file kept


def test_a_local_ray_gets_the_cpus_this_process_may_use_by_default(monkeypatch):
    """Ray is started with as many CPUs as the container's quota allows (faceanim.cpus), not the
    host's core count, unless --workers says otherwise."""
    import types

    from faceanim import dataset

    started = []
    fake = types.SimpleNamespace(init=lambda **kwargs: started.append(kwargs["num_cpus"]))
    monkeypatch.setitem(sys.modules, "ray", fake)
    monkeypatch.setenv("RAY_USAGE_STATS_ENABLED", "0")  # what _start_ray sets, undone after the test
    monkeypatch.setattr(dataset, "usable_cpus", lambda: 3)
    assert dataset._start_ray(None, None) is fake and dataset._start_ray(5, None) is fake
    assert started == [3, 5]
