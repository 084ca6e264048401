"""A start read from a file keeps the file's chains (issue 34, "Files in").

A link and a system of three chains (two linked rings and an open rod), written by knotmm's
own writers (``knotmm template --out``, a run's ``topology.pdb`` and ``trajectory.dcd``), are
read back with ``knot.kind = "file"``: the chains, their bonds (those of the OpenMM System
too) and the linking numbers are compared with the bonds the tests compute from the chain
lengths and closed flags (``drawn_segments.allowed_pairs``) and with Gauss's integral
(``reference_model.gauss_linking``).
Before, such a file was read as one chain with a long bond between the components, then
refused ("does not join").
"""

from __future__ import annotations

import re

import numpy as np
import pytest
import reference_model as rm
from drawn_segments import allowed_pairs, write_system_run

from knotmm.cli.main import main
from knotmm.config import RunConfig
from knotmm.errors import TrajectoryFileError
from knotmm.model.layout import ChainLayout
from knotmm.shapes import build_system, build_template


def chains_of(x, lengths):
    return np.split(np.asarray(x), np.cumsum(lengths)[:-1])


def file_cfg(path, **knot) -> RunConfig:
    return RunConfig.from_dict({"knot": {"kind": "file", "path": str(path), **knot}})


def system_bonds(cfg) -> set[tuple[int, int]]:
    """The bonded pairs of the OpenMM System a run of ``cfg`` would simulate."""
    topology, system, _ = build_system(cfg)
    force = next(f for f in system.getForces() if f.getName() == "bond")
    pairs = {tuple(sorted(force.getBondParameters(k)[:2])) for k in range(force.getNumBonds())}
    top = {tuple(sorted((a.index, b.index))) for a, b in topology.bonds()}
    assert pairs == top
    return pairs


@pytest.fixture(scope="module")
def hopf_pdb(tmp_path_factory):
    """``knotmm template hopf --beads 60 --out hopf.pdb``: knotmm's own PDB of a link."""
    path = tmp_path_factory.mktemp("hopf") / "hopf.pdb"
    assert main(["template", "hopf", "--beads", "60", "--out", str(path)]) == 0
    return path


def test_a_hopf_link_reads_back_with_its_chains_bonds_and_linking_number(hopf_pdb):
    tpl = build_template(file_cfg(hopf_pdb))
    assert tpl.layout.lengths == (30, 30) and tpl.layout.closed == (True, True)
    assert {tuple(sorted(b)) for b in tpl.layout.bonds().tolist()} == allowed_pairs(
        (30, 30), (True, True))
    assert system_bonds(file_cfg(hopf_pdb)) == allowed_pairs((30, 30), (True, True))
    a, b = chains_of(tpl.positions, (30, 30))
    lk = rm.gauss_linking(a, b)
    assert abs(abs(lk) - 1.0) < 0.05
    assert tpl.chain_facts["linking_numbers"] == {"A-B": round(lk)}
    assert [p.knot_type for p in tpl.parts] in ([None, None], ["0_1", "0_1"])
    # no bond joins the components: every bond of the start is about a bond length
    x = tpl.positions
    lengths = [np.linalg.norm(x[i] - x[j]) for i, j in allowed_pairs((30, 30), (True, True))]
    assert max(lengths) < 0.61 and np.linalg.norm(x[29] - x[30]) > 1.0
    assert tpl.facts["started_from"]["frame"] == 0


def test_a_hopf_link_with_closed_false_is_two_open_chains_never_one(hopf_pdb):
    tpl = build_template(file_cfg(hopf_pdb, closed=False))
    assert tpl.layout.lengths == (30, 30) and tpl.layout.closed == (False, False)
    assert system_bonds(file_cfg(hopf_pdb, closed=False)) == allowed_pairs((30, 30),
                                                                            (False, False))
    assert "linking_numbers" not in tpl.chain_facts
    assert all(p.knot_type is None for p in tpl.parts)
    assert any("knot.closed = false" in n and "cut open" in n for n in tpl.notes)
    closed = build_template(file_cfg(hopf_pdb))
    np.testing.assert_array_equal(tpl.positions, closed.positions)  # the same beads


def test_pdb_chains_without_conect_records_are_rings_with_a_note(hopf_pdb, tmp_path):
    bare = tmp_path / "bare.pdb"
    bare.write_text("".join(line for line in hopf_pdb.read_text().splitlines(True)
                            if not line.startswith("CONECT")))
    tpl = build_template(file_cfg(bare))
    assert tpl.layout.lengths == (30, 30) and tpl.layout.closed == (True, True)
    assert any("lists no bonds" in n and "2 PDB chains" in n for n in tpl.notes)


@pytest.fixture(scope="module")
def three_chains(tmp_path_factory):
    """A run directory of a Hopf link (2 x 20 beads) and an open rod of 12, written by the
    run's own writers, 5 frames 0.25 tau_d apart (the system falls and turns)."""
    cfg = RunConfig.from_dict({"chains": [
        {"kind": "knotinfo", "name": "hopf", "beads": 40},
        {"kind": "straight", "beads": 12, "offset": [0.0, 0.0, 5.0]},
    ]})
    x0 = build_template(cfg, identify="skip").positions
    turn = 0.2
    rot = np.array([[np.cos(turn), -np.sin(turn), 0], [np.sin(turn), np.cos(turn), 0],
                    [0, 0, 1]])
    frames = np.stack([x0 @ np.linalg.matrix_power(rot, k).T - [0.0, 0.0, 0.7 * k]
                       for k in range(5)])
    layout = ChainLayout((20, 20, 12), (True, True, False))
    record = ("[knotmm]\nframe_interval = 0.25\n[knotmm.layout]\nlengths = [20, 20, 12]\n"
              "closed = [true, true, false]\n")
    directory = write_system_run(tmp_path_factory.mktemp("three") / "run", frames, layout,
                                 0.25, record)
    return directory, frames


@pytest.mark.parametrize("where", ["directory", "trajectory.dcd", "topology.pdb"])
def test_three_chains_with_an_open_one_read_back_from_a_run(three_chains, where):
    directory, frames = three_chains
    path = directory if where == "directory" else directory / where
    frame = 0 if where == "topology.pdb" else -1
    tpl = build_template(file_cfg(path, frame=frame))
    lengths, closed = (20, 20, 12), (True, True, False)
    assert tpl.layout.lengths == lengths and tpl.layout.closed == closed
    assert system_bonds(file_cfg(path, frame=frame)) == allowed_pairs(lengths, closed)
    x = frames[frame]
    np.testing.assert_allclose(tpl.positions, x - x.mean(axis=0), atol=1e-4)
    a, b, _ = chains_of(tpl.positions, lengths)
    lk = rm.gauss_linking(a, b)
    assert abs(abs(lk) - 1.0) < 0.05
    assert tpl.chain_facts["linking_numbers"] == {"A-B": round(lk)}  # the rod has none
    assert tpl.parts[2].knot_type is None and tpl.parts[2].layout.closed == (False,)
    facts = tpl.facts
    assert [c["closed"] for c in facts["chains"]] == list(closed)
    source = facts["started_from"]
    if where == "topology.pdb":  # the run's start
        assert (source["frame"], source["frames"], source["time"]) == (0, 1, 0.0)
    else:  # the last of 5 frames 0.25 tau_d apart
        assert (source["frame"], source["frames"]) == (4, 5)
        assert source["time"] == pytest.approx(1.0)
    assert source["run"] == str(directory.resolve())


def test_a_run_whose_run_toml_records_other_chains_is_refused_in_one_line(three_chains,
                                                                           tmp_path):
    directory, _ = three_chains
    copy = tmp_path / "run"
    copy.mkdir()
    for f in directory.iterdir():
        (copy / f.name).write_bytes(f.read_bytes())
    text = (copy / "run.toml").read_text()
    (copy / "run.toml").write_text(text.replace("closed = [true, true, false]",
                                                "closed = [true, true, true]"))
    with pytest.raises(TrajectoryFileError, match=r"knot\.path: .*run\.toml.*\[knotmm\.layout\]"
                                                  r".*disagrees with the run's chains") as info:
        build_template(file_cfg(copy, frame=-1))
    assert "\n" not in str(info.value)


def test_the_old_failures_of_a_link_file_are_gone(hopf_pdb, capsys):
    """``knotmm template file:hopf.pdb`` read one 60-bead chain with a 1.33 d bond, or
    refused it with advice that would join the components ("CONECT    1   60")."""
    capsys.readouterr()
    assert main(["template", f"file:{hopf_pdb}"]) == 0
    out = capsys.readouterr()
    text = out.out + out.err
    assert "60 in 2 chains" in text
    assert "CONECT" not in text and "join" not in text and "1.33" not in text
    bonds = [float(v) for v in re.findall(r"bonds (\d\.\d+) - (\d\.\d+) d", text)[0]]
    assert max(bonds) < 0.61
