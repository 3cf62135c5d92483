import numpy as np
import pytest
from conftest import shared

from faceanim.errors import FileFormatError
from faceanim.mpeg4 import FAP_COUNT
from faceanim.mpeg4.fapfile import read_fap, write_fap
from faceanim.mpeg4.fapstream import FapStream

XFACE = ["anger", "beg", "disgust", "fear", "happy-for", "hate", "joy", "pride", "test"]

VISEME_MASK = " ".join(["1", "1", "1"] + ["0"] * 45 + ["1"] + ["0"] * 19)  # FAPs 1, 2, 3 and 49
HELLO = f"""2.1 hello 25 2
{VISEME_MASK}
0 1 10 63 0 1 40 0 0 1 0 200 5000
# a comment between frames
{VISEME_MASK}
1 10 1 32 0 1 20 0 0 0 0 150 2500
"""


@pytest.mark.parametrize("name", XFACE)
def test_every_xface_file_reads(name):
    path = shared("xface", "Faps", f"{name}.fap")
    stream = read_fap(path)
    header = open(path, encoding="latin-1").readline().split()
    assert len(stream) == int(header[-1]) and stream.fps == float(header[-2])
    first_mask = [t == "1" for t in open(path, encoding="latin-1").readlines()[1].split()]
    np.testing.assert_array_equal(stream.mask[0], first_mask)


def test_viseme_and_expression_fields(tmp_path):
    path = tmp_path / "hello.fap"
    path.write_text(HELLO)
    s = read_fap(path)
    assert s.name == "hello" and len(s) == 2
    np.testing.assert_array_equal(s.visemes, [[1, 10, 63, 0], [10, 1, 32, 0]])
    np.testing.assert_array_equal(s.expressions[0], [1, 40, 0, 0, 1, 0])
    assert s.values[0, 2] == 200 and s.values[0, 48] == 5000 and s.values[1, 48] == 2500


def test_write_then_read_round_trips(tmp_path):
    rng = np.random.default_rng(0)
    values = rng.integers(-300, 300, size=(5, FAP_COUNT)).astype(float)
    mask = rng.random((5, FAP_COUNT)) < 0.5
    mask[:, :2] = [True, False]
    stream = FapStream(values, mask, 30.0, visemes=rng.integers(0, 14, size=(5, 4)), name="round")
    write_fap(tmp_path / "a.fap", stream)
    back = read_fap(tmp_path / "a.fap")
    np.testing.assert_array_equal(back.mask, stream.mask)
    np.testing.assert_array_equal(back.values, stream.values)
    np.testing.assert_array_equal(back.visemes[mask[:, 0]], stream.visemes[mask[:, 0]])
    assert back.fps == 30 and back.name == "round"


def test_xface_file_round_trips(tmp_path):
    original = read_fap(shared("xface", "Faps", "joy.fap"))
    write_fap(tmp_path / "joy.fap", original)
    back = read_fap(tmp_path / "joy.fap")
    np.testing.assert_array_equal(back.values, original.values)
    np.testing.assert_array_equal(back.mask, original.mask)


MASK = " ".join(["0", "0", "1"] + ["0"] * 65)
VISEME_ONLY = " ".join(["1"] + ["0"] * 67)


@pytest.mark.parametrize("text, match", [
    ("2.1 a 25 1\n0 0 1\n0 5\n", r"a.fap:2: FAP mask must be 68 zeros and ones, got 3 tokens"),
    (f"2.1 a 25 1\n{MASK}\n", r"a.fap:2: FAP mask has no value line after it"),
    (f"2.1 a 25 1\n{MASK}\n0 1x\n", r"a.fap:3: value '1x' is not a number"),
    (f"2.1 a 25 1\n{MASK}\n0 1 2\n", r"a.fap:3: value line must hold the frame number and 1 values"),
    (f"2.1 a 25 2\n{MASK}\n0 1\n", r"a.fap:1: header says 2 frames but the file holds 1"),
    (f"2.1 a 25 2\n{MASK}\n3 1\n{MASK}\n2 1\n", r"a.fap:5: frame number 2 comes after frame 3"),
    ("2.1 a\n", r"a.fap:1: header must be"),
    ("", r"a.fap: is empty"),
    (f"2.1 a 25 1\n{MASK}\n1e30 5\n", r"a.fap:3: frame number 1e30 is not a whole number from 0 to 2147483647"),
    (f"2.1 a 25 1\n{MASK}\n2.5 5\n", r"a.fap:3: frame number 2.5 is not a whole number"),
    (f"2.1 a 25 1\n{MASK}\n-1 5\n", r"a.fap:3: frame number -1 is not a whole number from 0"),
    (f"2.1 a 25 1\n{VISEME_ONLY}\n0 1e300 1 0 0\n", r"a.fap:3: FAP 1 field 1e300 is not a whole number"),
    (f"2.1 a 25 1\n{VISEME_ONLY}\n0 1.5 1 0 0\n", r"a.fap:3: FAP 1 field 1.5 is not a whole number"),
    ("2.1 a 25 0\n", r"a.fap:1: holds no frames"),
    ("2.1 a 25 0\n# frames would follow\n", r"a.fap:1: holds no frames"),
])
def test_malformed_fap_names_line(tmp_path, text, match):
    path = tmp_path / "a.fap"
    path.write_text(text)
    with pytest.raises(FileFormatError, match=match):
        read_fap(path)


def test_out_of_range_values_are_kept_and_reported(tmp_path):
    path = tmp_path / "a.fap"
    path.write_text(f"2.1 a 25 1\n{MASK}\n0 99999\n")
    stream = read_fap(path)
    assert stream.values[0, 2] == 99999 and stream.out_of_range()[0, 2]


@pytest.mark.parametrize("fps", ["1e300", "5000", "1e-9"])
def test_a_frame_rate_no_player_keeps_is_refused_with_its_line(tmp_path, fps):
    """A .fap of 1e300 fps used to be read, and decoded into a glTF whose keyframe times were all 0."""
    path = tmp_path / "fast.fap"
    path.write_text(f"2.1 fast {fps} 1\n" + "0 0 1" + " 0" * 65 + "\n0 100\n")
    with pytest.raises(FileFormatError, match=rf"fast.fap:1: header frame rate {fps} must lie from 0.001 to 1000"):
        read_fap(path)


@pytest.mark.parametrize("fps", [0.4, 2000.0])
def test_a_frame_rate_the_format_cannot_hold_is_refused_before_writing(tmp_path, fps):
    """0.4 fps used to be written as 0, a file fap-info then refused."""
    mask = np.zeros((2, FAP_COUNT), dtype=bool)
    mask[:, 2] = True
    with pytest.raises(ValueError, match=f"a .fap holds a whole frame rate from 1 to 1000; {fps:g} fps rounds"):
        write_fap(tmp_path / "slow.fap", FapStream(np.zeros((2, FAP_COUNT)), mask, fps))
    assert not (tmp_path / "slow.fap").exists()
