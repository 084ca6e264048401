"""`knotmm template`: build, check and write a template from the command line."""

from __future__ import annotations

import mdtraj
import numpy as np
import pytest

from knotmm.cli.main import main
from knotmm.errors import ConfigError
from knotmm.knots.identify import topoly_available
from knotmm.shapes import BUILTIN_BRAIDS, torus_knot


def test_cli_writes_checked_template(tmp_path, capsys):
    out = tmp_path / "5_2.pdb"
    assert main(["template", "5_2", "--beads", "120", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    for word in ("beads      120", "bonds", "closest", "writhe", "knot type", "wrote"):
        assert word in text
    if topoly_available():
        assert "5_2 (topoly" in text
    assert mdtraj.load(str(out)).n_atoms == 120


@pytest.mark.parametrize(
    ("argv", "writhe_sign"),
    [
        (["torus:2,3", "--mirror"], -1),
        (["T(3,2)"], 1),
        (["braid:1,1,1"], 1),
        (["braid:-1,-1,-1"], -1),
    ],
)
def test_cli_knot_forms(argv, writhe_sign, capsys):
    assert main(["template", *argv, "--beads", "80"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("writhe"))
    assert np.sign(float(line.split()[1])) == writhe_sign


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["torus:2,4", "--beads", "61"], "use knot.beads = 60 or 62"),
        (["hopf", "--beads", "10"], "knot.beads=10 is too few"),
        (["L99a1"], "not in the LinkInfo tables"),
        (["torus:2"], "torus:P,Q"),
        (["braid:1,x"], "braid:W"),
        (["widget:3"], "unknown prefix"),
        (["torus:2,5", "--beads", "12"], "knot.beads >= "),
        (["3_1", "--beads", "2"], "knot.beads"),
        (["3_1", "--out", "x.txt"], ".pdb"),
        ([], "KNOT is missing"),
    ],
)
def test_cli_errors_are_one_line(argv, message, capsys):
    assert main(["template", *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("knotmm: error: ") and message in err
    assert err.count("\n") == 1


def test_cli_list(capsys):
    assert main(["template", "--list"]) == 0
    text = capsys.readouterr().out
    for name in BUILTIN_BRAIDS:
        assert name in text


def test_parse_knot():
    from knotmm.cli.template import parse_knot

    assert parse_knot("torus:3,2") == {"kind": "torus", "p": 3, "q": 2}
    assert parse_knot("T(2,5)") == {"kind": "torus", "p": 2, "q": 5}
    assert parse_knot("braid:1,-2,1,-2") == {"kind": "braid", "word": [1, -2, 1, -2]}
    assert parse_knot("6_1") == {"kind": "knotinfo", "name": "6_1"}
    assert parse_knot("run/top.pdb") == {"kind": "file", "path": "run/top.pdb"}
    assert parse_knot("file:a.dcd") == {"kind": "file", "path": "a.dcd"}
    with pytest.raises(ConfigError):
        parse_knot("torus:a,b")


def test_cli_refuses_to_overwrite_without_flag(tmp_path, capsys):
    out = tmp_path / "t.pdb"
    out.write_text("precious\n")
    assert main(["template", "3_1", "--beads", "60", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--overwrite" in err and str(out) in err
    assert out.read_text() == "precious\n"
    assert main(["template", "3_1", "--beads", "60", "--out", str(out), "--overwrite"]) == 0
    assert mdtraj.load(str(out)).n_atoms == 60


@pytest.mark.parametrize("option", [["--frame", "3"], ["--topology", "top.pdb"]])
def test_cli_file_options_for_other_knots_are_errors(option, capsys):
    assert main(["template", "3_1", "--beads", "60", *option]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and option[0] in err and "file:" in err


def test_cli_frame_applies_to_files(tmp_path, capsys):
    from knotmm.io.pdb import write_pdb

    write_pdb(tmp_path / "two.pdb", np.stack([torus_knot(2, 3, 60), torus_knot(2, 3, 60) * 1.01]))
    assert main(["template", f"file:{tmp_path / 'two.pdb'}", "--frame", "1"]) == 0
    assert "frame 1" in capsys.readouterr().out
