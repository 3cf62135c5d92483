"""The Python API (faceanim.track, encode, ...): light to import, the commands' options, runnable examples."""

import inspect
import pkgutil
import runpy
import subprocess
import sys

import pytest
from conftest import ROOT, shared

import faceanim
from faceanim.cli import _parser

# The command's option (argparse dest) -> the job's keyword, where the two names differ.
RENAMED = {"no_filter": "smoothing", "target": "target_mesh", "region": "regions"}


def test_import_faceanim_stays_light():
    code = ("import sys, faceanim; heavy = [m for m in ('faceanim.pipeline', 'mediapipe', 'av', 'ray', 'matplotlib', "
            "'moderngl') if m in sys.modules]; print(heavy)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_every_job_is_public_and_imports_on_first_use():
    assert set(faceanim.JOBS) <= set(faceanim.__all__) and set(faceanim.JOBS) <= set(dir(faceanim))
    for name in faceanim.JOBS:
        assert callable(getattr(faceanim, name)), name
    with pytest.raises(AttributeError, match="has no attribute 'nothing'"):
        faceanim.nothing  # noqa: B018


def test_no_job_is_shadowed_by_a_module_of_the_same_name():
    modules = {m.name for m in pkgutil.iter_modules(faceanim.__path__)}
    assert not modules & set(faceanim.JOBS)  # ``import faceanim.x`` would replace the job faceanim.x


@pytest.mark.parametrize("command", ["track", "encode", "decode", "animate", "express", "aus", "transfer", "avatar",
                                     "view"])
def test_each_job_takes_its_commands_options_as_keywords(command):
    sub = next(a for a in _parser()._actions if a.dest == "command").choices[command]
    options = {RENAMED.get(a.dest, a.dest) for a in sub._actions
               if a.option_strings and a.dest not in ("help", "output")}  # -o is the second positional argument
    keywords = {name for name, p in inspect.signature(getattr(faceanim, command)).parameters.items()
                if p.kind is p.KEYWORD_ONLY}
    assert options - {"no_browser"} <= keywords, options - keywords  # --no-browser belongs to the command


def test_capture_example_runs(tmp_path, monkeypatch):
    video = shared("videos", "d0.mp4")
    monkeypatch.syspath_prepend(str(ROOT / "examples"))
    example = runpy.run_path(str(ROOT / "examples" / "capture.py"))
    made = example["main"](video, tmp_path)
    assert len(made["track"]) == 78 and len(made["stream"]) == 78
    assert {p.name for p in tmp_path.iterdir()} == {"track.npz", "landmarks.csv", "faps.fap", "aus.csv", "aus.png"}


def test_expressions_example_runs(tmp_path):
    pytest.importorskip("skimage", reason="the default face is the avatar of scikit-image's astronaut (capture extra)")
    example = runpy.run_path(str(ROOT / "examples" / "expressions.py"))
    made = example["main"](tmp_path)
    assert made["recipe"] == {"6": 0.8, "12": 1.0} and len(made["animation"]) == 20
    assert {p.name for p in tmp_path.iterdir()} == {"smile.fap", "smile.glb", "smile_faps.csv"}


@pytest.mark.parametrize("workers", [0, 1.5, True])
def test_a_bad_number_of_deforming_processes_is_refused_before_any_work(tmp_path, workers):
    with pytest.raises(faceanim.InputError, match="workers must be a whole number"):
        faceanim.decode(tmp_path / "absent.fap", tmp_path / "out.glb", workers=workers)
    assert list(tmp_path.iterdir()) == []
