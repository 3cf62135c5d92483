"""`faceanim view`: the server answers only its own routes, bad inputs are refused before it starts, and,
in a real headless Chromium (skipped where absent), the page plays the face, keeps the video in step and
mixes action units with sliders. Screenshots go to a temporary folder that the test output names."""

import http.client
import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from conftest import shared
from test_gltf import animated_grid

from faceanim import pipeline, portrait
from faceanim.cli import main
from faceanim.errors import InputError
from faceanim.export import MorphSet, morphs_from_animation, write_glb
from faceanim.mpeg4.fapfile import read_fap
from faceanim.mpeg4.fapstream import FapStream
from faceanim.retarget.decode import animate_faps
from faceanim.viewer import ViewerFiles, ViewerServer, fap_curves

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def grid_glb(tmp_path):
    animation = animated_grid(frames=40)
    path = tmp_path / "grid.glb"
    write_glb(path, animation.mesh, morphs_from_animation(animation))
    return path


def raw_get(port: int, target: str) -> int:
    """Status of a GET sent exactly as written (no client-side normalisation of the path)."""
    connection = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
    connection.putrequest("GET", target, skip_host=True, skip_accept_encoding=True)
    connection.putheader("Host", f"127.0.0.1:{port}")
    connection.endheaders()
    status = connection.getresponse().status
    connection.close()
    return status


def test_server_serves_its_routes_and_refuses_everything_else(grid_glb):
    with ViewerServer(ViewerFiles(grid_glb), port=0).start() as server:
        assert server.url.startswith("http://127.0.0.1:")
        assert server.host == "127.0.0.1"  # loopback only
        for ok in ("/", "/config.json", "/files/model.glb", "/assets/viewer.js", "/assets/three/three.module.min.js",
                   "/assets/three/addons/loaders/GLTFLoader.js", "/?t=1"):
            assert raw_get(server.port, ok) == 200, ok
        for bad in ("/../pyproject.toml", "/%2e%2e/pyproject.toml", "/assets/../../pyproject.toml",
                    "/assets/%2e%2e/%2e%2e/pyproject.toml", "//etc/passwd", "/etc/passwd", str(grid_glb),
                    "/files/../grid.glb", "/files/grid.glb", "/assets/", "/assets/three", "/%2Fetc%2Fpasswd",
                    "http://127.0.0.1/../pyproject.toml"):
            assert raw_get(server.port, bad) == 404, bad
        config = json.loads(http_body(server.port, "/config.json"))
        assert config["model"] == "/files/model.glb" and config["video"] is None
        assert http_body(server.port, "/files/model.glb") == grid_glb.read_bytes()


def http_body(port: int, target: str) -> bytes:
    connection = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
    connection.request("GET", target)
    body = connection.getresponse().read()
    connection.close()
    return body


def test_video_is_served_in_ranges_for_seeking(grid_glb):
    video = shared("videos", "d0.mp4")
    with ViewerServer(ViewerFiles(grid_glb, video=video), port=0).start() as server:
        connection = http.client.HTTPConnection("127.0.0.1", server.port, timeout=10)
        connection.request("GET", "/files/source.mp4", headers={"Range": "bytes=100-199"})
        response = connection.getresponse()
        assert response.status == 206 and response.read() == video.read_bytes()[100:200]
        assert response.getheader("Content-Range") == f"bytes 100-199/{video.stat().st_size}"
        connection.request("GET", "/files/source.mp4", headers={"Range": "bytes=-50"})  # the last 50 bytes
        assert connection.getresponse().read() == video.read_bytes()[-50:]
        connection.request("GET", "/files/source.mp4", headers={"Range": f"bytes={10 ** 9}-"})
        response = connection.getresponse()
        response.read()
        assert response.status == 416


def test_view_refuses_bad_inputs_before_serving(tmp_path, grid_glb, capsys):
    (tmp_path / "broken.glb").write_bytes(b"not a glb at all, just text")
    (tmp_path / "clip.mp4").write_bytes(b"\x00\x01 not a video")
    cases = [
        ([str(tmp_path / "missing.glb")], "missing.glb: no such file"),
        ([str(tmp_path / "broken.glb")], "broken.glb: is not a binary glTF (.glb) file"),
        ([str(grid_glb), "--video", str(tmp_path / "clip.mp4")], "clip.mp4: not a video FFmpeg can read"),
        ([str(grid_glb), "--fap", str(tmp_path / "none.fap")], "none.fap"),
        ([str(grid_glb), "--port", "70000"], "--port must be between 0 and 65535"),
    ]
    for args, message in cases:
        assert main(["view", *args, "--no-browser"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and message in err[0], err
    with ViewerServer(ViewerFiles(grid_glb), port=0) as busy:
        with pytest.raises(InputError, match=rf"port {busy.port} is in use; try --port \d+"):
            pipeline.view(grid_glb, port=busy.port)


def test_fap_curves_carry_the_active_faps():
    stream = read_fap(shared("xface", "Faps", "joy.fap"))
    curves = fap_curves(stream)
    active = [j for j in range(2, 68) if stream.mask[:, j].any()]  # written out, not curve_columns
    assert len(curves["names"]) == len(active) and curves["fps"] == stream.fps
    assert curves["values"][0] == pytest.approx(np.where(stream.mask[:, active[0]], stream.values[:, active[0]], 0))


# ---- in a real browser


def browser_check(url: str, out: Path, unit: str | None = None) -> dict:
    script = ROOT / "tools" / "browser_check.js"
    if shutil.which("chromium") is None or shutil.which("node") is None:
        pytest.skip("needs Debian's chromium and Node.js (scripts/setup.sh installs them)")
    if not (ROOT / "tools" / "node" / "node_modules" / "playwright-core").exists():
        pytest.skip("needs playwright-core in tools/node (scripts/setup.sh installs it)")
    run = subprocess.run(["node", str(script), url, str(out)] + ([unit] if unit else []), capture_output=True,
                         text=True, timeout=240)
    assert run.returncode == 0, run.stderr[-3000:]
    print(f"screenshots in {out}")
    return json.loads((out / "report.json").read_text())


def face_difference(a: Path, b: Path) -> float:
    from PIL import Image

    return float(np.abs(np.asarray(Image.open(a), float) - np.asarray(Image.open(b), float)).mean())


def test_page_plays_the_face_beside_its_video_without_errors(tmp_path_factory):
    out = tmp_path_factory.mktemp("viewer_screenshots")
    demo = shared("videos", "d0.mp4")
    target = portrait.avatar_target()
    stream = read_fap(shared("xface", "Faps", "joy.fap"))
    glb = out / "joy.glb"
    write_glb(glb, target.mesh, morphs_from_animation(animate_faps(stream, target)))
    fap = shared("xface", "Faps", "joy.fap")
    with pipeline.view(glb, video=demo, fap=fap, port=0).start() as server:
        report = browser_check(server.url, out)
    assert report["console_errors"] == [] and report["page_errors"] == []
    assert report["time_b"] > report["time_a"]  # the clock runs
    assert face_difference(out / "playing_a.png", out / "playing_b.png") > 0.1  # and the face moves (a still face: 0)
    assert report["has_video"] and report["has_curves"] and not report["editor"]
    video = report["video"]
    assert not video["error"] and video["ready"] >= 2 and abs(video["time"] - video["face_time"]) < 0.05


def test_au_sliders_change_the_face_and_save_a_recipe_and_fap(tmp_path_factory):
    out = tmp_path_factory.mktemp("viewer_sliders")
    target = portrait.avatar_target()
    table = {"AU12": {12: 300, 13: 300, 6: 80, 7: 80}, "AU26": {3: 500}}  # lip corner puller, jaw drop
    shapes = []
    for faps in table.values():
        values, mask = np.zeros((1, 68)), np.zeros((1, 68), bool)
        for fap, value in faps.items():
            values[0, fap - 1], mask[0, fap - 1] = value, True
        shapes.append(animate_faps(FapStream(values, mask, 25.0), target).positions[0] - target.mesh.vertices)
    glb = out / "units.glb"
    write_glb(glb, target.mesh, MorphSet(np.stack(shapes), tuple(table)),
              extras={"au_faps": {name: {str(k): v for k, v in faps.items()} for name, faps in table.items()}})
    with pipeline.view(glb, port=0).start() as server:
        report = browser_check(server.url, out, unit="AU12")
    assert report["editor"] and report["console_errors"] == [] and report["page_errors"] == []
    assert face_difference(out / "before_unit.png", out / "unit.png") > 0.2
    assert report["recipe"] == "12:1.00"
    (out / "mix.fap").write_text(report["fap"])
    mixed = read_fap(out / "mix.fap")
    assert mixed.values[0, 11] == 300 and mixed.values[0, 5] == 80 and not mixed.mask[0, 2]
