import numpy as np
import pytest

from faceanim.mpeg4 import FAP_COUNT, Fapu, fap_table, fapu_from_points, feature_points, metres_per_unit


def test_tables_have_every_fap_and_feature_point():
    faps, fps = fap_table(), feature_points()
    assert len(faps.names) == FAP_COUNT == 68 and len(fps.names) == 84
    assert len(set(fps.names)) == 84
    for fap_points in faps.feature_points:  # every FAP's point is a known feature point
        assert all(p in fps.names for p in fap_points)


def test_the_shared_tables_are_frozen():
    """fap_table() is parsed once and shared: a caller cannot change it for everyone else."""
    faps = fap_table()
    for name in ("bidirectional", "direction", "quant_step", "i_min", "i_max", "p_min", "p_max"):
        with pytest.raises(ValueError, match="read-only"):
            getattr(faps, name)[0] = 0
    assert fap_table().direction[2].tolist() == [0, -1, 0]
    assert all(isinstance(getattr(faps, n), tuple) for n in ("names", "feature_points", "units"))
    assert all(isinstance(getattr(feature_points(), n), tuple) for n in ("names", "descriptions", "sides", "moved_by"))


def test_known_rows_of_table_c1():
    faps = fap_table()
    n = faps.number("open_jaw")
    assert n == 3 and faps.units[n - 1] == "MNS" and faps.feature_points[n - 1] == ("2.1",)
    np.testing.assert_array_equal(faps.direction[n - 1], [0, -1, 0])
    assert not faps.bidirectional[n - 1] and faps.quant_step[n - 1] == 4 and faps.i_max[n - 1] == 1080
    right = faps.number("stretch_r_cornerlip")
    np.testing.assert_array_equal(faps.direction[right - 1], [-1, 0, 0])  # right = -X
    assert faps.units[faps.number("head_yaw") - 1] == "AU"
    assert feature_points().sides[feature_points().index("8.3")] == "left"


def test_unknown_names_raise_key_error():
    with pytest.raises(KeyError, match="unknown FAP name 'jaw_open'"):
        fap_table().number("jaw_open")
    with pytest.raises(KeyError, match="unknown MPEG-4 feature point '12.1'"):
        feature_points().index("12.1")


def neutral_points():
    return {"3.1": [3, 10.5, 0], "3.3": [3, 9.5, 0], "3.2": [-3, 10.6, 0], "3.4": [-3, 9.4, 0],
            "3.5": [3.2, 10, 0], "3.6": [-3.2, 10, 0], "9.15": [0, 6, 0], "2.2": [0, 3, 0],
            "8.3": [2.5, 3, 0], "8.4": [-2.5, 3, 0]}


def test_fapu_from_points_follows_table_1():
    f = fapu_from_points(neutral_points())
    assert f.irisd0 == pytest.approx(1.1)  # mean of 1.0 and 1.2
    assert (f.es0, f.ens0, f.mns0, f.mw0) == pytest.approx((6.4, 4.0, 3.0, 5.0))
    scale = f.scale()
    assert scale[2] == pytest.approx(3.0 / 1024)   # open_jaw in MNS
    assert scale[48] == pytest.approx(1e-5)        # head_pitch in AU
    assert np.isnan(scale[0])                      # viseme has no unit


def test_fapu_errors_name_the_problem():
    points = neutral_points()
    del points["9.15"], points["2.2"]
    with pytest.raises(KeyError, match="FAPU needs feature points 2.2, 9.15"):
        fapu_from_points(points)
    upside_down = {k: np.array(v) * [1, -1, 1] for k, v in neutral_points().items()}
    with pytest.raises(ValueError, match="irisd0 must be a positive distance"):
        fapu_from_points(upside_down)
    with pytest.raises(ValueError, match="mw0 must be a positive distance"):
        Fapu(1, 1, 1, 1, 0)


def test_curve_columns_are_the_low_level_faps_some_frame_carries():
    import numpy as np

    from faceanim.mpeg4.fapstream import FapStream, curve_columns

    mask = np.zeros((3, 68), bool)
    mask[0, 0] = True  # a viseme: a selection, not a curve
    mask[1, 2] = mask[2, 47] = True
    stream = FapStream(np.zeros((3, 68)), mask, 25.0, visemes=np.zeros((3, 4), np.int64))
    assert curve_columns(stream).tolist() == [2, 47]


@pytest.mark.parametrize("scale, unit", [(1.0, 0.01), (0.01, 1.0), (10.0, 0.001), (0.1, 0.1)])
def test_the_unit_of_a_face_is_told_from_its_eye_separation(scale, unit):
    centimetres = np.array([1.0, 6.3, 4.6, 3.0, 5.0])  # IRISD0, ES0, ENS0, MNS0, MW0 of an adult, in cm
    fapu = Fapu(*(centimetres * scale))  # the same face in cm, m, mm and a model normalised to ~2 units tall
    assert metres_per_unit(fapu) == unit
    assert fapu.es0 * unit == pytest.approx(0.063)  # 6.3 cm, whatever the unit
    assert metres_per_unit(Fapu(*(centimetres * scale * 3))) == unit  # a wide face keeps its unit
    assert metres_per_unit(Fapu(*(centimetres * scale * 0.35))) == unit  # a child's keeps it too


@pytest.mark.parametrize("es0, message", [
    (0.01, r"es0 \(eye separation\) of 0.01 model units is no human face .*\(1 cm as metres; expected 2 to 20 cm\)"),
    (500.0, r"es0 \(eye separation\) of 500 model units is no human face .*\(50 cm as millimetres;"),
])
def test_a_face_of_no_human_size_has_no_unit(es0, message):
    with pytest.raises(ValueError, match=message):
        metres_per_unit(Fapu(irisd0=1.0, es0=es0, ens0=1.0, mns0=1.0, mw0=1.0))
