"""faceanim.inputs: how a job's sources are read (a video or a saved track, the neutral)."""

import numpy as np
import pytest
from test_track import parts

from faceanim import inputs
from faceanim.capture.track import Track
from faceanim.cli import main
from faceanim.errors import InputError


def test_a_saved_track_is_read_whatever_the_case_of_its_suffix(tmp_path, monkeypatch):
    track = Track(**parts())
    track.save(tmp_path / "t.npz")
    (tmp_path / "t.npz").rename(tmp_path / "T.NPZ")  # was handed to FFmpeg as a video
    monkeypatch.setattr(inputs, "motion_of_track", lambda recorded, **_: recorded)
    np.testing.assert_array_equal(inputs.capture_motion(tmp_path / "T.NPZ").landmarks, track.landmarks)


@pytest.mark.parametrize("neutral, match", [
    ("missing.png", r"--neutral missing.png: no such image"),
    ("", r"--neutral is empty"),  # was the path ".", whose images were taken for the face at rest
    ("  ", r"--neutral is empty"),
])
def test_a_neutral_that_cannot_be_read_is_refused_before_the_video_is_tracked(tmp_path, monkeypatch, neutral,
                                                                               match):
    def tracked(*_, **__):
        raise AssertionError("the video was tracked")

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr("faceanim.capture.track.track_video", tracked)
    with pytest.raises(InputError, match=match):
        inputs.capture_motion(tmp_path / "in.mp4", neutral=neutral)


def test_encode_names_a_missing_neutral_in_one_line(tmp_path, capsys):
    assert main(["encode", str(tmp_path / "in.mp4"), "-o", str(tmp_path / "x.fap"), "--neutral",
                 str(tmp_path / "rest.png")]) == 2
    assert capsys.readouterr().err == f"faceanim: error: --neutral {tmp_path / 'rest.png'}: no such image, or frame " \
                                      "number (FRAME or START:END)\n"
    assert list(tmp_path.iterdir()) == []
