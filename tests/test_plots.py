"""faceanim plot (faceanim.export.plots): a panel per group, each on its own scale and unit, with ticks."""

import numpy as np
import pytest
from conftest import shared
from PIL import Image

from faceanim.cli import main
from faceanim.errors import FileFormatError, InputError
from faceanim.export.curves import write_au_csv, write_fap_csv
from faceanim.mpeg4.fapstream import FapStream

pytest.importorskip("matplotlib", reason="faceanim plot needs matplotlib (the plot extra)")

from faceanim.export.plots import GROUPS, curve_panels, draw, plot  # noqa: E402


def faps(frames=50):
    values, mask = np.zeros((frames, 68)), np.zeros((frames, 68), bool)
    t = np.linspace(0, 1, frames)
    for number, curve in ((3, 400 * t), (12, 100 * t), (31, 50 * t), (19, 1024 * t), (23, 21000 * t), (49, -5000 * t)):
        values[:, number - 1], mask[:, number - 1] = curve, True
    return FapStream(values, mask, 25.0)


def test_faps_fall_into_groups_each_in_its_unit(tmp_path):
    write_fap_csv(tmp_path / "f.csv", faps())
    x, label, panels = curve_panels(tmp_path / "f.csv")
    by = {(p.name, p.unit): p for p in panels}
    assert [p.name for p in panels] == ["jaw", "lips", "brows", "lids", "eyes", "head"]
    assert [p.name for p in panels] == sorted((p.name for p in panels), key=GROUPS.index)
    assert label == "time (s)" and x[-1] == pytest.approx(49 / 25)
    assert by["jaw", "x MNS0"].curves["open_jaw (MNS)"][-1] == pytest.approx(400 / 1024)  # FAPU/1024 -> x FAPU
    assert by["eyes", "degrees"].curves["yaw_l_eyeball"][-1] == pytest.approx(np.degrees(0.21))  # 21000 x 1e-5 rad
    assert by["head", "degrees"].curves["head_yaw"][-1] == pytest.approx(np.degrees(-0.05))


def test_each_panel_has_its_own_scale_ticks_and_unit(tmp_path):
    write_fap_csv(tmp_path / "f.csv", faps())
    x, label, panels = curve_panels(tmp_path / "f.csv")
    figure = draw(x, label, panels, title="t")
    axes = figure.axes
    assert len(axes) == len(panels)
    for ax, panel in zip(axes, panels, strict=True):
        assert ax.get_ylabel() == panel.unit and len(ax.get_yticks()) >= 3 and len(ax.get_xticks()) >= 3
        low, high = ax.get_ylim()
        peak = max(np.nanmax(np.abs(c)) for c in panel.curves.values())
        assert high - low < 3 * peak  # scaled to its own curves: eyeball degrees do not flatten the jaw
    out = tmp_path / "f.png"
    assert [p.name for p in plot(tmp_path / "f.csv", out)] == [p.name for p in panels]
    with Image.open(out) as image:
        assert image.format == "PNG" and image.size[0] == 1100


def test_au_csv_and_a_live_link_take(tmp_path):
    values = np.linspace(0, 1, 20)[:, None] * [0.2, 1.0, 0.5]
    write_au_csv(tmp_path / "a.csv", (1, 12, 26), values, np.arange(20) / 30, pose=np.full((20, 3), 0.1))
    _, _, panels = curve_panels(tmp_path / "a.csv")
    assert [(p.name, p.unit) for p in panels] == [("jaw", "intensity (0-5)"), ("lips", "intensity (0-5)"),
                                                 ("brows", "intensity (0-5)"), ("head", "degrees")]
    assert panels[-1].curves["yaw (Ry)"][0] == pytest.approx(np.degrees(0.1))
    take = ["Timecode,BlendShapeCount,EyeBlinkLeft,JawOpen,MouthSmileLeft,BrowInnerUp,HeadYaw"]
    take += [f"00:00:00:{i:02d}.000,52,0.1,{i / 10},0.5,0.2,0.01" for i in range(10)]
    (tmp_path / "take.csv").write_text("\n".join(take) + "\n")
    x, label, panels = curve_panels(tmp_path / "take.csv")
    assert label == "row" and [p.name for p in panels] == ["jaw", "lips", "brows", "lids", "head"]
    plot(tmp_path / "take.csv", tmp_path / "take.png")


def test_a_real_fap_file():
    _, _, panels = curve_panels(shared("xface", "Faps", "joy.fap"))
    assert {"jaw", "lips", "head"} <= {p.name for p in panels}


def test_bad_input_is_one_line_and_writes_nothing(tmp_path, capsys):
    (tmp_path / "x.csv").write_text("a,b\n1,2\n")
    with pytest.raises(FileFormatError, match="holds no FAP .* AU .* or blendshape .* columns to plot"):
        curve_panels(tmp_path / "x.csv")
    (tmp_path / "x.txt").write_text("3_open_jaw\n1\n")
    with pytest.raises(InputError, match="plot reads a .fap file or a .csv"):
        curve_panels(tmp_path / "x.txt")
    assert main(["plot", str(tmp_path / "x.csv"), "-o", str(tmp_path / "x.png")]) == 2
    assert main(["plot", str(tmp_path / "x.csv"), "-o", str(tmp_path / "x.jpg")]) == 2
    assert main(["plot", str(tmp_path / "none.fap"), "-o", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 3 and all(line.startswith("faceanim: error: ") for line in err)
    assert "this output is written as .png" in err[1] and "none.fap: no such file" in err[2]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.csv", "x.txt"]
