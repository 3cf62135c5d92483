import json
import re

import numpy as np
import pytest
from test_project import bumpy_sphere
from test_transfer import expression_of, shuffled

from faceanim.cli import main
from faceanim.geometry import read_mesh, write_mesh


def write_transfer_files(folder):
    """``src.obj``, ``expr.ply``, ``tgt.glb`` (the source shuffled) and ``pairs.json`` (12 pairs) in
    ``folder``; returns the shuffle's new vertex index."""
    rng = np.random.default_rng(3)
    source = bumpy_sphere()
    target, new_index = shuffled(source, rng)
    ids = rng.choice(len(source.vertices), 12, replace=False)
    write_mesh(folder / "src.obj", source)
    write_mesh(folder / "expr.ply", expression_of(source, rng))
    write_mesh(folder / "tgt.glb", target)
    (folder / "pairs.json").write_text(json.dumps({"source": ids.tolist(), "target": new_index[ids].tolist()}))
    return new_index


@pytest.fixture
def files(tmp_path):
    return tmp_path, write_transfer_files(tmp_path)


def run(tmp_path, *extra):
    return main(["transfer", str(tmp_path / "src.obj"), str(tmp_path / "expr.ply"), str(tmp_path / "tgt.glb"),
                 "-o", str(tmp_path / "out.obj"), "--correspondence", str(tmp_path / "pairs.json"), *extra])


@pytest.mark.parametrize("method", ["clone", "rbf"])
def test_transfer_command_writes_the_moved_target(files, capsys, method):
    tmp_path, new_index = files
    assert run(tmp_path, "--method", method) == 0
    out = read_mesh(tmp_path / "out.obj")
    expr = read_mesh(tmp_path / "expr.ply")
    assert len(out.vertices) == len(expr.vertices)
    error = np.abs(out.vertices[new_index] - expr.vertices).max()
    if method == "clone":
        assert error < 1e-6
    else:  # only the 12 control points' motion is known: exact there, and better than not moving
        ids = json.loads((tmp_path / "pairs.json").read_text())["source"]
        np.testing.assert_allclose(out.vertices[new_index][ids], expr.vertices[ids], atol=1e-6)
        rest = read_mesh(tmp_path / "src.obj").vertices
        assert np.linalg.norm(out.vertices[new_index] - expr.vertices) < np.linalg.norm(rest - expr.vertices)
    assert "wrote" in capsys.readouterr().out


@pytest.mark.parametrize("pairs, match", [
    ({"source": [0, 1, 2], "target": [0, 1]}, "pairs.json: \"source\" has 3 ids but \"target\" has 2"),
    ({"source": [0, 1, 2, 3], "target": [0, 1, 2, 9999]}, r"pairs.json: target ids must lie in \[0, 144\)"),
    ({"source": [0, 1, 2, 2], "target": [0, 1, 2, 3]}, r"pairs.json: source ids must be distinct; repeated: \[2\]"),
    ({"src": [0]}, 'pairs.json: must be an object with "source" and "target"'),
    ({"source": [0, 1.5], "target": [0, 1]}, '"source" must be a list of integer vertex ids'),
])
def test_bad_pairs_print_one_line_and_write_nothing(files, capsys, pairs, match):
    tmp_path, _ = files
    (tmp_path / "pairs.json").write_text(json.dumps(pairs))
    assert run(tmp_path) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("faceanim: error: ")
    assert re.search(match, err)
    assert not (tmp_path / "out.obj").exists()


def test_malformed_obj_names_line(files, capsys):
    tmp_path, _ = files
    text = (tmp_path / "src.obj").read_text().splitlines()
    text[5] = "v 1.0 oops 2.0"
    (tmp_path / "src.obj").write_text("\n".join(text))
    assert run(tmp_path) == 2
    assert "src.obj:6: vertex has a non-numeric token" in capsys.readouterr().err
    assert not (tmp_path / "out.obj").exists()


def test_region_needs_68_pairs_and_known_names(files, capsys):
    tmp_path, _ = files
    assert run(tmp_path, "--region", "lips") == 2
    assert "needs the 68 pairs" in capsys.readouterr().err
    assert run(tmp_path, "--region", "ears") == 2
    assert "unknown region 'ears'; regions are lips, eyes" in capsys.readouterr().err


def test_vertex_mask_file(files):
    tmp_path, _ = files
    (tmp_path / "mask.json").write_text(json.dumps([0, 1, 2]))
    assert run(tmp_path, "--mask", str(tmp_path / "mask.json")) == 0
    out, target = read_mesh(tmp_path / "out.obj"), read_mesh(tmp_path / "tgt.glb")
    np.testing.assert_allclose(out.vertices[3:], target.vertices[3:], atol=1e-6)


def test_missing_input_is_one_line(files, capsys):
    tmp_path, _ = files
    (tmp_path / "src.obj").unlink()
    assert run(tmp_path) == 2
    assert capsys.readouterr().err.strip().endswith("src.obj: no such file")


def test_a_reader_that_leaves_early_ends_the_command_quietly(tmp_path):
    """``faceanim fap-info F | head -1``: the reader closes the pipe before the summary is printed; the
    command ends as a signal would (128 + SIGPIPE), without a traceback."""
    import signal
    import subprocess
    import sys

    from faceanim.mpeg4.fapfile import write_fap
    from faceanim.mpeg4.fapstream import FapStream

    fap = tmp_path / "f.fap"
    mask = np.zeros((3, 68), dtype=bool)
    mask[:, 2:] = True  # every FAP but the viseme and expression: a long summary
    write_fap(fap, FapStream(np.zeros((3, 68)), mask, 25.0))
    child = subprocess.Popen([sys.executable, "-m", "faceanim.cli", "fap-info", str(fap)], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE)
    child.stdout.close()  # long before the interpreter has started and imported faceanim
    stderr = child.stderr.read().decode()
    assert child.wait(timeout=60) == 128 + signal.SIGPIPE and "Traceback" not in stderr, stderr


@pytest.mark.parametrize("argv, says", [
    (["express", "--au", "12:1", "--frames", "abc", "-o", "x.glb"],
     "argument --frames: invalid int value: 'abc' (see faceanim express --help)"),
    (["decode"], "the following arguments are required: FILE.fap, -o/--output (see faceanim decode --help)"),
    (["nosuch"], "argument COMMAND: invalid choice: 'nosuch'"),
])
def test_a_command_line_mistake_is_one_line_like_any_user_error(capsys, argv, says):
    """argparse printed its usage block and then the error: 4 to 6 lines."""
    with pytest.raises(SystemExit) as stop:
        main(argv)
    error = capsys.readouterr().err
    assert stop.value.code == 2 and error.count("\n") == 1 and error.startswith("faceanim: error: ") and says in error
