"""One CSV convention (faceanim.export.curves): frame from 1, the video's timestamps, a success column."""

import numpy as np
import pytest

from faceanim.cli import main
from faceanim.errors import FileFormatError
from faceanim.export.curves import FRAME_COLUMNS, read_curve_csv, write_au_csv, write_fap_csv
from faceanim.mpeg4.fapstream import FapStream


def stream(frames=4, numbers=None):
    values, mask = np.zeros((frames, 68)), np.zeros((frames, 68), bool)
    values[:, 2], mask[:, 2] = np.arange(frames) * 10.0, True
    mask[1, 2] = False  # a frame carrying no low-level FAP
    return FapStream(values, mask, 25.0, frame_numbers=numbers)


def test_fap_curves_count_frames_from_one_and_time_them_by_the_video(tmp_path):
    header = write_fap_csv(tmp_path / "a.csv", stream())
    assert header == [*FRAME_COLUMNS, "3_open_jaw"]
    assert (tmp_path / "a.csv").read_text().splitlines()[1:] == [
        "1,0.000,1,0", "2,0.040,0,", "3,0.080,1,20", "4,0.120,1,30"]
    write_fap_csv(tmp_path / "b.csv", stream(), times=[0.5, 0.533, 0.6, 0.7], success=[True, True, False, True])
    _, columns = read_curve_csv(tmp_path / "b.csv")
    np.testing.assert_array_equal(columns["timestamp"], [0.5, 0.533, 0.6, 0.7])
    np.testing.assert_array_equal(columns["success"], [1, 1, 0, 1])
    write_fap_csv(tmp_path / "c.csv", stream(numbers=np.array([0, 2, 4, 6])))  # a .fap's own frame numbers
    _, columns = read_curve_csv(tmp_path / "c.csv")
    np.testing.assert_array_equal(columns["frame"], [1, 3, 5, 7])
    np.testing.assert_allclose(columns["timestamp"], [0, 0.08, 0.16, 0.24])
    with pytest.raises(ValueError, match=r"times and success must have shape \(4,\)"):
        write_fap_csv(tmp_path / "d.csv", stream(), times=[0.0])


def test_every_per_frame_file_reads_back_with_the_same_first_columns(tmp_path):
    write_fap_csv(tmp_path / "f.csv", stream())
    write_au_csv(tmp_path / "a.csv", (12,), [[0.1], [0.2], [0.3], [0.4]], [0, 0.04, 0.08, 0.12])
    for name in ("f.csv", "a.csv"):
        header, columns = read_curve_csv(tmp_path / name)
        assert set(FRAME_COLUMNS) <= set(header)
        np.testing.assert_array_equal(columns["frame"], [1, 2, 3, 4])
        np.testing.assert_allclose(columns["timestamp"], [0, 0.04, 0.08, 0.12])
    _, columns = read_curve_csv(tmp_path / "f.csv")
    assert np.isnan(columns["3_open_jaw"][1])  # an empty cell


def test_reading_a_broken_csv_names_the_file_and_line(tmp_path):
    (tmp_path / "ragged.csv").write_text("frame,timestamp,success\n1,0.0,1\n2,0.04\n")
    with pytest.raises(FileFormatError, match=r"ragged.csv:3: has 2 cells where the header names 3"):
        read_curve_csv(tmp_path / "ragged.csv")
    (tmp_path / "bin.csv").write_bytes(b"\xff\xfe\x00frame")
    with pytest.raises(FileFormatError, match="bin.csv: is not a UTF-8 text CSV"):
        read_curve_csv(tmp_path / "bin.csv")
    (tmp_path / "empty.csv").write_text("")
    with pytest.raises(FileFormatError, match="empty.csv: has no header line"):
        read_curve_csv(tmp_path / "empty.csv")


def test_version(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0 and capsys.readouterr().out.strip() == "faceanim 0.1.0"
