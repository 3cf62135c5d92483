"""`faceanim view`: the server answers only its own routes, bad inputs are refused before it starts, and,
in a real headless Chromium (skipped where absent), the page plays the face, keeps the video in step and
mixes action units with sliders; at 1280 x 800 the face and its video both lie inside the window, each
group of FAP curves has its own chart with tick labels, a unit and its "N most active of M" note, a still
model shows no play controls and its AU sliders start from its recipe and adjust it. Screenshots go to a
temporary folder that the test output names.

The server's HTTP (issue 20): the Range parser is checked with Hypothesis over 10,000 headers (every one
gets a range inside the body, a 416 or the whole body; nothing else, no exception), and a running server
is asked for known answers: 206/416/200 with their Content-Length and Content-Range, the Host check, a
bounded number of workers, a half-open connection dropped after its timeout, and files served as they
were opened, whatever their paths become."""

import http.client
import json
import os
import shutil
import socket
import subprocess
import threading
from pathlib import Path

import numpy as np
import pytest
from conftest import shared
from hypothesis import example, given, settings
from hypothesis import strategies as st
from test_gltf import animated_grid

from faceanim import pipeline, portrait
from faceanim.cli import main
from faceanim.errors import InputError
from faceanim.export import MorphSet, morphs_from_animation, write_glb
from faceanim.export.plots import GROUPS, MOST_ACTIVE, curve_panels
from faceanim.mpeg4 import fap_table
from faceanim.mpeg4.fapfile import read_fap
from faceanim.mpeg4.fapstream import FapStream
from faceanim.retarget.decode import animate_faps
from faceanim.viewer import ViewerFiles, ViewerServer, fap_curves
from faceanim.viewer.server import parse_range

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


# ---- the Range parser, by property and against RFC 9110 read case by case

DIGITS = st.one_of(st.integers(0, 2100).map(str), st.sampled_from(["", "00", "007", str(2**64), "9" * 5000,
                                                                     "0" * 5000 + "1"]))
WELL_FORMED = st.builds(lambda unit, first, last, end: f"{unit}={first}-{last}{end}",  # mostly parse, many sizes
                        st.sampled_from(["bytes", "BYTES", "Bytes"]), DIGITS, DIGITS, st.sampled_from(["", ",", " , "]))
NUMBERISH = ("", "0", "5", "99", "100", "999", "1000", "1001", "0100", str(2**64), "9" * 5000, "+1", "-1", " 1", "1_0",
             "1.5", "0x10", "1e3", "\u0661", "\u00b2", "\uff11", "inf")
NEAR_MISSES = st.builds(  # the grammar's pieces, right and wrong, put together
    lambda unit, equals, specs, comma: unit + equals + comma.join(a + dash + b for a, dash, b in specs),
    st.sampled_from(["bytes", "bytes", "BYTES", "byte", "bytes ", " bytes", "items", "", "byte\u017f", "bytes\x00"]),
    st.sampled_from(["=", "=", "", "==", " = "]),
    st.lists(st.tuples(st.sampled_from(NUMBERISH), st.sampled_from(["-", "-", "", "--", " - ", "\u2212"]),
                       st.sampled_from(NUMBERISH)), max_size=3),
    st.sampled_from([",", ", ", " ,", ",,", ";", ", ,"]))
HEADERS = st.one_of(st.text(), st.text(alphabet="bytesBYTES=0123456789-, \t;\u2212"), NEAR_MISSES, WELL_FORMED)
SIZES = st.one_of(st.integers(0, 2100), st.integers(0, 2**64))


@settings(max_examples=10_000, deadline=None)
@given(header=HEADERS, size=SIZES)
def test_every_range_header_gets_a_range_in_the_body_a_416_or_the_whole_body(header, size):
    answer = parse_range(header, size)
    if answer is None or answer == "unsatisfiable":
        return
    first, last = answer
    assert type(first) is int and type(last) is int and 0 <= first <= last < size


def rfc_9110(first: int | None, last: int | None, size: int):
    """The answer to ``bytes=first-last`` (either may be absent) from RFC 9110 14.1.2 and 15.5.17, one sentence
    at a time: ``None`` for the whole body (a suffix of an empty body), "unsatisfiable" for a 416."""
    if first is None:  # suffix-range: the last ``last`` bytes, all of them if the body is shorter
        if last == 0:
            return "unsatisfiable"  # "a suffix-range with a non-zero suffix-length" is what can be satisfied
        return None if size == 0 else (max(0, size - last), size - 1)
    if first >= size:
        return "unsatisfiable"  # "a first-pos that is less than the current length" is what can be satisfied
    if last is None:
        return first, size - 1
    if last < first:
        return "unsatisfiable"  # invalid; the server may ignore or reject it: this one rejects
    return first, min(last, size - 1)  # a last-pos past the end means the end


POSITIONS = st.one_of(st.none(), st.integers(0, 2100), st.integers(0, 10**40))


@settings(max_examples=2_000, deadline=None)
@example(first=None, last=1, size=0, zeros="", unit="bytes", pad="")  # found by Hypothesis: was 416, not the body
@given(first=POSITIONS, last=POSITIONS, size=SIZES, zeros=st.sampled_from(["", "0", "000"]),
       unit=st.sampled_from(["bytes", "BYTES", "bYtEs"]), pad=st.sampled_from(["", " ", "\t ", ", ", " ,,"]))
def test_well_formed_single_ranges_are_answered_as_rfc_9110_says(first, last, size, zeros, unit, pad):
    if first is None and last is None:
        return  # "bytes=-" is not a range: see the next test
    text = "-".join("" if n is None else zeros + str(n) for n in (first, last))
    header = f"{unit}={pad.strip(', ')}{text}{pad}"  # white space before; after, also empty list elements
    assert parse_range(header, size) == rfc_9110(first, last, size), header


@pytest.mark.parametrize("header", ["bytes=-", "bytes=", "bytes", "bytes=1-2-3", "bytes=+5-", "bytes=5", "bytes=a-b",
                                    "bytes=0-1,5-6", "bytes=0-1,x", "bytes=1 - 2", "bytes = 0-1", "bytes=\u0661-",
                                    "items=0-1", "=0-1", "bytes=0-1;", "", "byte\u017f=0-1"])
def test_headers_outside_the_grammar_or_with_several_ranges_are_ignored(header):
    assert parse_range(header, 1000) is None


def test_parse_range_refuses_a_size_that_is_no_byte_count():
    for size in (-1, 1.5, True, "10"):
        with pytest.raises(ValueError, match=r"size must be a byte count \(an int >= 0\), got"):
            parse_range("bytes=0-1", size)


# ---- the server's answers, through a real running server

BODY = np.random.default_rng(0).bytes(1000)  # a stand-in video: the server does not look inside


def ask(port: int, target: str = "/files/source.mp4", *, method: str = "GET", headers: dict | None = None,
        hosts: tuple | None = None):
    """(status, headers, body) of one request sent as written; ``hosts``: the Host headers (default this one)."""
    connection = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
    connection.putrequest(method, target, skip_host=True, skip_accept_encoding=True)
    for host in (f"127.0.0.1:{port}",) if hosts is None else hosts:
        connection.putheader("Host", host)
    for name, value in (headers or {}).items():
        connection.putheader(name, value)
    connection.endheaders()
    response = connection.getresponse()
    body = response.read()
    connection.close()
    return response.status, response.headers, body


@pytest.fixture
def served(tmp_path, grid_glb):
    video = tmp_path / "clip.mp4"
    video.write_bytes(BODY)
    with ViewerServer(ViewerFiles(grid_glb, video=video), port=0).start() as server:
        yield server


@pytest.mark.parametrize(("header", "status", "content_range", "part"), [
    (None, 200, None, slice(None)),
    ("bytes=100-199", 206, "bytes 100-199/1000", slice(100, 200)),
    ("bytes=100-", 206, "bytes 100-999/1000", slice(100, None)),
    ("bytes=-500", 206, "bytes 500-999/1000", slice(500, None)),
    ("bytes=-5000", 206, "bytes 0-999/1000", slice(None)),
    ("bytes=900-5000", 206, "bytes 900-999/1000", slice(900, None)),
    ("bytes=999-999", 206, "bytes 999-999/1000", slice(999, None)),
    ("Bytes=0-0, ", 206, "bytes 0-0/1000", slice(0, 1)),
    (f"bytes=0-{'9' * 5000}", 206, "bytes 0-999/1000", slice(None)),
    ("bytes=100-50", 416, "bytes */1000", slice(0)),
    ("bytes=1000-", 416, "bytes */1000", slice(0)),
    ("bytes=-0", 416, "bytes */1000", slice(0)),
    (f"bytes={'9' * 5000}-", 416, "bytes */1000", slice(0)),
    ("bytes=abc", 200, None, slice(None)),
    ("bytes=1-2-3", 200, None, slice(None)),
    ("bytes=0-1,5-6", 200, None, slice(None)),  # several ranges: the whole body
    ("items=0-1", 200, None, slice(None)),
], ids=lambda value: value[:20] if isinstance(value, str) else None)
def test_video_ranges_are_answered_with_206_416_or_the_whole_body(served, capfd, header, status, content_range,
                                                                   part):
    got, headers, body = ask(served.port, headers={"Range": header} if header else None)
    assert (got, headers["Content-Range"], body) == (status, content_range, BODY[part])
    assert headers["Content-Length"] == str(len(body))
    assert capfd.readouterr().err == ""  # no traceback on the server's side


def test_ranges_apply_to_every_route_and_only_to_a_plain_get(served, grid_glb):
    assert ask(served.port, "/files/model.glb", headers={"Range": "bytes=0-3"})[::2] == (206, b"glTF")
    config = ask(served.port, "/config.json")[2]
    status, headers, body = ask(served.port, "/config.json", headers={"Range": "bytes=0-0"})
    assert (status, headers["Content-Range"], body) == (206, f"bytes 0-0/{len(config)}", b"{")
    status, headers, body = ask(served.port, method="HEAD", headers={"Range": "bytes=0-9"})  # ranges are GET's
    assert (status, headers["Content-Length"], headers["Content-Range"], body) == (200, "1000", None, b"")
    status, headers, body = ask(served.port, headers={"Range": "bytes=0-9", "If-Range": '"an-etag"'})
    assert (status, body) == (200, BODY)  # no validator is ever sent, so no If-Range matches: the whole body


def test_only_requests_addressed_to_a_loopback_name_are_answered(served, grid_glb):
    port, model = served.port, grid_glb.read_bytes()
    for host in (f"127.0.0.1:{port}", f"localhost:{port}", f"LocalHost:{port}", "127.0.0.1", "localhost"):
        assert ask(port, "/files/model.glb", hosts=(host,))[::2] == (200, model), host
    for host in ("evil.example", f"evil.example:{port}", f"127.0.0.1:{port + 1}", f"[::1]:{port}", "",
                 f"127.0.0.1:{port}.evil.example", f"localhost:{port}@evil.example", "127.0.0.1.nip.io"):
        status, _, body = ask(port, "/files/model.glb", hosts=(host,))
        assert status == 421 and model not in body, host
    assert ask(port, "http://evil.example/files/model.glb")[0] == 421  # absolute form names a host too
    assert ask(port, f"http://localhost:{port}/files/model.glb")[0] == 200
    assert ask(port, "/files/model.glb", hosts=())[0] == 400  # no Host at all
    assert ask(port, "/files/model.glb", hosts=(f"127.0.0.1:{port}", "evil.example"))[0] == 400


def test_connections_beyond_the_workers_are_told_503_instead_of_holding_a_thread(grid_glb):
    with ViewerServer(ViewerFiles(grid_glb), port=0, workers=4, timeout=60).start() as server:
        before = threading.active_count()
        idle = [socket.create_connection(("127.0.0.1", server.port), timeout=30) for _ in range(50)]
        try:
            # accepted in order: the first four hold the workers, each later one is answered and closed
            assert all(s.recv(200).startswith(b"HTTP/1.0 503 Service Unavailable\r\n") for s in idle[4:])
            assert threading.active_count() - before <= 4
        finally:
            for s in idle:
                s.close()


def test_a_half_open_connection_is_dropped_after_its_timeout_and_frees_its_worker(grid_glb):
    with ViewerServer(ViewerFiles(grid_glb), port=0, workers=1, timeout=1).start() as server:
        stalled = socket.create_connection(("127.0.0.1", server.port), timeout=30)
        stalled.sendall(b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n")  # the headers never end
        with socket.create_connection(("127.0.0.1", server.port), timeout=30) as other:
            assert other.recv(200).startswith(b"HTTP/1.0 503 ")  # the one worker waits on the stalled request
        assert stalled.recv(200) == b""  # until the server gives up on it, without an answer
        stalled.close()
        assert raw_get(server.port, "/") == 200  # and the worker serves again


def test_files_are_served_as_opened_whatever_their_paths_become(tmp_path, grid_glb):
    real, secret = tmp_path / "real.mp4", tmp_path / "secret.mp4"
    real.write_bytes(BODY)
    secret.write_bytes(b"not for the viewer " * 100)
    link = tmp_path / "clip.mp4"
    link.symlink_to(real)
    model = tmp_path / "model.glb"
    shutil.copy(grid_glb, model)
    with ViewerServer(ViewerFiles(model, video=link), port=0).start() as server:
        swapped = tmp_path / "swapped"
        swapped.symlink_to(secret)
        os.replace(swapped, link)  # the symlink now points elsewhere
        model.unlink()
        model.symlink_to(secret)  # the model's path too
        real.unlink()  # and the file first opened has no name left
        assert ask(server.port)[::2] == (200, BODY)
        assert ask(server.port, headers={"Range": "bytes=10-19"})[::2] == (206, BODY[10:20])
        assert ask(server.port, "/files/model.glb")[::2] == (200, grid_glb.read_bytes())


def open_descriptors() -> int:
    if not Path("/proc/self/fd").is_dir():
        pytest.skip("counts open descriptors in /proc/self/fd (Linux)")
    return len(os.listdir("/proc/self/fd"))


def test_only_regular_files_are_served_and_every_descriptor_is_closed_again(tmp_path, grid_glb):
    fifo = tmp_path / "pipe.mp4"
    os.mkfifo(fifo)  # opening it to read would wait for a writer: refused without waiting
    before = open_descriptors()
    for video, message in ((tmp_path, "is not a regular file"), (fifo, "is not a regular file"),
                           (tmp_path / "gone.mp4", r"cannot be opened \(No such file or directory\)")):
        with pytest.raises(InputError, match=rf"{video}: {message}"):
            ViewerServer(ViewerFiles(grid_glb, video=video), port=0)
    with ViewerServer(ViewerFiles(grid_glb, video=grid_glb), port=0).start() as server:
        assert raw_get(server.port, "/") == 200
        with pytest.raises(InputError, match="is in use"):  # the files it opened are closed again
            ViewerServer(ViewerFiles(grid_glb, video=grid_glb), port=server.port)
    assert open_descriptors() == before
    with pytest.raises(ValueError, match="timeout must be a positive number of seconds, got 0"):
        ViewerServer(ViewerFiles(grid_glb), timeout=0)
    with pytest.raises(ValueError, match="workers must be an int >= 1, got 0"):
        ViewerServer(ViewerFiles(grid_glb), workers=0)


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


def test_fap_curves_are_grouped_as_the_plot_groups_them_in_fapu_and_degrees():
    path = shared("xface", "Faps", "joy.fap")
    stream = read_fap(path)
    curves = fap_curves(stream, name=path.name)
    assert curves["title"] == "FAP curves of joy.fap" and curves["fps"] == stream.fps
    assert curves["times"] == pytest.approx(np.arange(len(stream)) / stream.fps)
    groups = curves["groups"]
    assert [g["name"] for g in groups] == [p.name for p in curve_panels(path)[2]]  # the plot's panels, in order
    assert [g["name"] for g in groups] == sorted((g["name"] for g in groups), key=GROUPS.index)
    table = fap_table()
    by_name = {c["label"].split(" (")[0]: (g, c) for g in groups for c in g["curves"]}
    active = [j for j in range(2, 68) if stream.mask[:, j].any()]  # written out, not curve_columns
    assert sorted(by_name) == sorted(table.names[j] for j in active)  # every active FAP once
    for j in active:
        group, curve = by_name[table.names[j]]
        raw = np.where(stream.mask[:, j], stream.values[:, j], np.nan)
        want = np.degrees(raw * 1e-5) if table.units[j] == "AU" else raw / 1024  # FAP angle units: 1e-5 rad
        got = np.array([np.nan if v is None else v for v in curve["values"]])
        np.testing.assert_allclose(got, want, atol=6e-5)  # rounded to 4 decimals, gaps kept as null
        assert group["unit"] == "degrees" if table.units[j] == "AU" else f"{table.units[j]}0" in group["unit"]
    assert by_name["open_jaw"][0]["name"] == "jaw" and by_name["yaw_l_eyeball"][0]["name"] == "eyes"
    for group in groups:
        count = len(group["curves"])
        assert [c["named"] for c in group["curves"]] == [i < MOST_ACTIVE for i in range(count)]
        spans = [np.ptp([v for v in c["values"] if v is not None]) for c in group["curves"]]
        assert spans == sorted(spans, reverse=True)  # most active first
        assert group["note"] == (f"{MOST_ACTIVE} most active of {count}" if count > MOST_ACTIVE else f"{count} curves")
    assert any("most active of" in g["note"] for g in groups)  # joy moves 22 lip FAPs
    json.dumps(curves, allow_nan=False)  # plain JSON: no NaN


# ---- in a real browser


def browser_check(url: str, out: Path, unit: str | None = None, *, script: str = "browser_check.js") -> dict:
    """Run ``tools/<script>`` on the page at ``url`` (it writes screenshots and report.json into ``out``)."""
    if shutil.which("chromium") is None or shutil.which("node") is None:
        pytest.skip("needs Debian's chromium and Node.js (scripts/setup.sh installs them)")
    if not (ROOT / "tools" / "node" / "node_modules" / "playwright-core").exists():
        pytest.skip("needs playwright-core in tools/node (scripts/setup.sh installs it)")
    run = subprocess.run(["node", str(ROOT / "tools" / script), url, str(out)] + ([unit] if unit else []),
                         capture_output=True, text=True, timeout=240)
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
    # And the face moves: a still face differs by exactly 0. The joy clip comes back near its 0.25 s pose
    # at 1.5-1.7 s (0.09 cm rms apart, 0.29 at 1.4 s), so by when the screenshots fall the difference
    # ran from 0.09 (one CI run, which a threshold of 0.1 failed) to 0.76.
    assert face_difference(out / "playing_a.png", out / "playing_b.png") > 0.02
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


def inside(rect: dict | None, viewport: dict) -> bool:
    return rect is not None and rect["left"] >= 0 and rect["top"] >= 0 and rect["right"] <= viewport["width"] \
        and rect["bottom"] <= viewport["height"]


def test_at_1280x800_face_and_video_sit_side_by_side_and_every_curve_group_has_ticks(tmp_path_factory):
    out = tmp_path_factory.mktemp("viewer_layout")
    target = portrait.avatar_target()
    fap = shared("xface", "Faps", "joy.fap")
    glb = out / "joy.glb"
    write_glb(glb, target.mesh, morphs_from_animation(animate_faps(read_fap(fap), target)))
    with pipeline.view(glb, video=shared("videos", "d0.mp4"), fap=fap, port=0).start() as server:
        report = browser_check(server.url, out, script="browser_layout.js")
    assert report["console_errors"] == [] and report["page_errors"] == []
    viewport = report["viewport"]
    assert viewport == {"width": 1280, "height": 800}
    face, video = report["face"], report["video"]
    assert inside(face, viewport) and inside(video, viewport), (face, video)  # both whole, in the window
    assert face["right"] <= video["left"] and abs(face["top"] - video["top"]) < 2  # side by side
    assert min(face["right"] - face["left"], video["right"] - video["left"]) >= 500  # and not made tiny
    assert inside(report["transport"], viewport)  # the play controls too
    charts = report["charts"]
    assert [c["name"] for c in charts] == [g["name"] for g in fap_curves(read_fap(fap))["groups"]]
    assert {"jaw", "lips", "eyes", "head"} <= {c["name"] for c in charts}
    for chart in charts:  # each group on its own scale, with ticks and its unit
        assert len(chart["y_ticks"]) >= 2 and len(chart["x_ticks"]) >= 2, chart
        assert all(t.endswith(" s") for t in chart["x_ticks"]) and chart["unit"], chart
    eyes, jaw = (next(c for c in charts if c["name"] == name) for name in ("eyes", "jaw"))
    assert eyes["unit"] == "degrees" and jaw["unit"].startswith("x MNS0")
    assert max(abs(float(t)) for t in jaw["y_ticks"]) < 1  # open_jaw's own scale, not the eyes'
    assert report["notes_visible"] == [True] * len(charts)
    assert "6 most active of 22" in [c["note"] for c in charts]  # lips


def test_a_still_expression_has_no_play_controls_and_its_sliders_start_from_its_recipe(tmp_path_factory):
    out = tmp_path_factory.mktemp("viewer_recipe")
    target = portrait.avatar_target()
    table = {"AU12": {12: 300, 13: 300, 6: 80, 7: 80}, "AU26": {3: 500}, "AU4": {31: -150, 32: -150}}
    shapes = {}
    for name, faps in table.items():
        values, mask = np.zeros((1, 68)), np.zeros((1, 68), bool)
        for fap, value in faps.items():
            values[0, fap - 1], mask[0, fap - 1] = value, True
        shapes[name] = animate_faps(FapStream(values, mask, 25.0), target).positions[0] - target.mesh.vertices
    made = 0.8 * shapes["AU12"] + 0.5 * shapes["AU26"]  # as faceanim express writes a still: the recipe made whole
    glb = out / "smile.glb"
    write_glb(glb, target.mesh, MorphSet(np.stack([made, *shapes.values()]), ("expression", *shapes),
                                         default_weights=np.array([1.0, 0, 0, 0])),
              extras={"recipe": "12:0.80,26:0.50",
                      "au_faps": {name: {str(k): v for k, v in faps.items()} for name, faps in table.items()}})
    with pipeline.view(glb, port=0).start() as server:
        report = browser_check(server.url, out, script="browser_layout.js")
    assert report["console_errors"] == [] and report["page_errors"] == []
    assert report["transport"] is None and report["video"] is None and report["charts"] == []  # nothing plays
    assert inside(report["face"], report["viewport"])
    assert report["editor"] and report["units"] == {"AU4": 0, "AU12": 0.8, "AU26": 0.5}  # the recipe's values
    assert report["recipe"] == "12:0.80,26:0.50"
    assert report["influences"] == {"expression": 1, "AU12": 0, "AU26": 0, "AU4": 0}  # the face as made
    # raising AU12 by 0.2 adjusts the recipe: the rest of the expression stays
    assert report["adjusted_unit"] == "AU12" and report["adjusted"]["recipe"] == "12:1.00,26:0.50"
    assert report["adjusted"]["influences"] == pytest.approx({"expression": 1, "AU12": 0.2, "AU26": 0, "AU4": 0})
    assert face_difference(out / "recipe.png", out / "adjusted.png") > 0.05
    assert face_difference(out / "recipe.png", out / "restored.png") < 0.01  # back at the recipe: the face made
    # every unit of the recipe at 0: nothing of the expression is left
    assert report["zeroed"]["recipe"] == ""
    assert report["zeroed"]["influences"] == pytest.approx({"expression": 0, "AU12": 0, "AU26": 0, "AU4": 0})


@pytest.mark.parametrize("size", ["1280x800", "1024x700"])
def test_sliders_adjust_an_animated_expressions_apex_and_the_animation_plays_it(tmp_path_factory, size):
    from faceanim.expressions import envelope
    from faceanim.geometry.animation import Animation

    out = tmp_path_factory.mktemp(f"viewer_express_{size}")
    target = portrait.avatar_target()
    table = {"AU12": {12: 300, 13: 300, 6: 80, 7: 80}, "AU26": {3: 500}, "AU4": {31: -150, 32: -150}}
    shapes = {}
    for name, faps in table.items():
        values, mask = np.zeros((1, 68)), np.zeros((1, 68), bool)
        for fap, value in faps.items():
            values[0, fap - 1], mask[0, fap - 1] = value, True
        shapes[name] = animate_faps(FapStream(values, mask, 25.0), target).positions[0] - target.mesh.vertices
    made = 0.8 * shapes["AU12"] + 0.5 * shapes["AU26"]
    strength = envelope(50)  # as faceanim express --frames 50 writes it: onset, apex, offset over 2 s
    clip = morphs_from_animation(Animation(target.mesh, target.mesh.vertices + strength[:, None, None] * made, 25.0))
    glb = out / "smile.glb"
    write_glb(glb, target.mesh, MorphSet(np.concatenate([clip.targets, np.stack(list(shapes.values()))]),
                                         (*clip.names, *shapes), np.hstack([clip.weights, np.zeros((50, 3))]), 25.0),
              extras={"recipe": "12:0.80,26:0.50",
                      "au_faps": {name: {str(k): v for k, v in faps.items()} for name, faps in table.items()}})
    with pipeline.view(glb, video=shared("videos", "d0.mp4"), port=0).start() as server:
        report = browser_check(server.url, out, size, script="browser_express.js")
    assert report["console_errors"] == [] and report["page_errors"] == []
    viewport = report["viewport"]
    assert [viewport["width"], viewport["height"]] == [int(v) for v in size.split("x")]
    assert inside(report["face"], viewport) and inside(report["video"], viewport), (report["face"], report["video"])
    assert report["face"]["right"] <= report["video"]["left"] and inside(report["transport"], viewport)
    assert report["units"] == {"AU4": 0, "AU12": 0.8, "AU26": 0.5} and "adjust its apex" in report["help"]
    apex_times = np.flatnonzero(strength == 1) / 25.0
    assert apex_times[0] - 1e-6 <= report["apex"] <= apex_times[-1] + 1e-6
    # raising AU12 by 0.2 while playing: paused at the apex, the recipe's shape kept, 0.2 of AU12 added
    apex = report["at_apex"]
    assert not apex["playing"] and apex["time"] == pytest.approx(report["apex"])
    assert apex["strength"] == pytest.approx(1)
    assert apex["recipe"] == "12:1.00,26:0.50"
    assert apex["influences"]["AU12"] == pytest.approx(0.2) and apex["influences"]["AU26"] == pytest.approx(0)
    assert max(apex["influences"][n] for n in clip.names) == pytest.approx(1, abs=1e-3)
    # halfway up the onset the adjustment is at the clip's strength there, not the apex's
    onset = report["onset"]
    want = np.interp(onset["time"], np.arange(50) / 25.0, strength)
    assert onset["strength"] == pytest.approx(want, abs=0.02) and 0.3 < want < 0.7
    assert onset["influences"]["AU12"] == pytest.approx(0.2 * onset["strength"], abs=1e-6)
    # playing: the adjusted expression over time, its units following the clip's strength
    played = report["played"]
    assert all(p["playing"] for p in played) and played[-1]["time"] != played[0]["time"]
    assert all(p["influences"]["AU12"] == pytest.approx(0.2 * p["strength"], abs=1e-6) for p in played)
    assert max(p["strength"] for p in played) - min(p["strength"] for p in played) > 0.3
    assert face_difference(out / "played_a.png", out / "played_b.png") > 0.05
    # every recipe unit at 0: nothing of the expression is left, at the apex as at rest
    zeroed = report["zeroed"]
    assert zeroed["recipe"] == "" and all(v == pytest.approx(0, abs=1e-6) for v in zeroed["influences"].values())
    assert face_difference(out / "zeroed.png", out / "rest.png") < 0.01
    assert face_difference(out / "apex.png", out / "rest.png") > 0.2
