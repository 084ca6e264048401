"""Runs of several chains built and read back right, from the command line (issue 30):

* BUG-15: 70 chains (straight rods of 4 beads): run, topology.pdb, run.toml's layout, the
  chains read back, ``--resume`` and (slow) ``analyze``;
* BUG-20: an edited ``[knotmm.layout]`` is refused on ``--resume`` in one line, before any
  step, run.toml left as it was;
* BUG-24, issue 34: ``knotmm template file:`` of a run of two chains reads two chains,
  never one;
* BUG-10 / BUG-11: a perturbed link's replicas differ; a link with ``closed = false`` runs
  as one open chain per component.
"""

from __future__ import annotations

import json
import re

import mdtraj
import numpy as np
import pytest

from knotmm.cli.main import main
from knotmm.io.dcd import read_dcd
from knotmm.io.run_data import load_run
from knotmm.io.rundir import read_facts

_OUTPUT = """
[output]
frame_interval = {fi}
checkpoint_interval = 0.1
"""


def _rods(tmp_path, n_chains: int = 70, duration: float = 0.2, fi: float = 0.1):
    """A run file of ``n_chains`` straight rods of 4 beads on a 6 d grid."""
    lines = []
    for c in range(n_chains):
        lines += ["[[chains]]", 'kind = "straight"', "beads = 4",
                  f"offset = [{6.0 * (c % 10)}, {6.0 * (c // 10)}, 0.0]", ""]
    path = tmp_path / "rods.toml"
    path.write_text("\n".join(lines) + f"\n[run]\nduration = {duration}\n"
                    + _OUTPUT.format(fi=fi))
    return path


def _one_error_line(capsys, *words):
    err = capsys.readouterr().err
    assert err.startswith("knotmm: error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err
    for word in words:
        assert word in err, err
    return err


def test_a_run_of_70_chains_is_written_read_back_and_resumed(tmp_path, capsys):
    out = tmp_path / "ch70"
    assert main(["run", str(_rods(tmp_path)), "--out", str(out), "--no-progress"]) == 0
    facts = read_facts(out)
    assert facts["layout"]["lengths"] == [4] * 70 and facts["layout"]["closed"] == [False] * 70
    ids = [c["id"] for c in facts["chains"]]
    assert len(set(ids)) == 70 and ids[61:64] == ["9", "AA", "AB"]
    top = mdtraj.load(str(out / "topology.pdb")).topology
    assert top.n_chains == 70 and top.n_bonds == 210
    assert [c.residue(0).segment_id for c in top.chains] == ids
    assert "mol color SegName" in (out / "view.vmd").read_text()
    data = load_run(out)
    assert data.chains() == [(4 * c, 4, False) for c in range(70)]
    assert main(["run", "--resume", str(out), "--duration", "0.4", "--no-progress"]) == 0
    assert read_facts(out)["status"] == "finished"
    assert load_run(out).n_frames == 5 and load_run(out).chains() == data.chains()


@pytest.mark.slow
def test_the_analysis_of_70_chains_names_each_chain(tmp_path):
    out = tmp_path / "ch70"
    path = _rods(tmp_path, duration=0.2, fi=0.01)
    assert main(["run", str(path), "--out", str(out), "--no-progress", "-q"]) == 0
    assert main(["analyze", str(out)]) == 0
    chains = json.loads((out / "analysis.json").read_text())["chains"]
    assert [c["beads"] for c in chains] == [4] * 70
    assert len({c["id"] for c in chains}) == 70


TWO_RINGS = """
[[chains]]
beads = 30
offset = [-4.0, 0.0, 0.0]
[[chains]]
beads = 30
offset = [4.0, 0.0, 0.0]
[run]
duration = 0.2
topology_check_interval = 0.0
""" + _OUTPUT.format(fi=0.1)


@pytest.fixture(scope="module")
def two_rings(tmp_path_factory):
    """A finished run of two T(2,3) rings of 30 beads."""
    base = tmp_path_factory.mktemp("two")
    (base / "two.toml").write_text(TWO_RINGS)
    assert main(["run", str(base / "two.toml"), "--out", str(base / "run"), "-q",
                 "--no-progress"]) == 0
    return base / "run"


def _edited(two_rings, tmp_path, lengths: str | None, closed: str | None = None):
    copy = tmp_path / "run"
    copy.mkdir()
    for f in two_rings.iterdir():
        (copy / f.name).write_bytes(f.read_bytes())
    text = (copy / "run.toml").read_text()
    if lengths is None:  # the table removed
        text = re.sub(r"\[knotmm\.layout\]\n(?:[^\[]|\[\s*[^\]\s])*?(?=\n\[|\Z)", "", text)
        assert "[knotmm.layout]" not in text
    else:
        text = re.sub(r"(\[knotmm\.layout\]\nlengths = )\[[^\]]*\]",
                      lambda m: m.group(1) + lengths, text)
    if closed is not None:
        text = re.sub(r"(\[knotmm\.layout\]\n(?:.*\n)*?closed = )\[[^\]]*\]",
                      lambda m: m.group(1) + closed, text)
    (copy / "run.toml").write_text(text)
    return copy


@pytest.mark.parametrize(("lengths", "closed", "says"), [
    ("[20, 40]", None, "disagrees with the run's chains"),
    ("[30, 31]", None, "hold 61 beads, the run's state 60"),
    ('"abc"', None, "lengths = 'abc': expected a list"),
    ("[30, 30]", "[true, false]", "disagrees with the run's chains"),
    ("[30, 30]", "[true]", "closed has 1 entries for 2 chains"),
    (None, None, "is missing, but the run holds"),
])
def test_an_edited_layout_is_refused_on_resume_before_any_step(two_rings, tmp_path, capsys,
                                                                lengths, closed, says):
    run = _edited(two_rings, tmp_path, lengths, closed)
    before = {f.name: f.read_bytes() for f in run.iterdir()}
    capsys.readouterr()
    assert main(["run", "--resume", str(run), "--duration", "0.4", "--no-progress"]) == 2
    err = _one_error_line(capsys, "run.toml's [knotmm.layout]", says)
    assert "restore" in err and "lengths = [30, 30], closed = [true, true]" in err
    assert {f.name: f.read_bytes() for f in run.iterdir()} == before


def test_a_template_from_a_run_of_two_chains_reads_two_chains(two_rings, tmp_path, capsys):
    """Issue 34: it was refused ("does not join"), and before that joined into one ring."""
    for k, source in enumerate((two_rings / "trajectory.dcd", two_rings / "topology.pdb",
                                two_rings)):
        capsys.readouterr()
        out = tmp_path / f"t{k}.pdb"
        assert main(["template", f"file:{source}", "--out", str(out)]) == 0
        text = capsys.readouterr().out
        assert "60 in 2 chains" in text and "does not join" not in text
        assert [c.n_atoms for c in mdtraj.load(str(out)).topology.chains] == [30, 30]
        bonds = {tuple(sorted((a.index, b.index))) for a, b in
                 mdtraj.load(str(out)).topology.bonds}
        assert (0, 29) in bonds and (30, 59) in bonds and (29, 30) not in bonds


HOPF = """
[knot]
kind = "knotinfo"
name = "hopf"
beads = 40
{extra}
[run]
duration = 0.1
topology_check_interval = 0.0
{run}
""" + _OUTPUT.format(fi=0.05)


def test_a_link_cut_open_runs_as_one_open_chain_per_component(tmp_path):
    path = tmp_path / "open.toml"
    path.write_text(HOPF.format(extra="closed = false", run=""))
    assert main(["run", str(path), "--out", str(tmp_path / "r"), "-q", "--no-progress"]) == 0
    facts = read_facts(tmp_path / "r")
    assert facts["layout"] == {"lengths": [20, 20], "closed": [False, False],
                               "ids": ["A", "B"]}
    data = load_run(tmp_path / "r")
    assert data.chains() == [(0, 20, False), (20, 20, False)]  # no bond joins them


def test_the_replicas_of_a_perturbed_link_differ(tmp_path):
    path = tmp_path / "pert.toml"
    path.write_text(HOPF.format(extra="perturbation = 0.05", run="replicas = 2"))
    assert main(["run", str(path), "--out", str(tmp_path / "r"), "-q", "--no-progress"]) == 0
    first = [read_dcd(tmp_path / "r" / f"replica_{k}" / "trajectory.dcd")[0][0]
             for k in range(2)]
    assert np.abs(first[0] - first[1]).max() > 0.01
    seeds = [read_facts(tmp_path / "r" / f"replica_{k}") for k in range(2)]
    assert all(f["n_beads"] == 40 for f in seeds)
