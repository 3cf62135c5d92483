import base64
import re

import pytest
from conftest import khronos_report

from faceanim.cli import main
from faceanim.demo import FPS, SCRIPT, apex_frames, run_demo, scripted_stream
from faceanim.mpeg4.fapfile import read_fap


def test_scripted_stream_reaches_each_apex_in_its_window():
    stream = scripted_stream()
    for middle, (_, start, _end, apex) in zip(apex_frames(), SCRIPT, strict=True):
        for fap, value in apex.items():
            assert stream.values[middle, fap - 1] == pytest.approx(value, rel=0.05)  # within half a frame of the apex
            assert stream.values[: int(start * FPS), fap - 1].max() < 1e-9  # still before its window
    assert stream.values[: int(0.5 * FPS)].max() == 0  # a neutral half second to calibrate on


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    folder = tmp_path_factory.mktemp("demo")
    return run_demo(folder)


def test_demo_writes_every_output_and_reads_the_performance_back(demo):
    for path in demo.outputs.values():
        assert path.is_file() and path.stat().st_size > 0
    stream = read_fap(demo.outputs["demo.fap"])
    assert len(stream) == len(scripted_stream())
    report = khronos_report(demo.outputs["demo.glb"])
    assert report["errors"] == 0 and report["warnings"] == 0
    recovery = {name: (correlation, gain) for name, _, correlation, gain in demo.recovery}
    assert set(recovery) == {name for name, *_ in SCRIPT}
    # The capture follows every scripted expression in time; how much of its size it recovers is
    # reported (the tracker under-reads the jaw and the lids), not asserted. The smile is the
    # exception: the Face Landmarker (the tracker since issue 16) follows the demo's warped-photo smile
    # at a correlation of 0.34 where FaceMesh reached 0.75 (an open regression, issue 16's part 5);
    # it must still rise with the script, not against it.
    assert all(correlation > 0.5 for name, (correlation, _) in recovery.items() if name != "smile")
    assert recovery["smile"][0] > 0.25
    # brows: 0.82 with the plain head fit and tracked brows, 0.79 with the robust fit and the scores'
    # brows (issue 16 part 5), which lift blink from 0.56 to 0.68
    assert recovery["jaw open"][0] > 0.85 and recovery["brows up"][0] > 0.75
    page = demo.outputs["report.html"].read_text()
    assert "FAPs read back from the video" in page and "faceanim view " in page
    assert page.count('<img src="data:image/jpeg') == len(SCRIPT)
    curves = re.search(r'<img class="curves" src="data:image/png;base64,([^"]+)"', page)  # faceanim plot's panels
    assert curves and base64.b64decode(curves.group(1)).startswith(b"\x89PNG")
    for frame, (name, *_) in zip(apex_frames(), SCRIPT, strict=True):  # every still says what it shows
        assert f"<figcaption>frame {frame}: {name}</figcaption>" in page


def test_demo_command_says_where_its_outputs_are(tmp_path, capsys):
    target = tmp_path / "file"
    target.write_text("x")
    assert main(["demo", "-o", str(target)]) == 2
    assert "exists and is not a folder" in capsys.readouterr().err
    assert target.read_text() == "x"


def test_blender_opens_the_demo_avatar_with_its_animation(demo, tmp_path):
    from test_blender import blender_import

    found = blender_import(demo.outputs["demo.glb"], tmp_path)
    (obj,) = found["objects"]
    assert obj["textured"] and obj["animated_keys"] == len(obj["shape_keys"]) - 1 > 0
    start, end = obj["frame_range"]
    assert end - start == pytest.approx((len(scripted_stream()) - 1) / FPS * 24, abs=1.0)


@pytest.mark.parametrize("stop", [KeyboardInterrupt, RuntimeError])
def test_a_demo_stopped_in_its_first_step_leaves_no_folder_it_made(tmp_path, monkeypatch, stop):
    """An interrupt (or a failure) before the first output is in place used to leave an empty folder."""
    import faceanim.demo as demo

    def halt(*_):
        raise stop("stopped while making the avatar")

    monkeypatch.setattr(demo, "face_crop", halt)
    with pytest.raises(stop):
        run_demo(tmp_path / "new" / "demo")
    assert not (tmp_path / "new" / "demo").exists()
    (tmp_path / "mine").mkdir()  # a folder the user made stays, empty as it was
    with pytest.raises(stop):
        run_demo(tmp_path / "mine")
    assert (tmp_path / "mine").is_dir()
