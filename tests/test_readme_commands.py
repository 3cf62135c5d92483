"""Every ``faceanim`` command in README.md runs as written, in the README's order.

The commands of the README's ```bash blocks run one after another in one working folder (later ones
read what earlier ones wrote, like ``face.glb``), each in its own process, as a person would type
them from the checkout: ``../shared/data`` is the shared data folder, ``examples/...`` the checkout's.
Each must exit 0 and leave every output it names (``-o``, ``--preview``, ``--fap``...) non-empty.
``faceanim view`` serves until stopped: it runs with ``--no-browser --port 0``, must answer one GET,
and is then stopped. Marked ``slow`` (a few minutes), and still part of the default run.
"""

import re
import select
import shlex
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest
from conftest import ROOT, SHARED

pytestmark = pytest.mark.slow

README = ROOT / "README.md"
DATA = "../shared/data"
OUTPUT_OPTIONS = ("-o", "--output", "--preview", "--fap", "--overlay", "--csv", "--obj-sequence")
DEMO_OUTPUTS = ("report.html", "demo.glb", "preview.mp4", "demo.fap", "performance.mp4")
COMMAND_SECONDS = 600  # the longest any one command may run (the slowest takes about 30 s on 2 cores)
SERVE_SECONDS = 60  # for faceanim view to print its address, and then to answer
# README commands known to fail, as written in the README, with why (a strict xfail: once a command
# passes, its entry must go). Empty since the part labels travel in the .glb (express --target face.glb).
KNOWN_FAILURES: dict[str, str] = {}


def readme_commands(text: str) -> list[list[str]]:
    """The ``faceanim`` commands of the ```bash blocks in ``text``, in order, as argument lists:
    comments dropped, continued lines joined, ``setup && faceanim demo`` giving ``faceanim demo``."""
    commands = []
    for block in re.findall(r"^```bash\n(.*?)^```", text, flags=re.M | re.S):
        for line in block.replace("\\\n", " ").splitlines():
            segment = []
            for word in [*shlex.split(line, comments=True), "&&"]:
                if word in ("&&", "||", ";"):
                    if segment[:1] == ["faceanim"]:
                        commands.append(segment)
                    segment = []
                else:
                    segment.append(word)
    return commands


COMMANDS = readme_commands(README.read_text())


def outputs(words: list[str]) -> list[str]:
    """The files (or folders) a command says it writes."""
    if words[1] == "view":
        return []
    named = [value for option, value in zip(words, words[1:], strict=False) if option in OUTPUT_OPTIONS]
    if words[1] == "demo":
        folder = named[0] if named else "faceanim-demo"
        return [f"{folder}/{name}" for name in DEMO_OUTPUTS]
    return named


def test_readme_commands_are_found():
    kinds = [words[1] for words in COMMANDS]
    assert kinds[0] == "demo"  # the main job comes first
    assert {"track", "encode", "animate", "decode", "express", "view", "avatar"} <= set(kinds)
    assert all("#" not in word for words in COMMANDS for word in words)
    assert set(KNOWN_FAILURES) <= {shlex.join(words) for words in COMMANDS}  # no stale entries


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    """The one working folder the commands share, and the outputs of commands that were skipped."""
    return {"folder": tmp_path_factory.mktemp("readme"), "missing": {}}


def localised(words: list[str], missing: dict) -> list[str]:
    """``words`` with the README's relative paths made real, or skip saying what is missing."""
    out = []
    for word in words:
        if word.startswith(DATA):
            path = SHARED / word[len(DATA):].lstrip("/")
            if not path.exists():
                pytest.skip(f"needs {path} (the shared data folder beside the checkout)")
            word = str(path)
        elif "/" in word and not word.startswith("-") and (ROOT / word).exists():
            word = str(ROOT / word)  # a file of the checkout, like examples/ict_landmark_pairs.json
        elif word in missing:
            pytest.skip(f"needs {word}, which `{missing[word]}` would have written")
        out.append(word)
    return out


def serve_once(argv: list[str], folder: Path) -> None:
    """Run ``faceanim view``, GET its page once, and stop it."""
    if "--no-browser" not in argv:
        argv = [*argv, "--no-browser"]
    if "--port" not in argv:
        argv = [*argv, "--port", "0"]
    with open(folder / "view.stderr", "w") as errors:
        server = subprocess.Popen(argv, cwd=folder, stdout=subprocess.PIPE, stderr=errors, text=True)
    try:
        deadline, line = time.monotonic() + SERVE_SECONDS, ""
        while "http://" not in line:
            ready, _, _ = select.select([server.stdout], [], [], max(0.0, deadline - time.monotonic()))
            if not ready:
                pytest.fail(f"faceanim view printed no address within {SERVE_SECONDS} s")
            line = server.stdout.readline()
            if not line:
                pytest.fail(f"faceanim view exited with {server.wait()} before serving: "
                            f"{(folder / 'view.stderr').read_text()[-2000:]}")
        url = re.search(r"http://127\.0\.0\.1:\d+/", line).group(0)
        with urllib.request.urlopen(url, timeout=SERVE_SECONDS) as response:
            assert response.status == 200 and response.read()
    finally:
        server.terminate()
        try:
            server.wait(timeout=10)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait()


@pytest.mark.parametrize("words", COMMANDS, ids=[f"{i:02d}-{words[1]}" for i, words in enumerate(COMMANDS)])
def test_readme_command_runs(words, session, request):
    written = shlex.join(words)
    if written in KNOWN_FAILURES:
        request.applymarker(pytest.mark.xfail(reason=KNOWN_FAILURES[written], strict=True))
    folder = session["folder"]
    try:
        argv = [sys.executable, "-m", "faceanim", *localised(words[1:], session["missing"])]
    except pytest.skip.Exception:
        session["missing"].update(dict.fromkeys(outputs(words), written))
        raise
    if words[1] == "view":
        serve_once(argv, folder)
        return
    done = subprocess.run(argv, cwd=folder, capture_output=True, text=True, timeout=COMMAND_SECONDS)
    assert done.returncode == 0, f"{written}\nexited {done.returncode}:\n{done.stderr[-3000:]}"
    for name in outputs(words):
        path = folder / name
        assert path.exists(), f"{written} did not write {name}"
        size = sum(f.stat().st_size for f in path.iterdir()) if path.is_dir() else path.stat().st_size
        assert size > 0, f"{written} wrote an empty {name}"
