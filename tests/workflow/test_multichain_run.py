"""Runs of several chains: [[chains]] run files, links, open filaments; their files, their
resume and their refusals."""

from __future__ import annotations

import re
import types

import mdtraj
import numpy as np
import pytest
import reference_model as rm

from knotmm.cli.main import main
from knotmm.config import RunConfig
from knotmm.engine.knot_checks import LinkingWatch
from knotmm.io.rundir import read_facts
from knotmm.model.layout import ChainLayout
from knotmm.workflow import resume, run

TWO_RINGS = {
    "chains": [
        {"kind": "torus", "p": 2, "q": 3, "beads": 40, "offset": [-3.5, 0.0, 0.0]},
        {"kind": "torus", "p": 2, "q": 3, "beads": 30, "offset": [3.5, 0.0, 0.0],
         "mirror": True, "rotation": [1.0, 0.0, 0.0, 90.0]},
        {"kind": "straight", "beads": 12, "offset": [0.0, 0.0, 4.0]},
    ],
    "run": {"duration": 3.0, "topology_check_interval": 0.0},
    "output": {"frame_interval": 0.125, "checkpoint_interval": 1.0},
}


@pytest.fixture(scope="module")
def system_run(tmp_path_factory):
    directory = tmp_path_factory.mktemp("chains") / "run"
    run(RunConfig.from_dict(TWO_RINGS), directory=directory, progress=False)
    return directory


def test_the_files_of_a_run_of_two_knots_and_a_rod(system_run):
    facts = read_facts(system_run)
    assert facts["status"] == "finished"
    assert ChainLayout.from_record(facts["layout"], 82) == ChainLayout((40, 30, 12),
                                                                        (True, True, False))
    chains = facts["chains"]
    assert [c["id"] for c in chains] == ["A", "B", "C"]
    assert chains[0]["template_knot_type"] in ("+3_1", None)
    traj = mdtraj.load(str(system_run / "trajectory.dcd"), top=str(system_run / "topology.pdb"))
    assert traj.n_atoms == 82 and traj.n_frames == 25
    assert [c.n_atoms for c in traj.topology.chains] == [40, 30, 12]
    bonds = {tuple(sorted((b[0].index, b[1].index))) for b in traj.topology.bonds}
    assert len(bonds) == 40 + 30 + 11
    assert (0, 39) in bonds and (40, 69) in bonds and (70, 81) not in bonds
    # CONECT records close each ring in the PDB file itself (VMD reads those)
    conect = [line for line in (system_run / "topology.pdb").read_text().splitlines()
              if line.startswith("CONECT")]
    assert conect, "no CONECT records"
    assert "Chain" in (system_run / "view.vmd").read_text()
    # the rings start where the offsets put them (mdtraj's nm are d: d = 10 Angstrom)
    x0 = traj.xyz[0]
    centres = [x0[sl].mean(axis=0) for sl in (slice(0, 40), slice(40, 70))]
    assert centres[1][0] - centres[0][0] == pytest.approx(7.0, abs=1e-3)
    assert facts["mean_sedimentation_velocity"] > 0


def test_a_resumed_system_run_equals_the_uninterrupted_one(system_run, tmp_path):
    cfg = RunConfig.from_dict({**TWO_RINGS, "run": {**TWO_RINGS["run"], "duration": 1.5}})
    part = tmp_path / "part"
    run(cfg, directory=part, progress=False)
    resume(part, progress=False, duration=3.0)
    a = mdtraj.load(str(system_run / "trajectory.dcd"), top=str(system_run / "topology.pdb"))
    b = mdtraj.load(str(part / "trajectory.dcd"), top=str(part / "topology.pdb"))
    assert a.n_frames == b.n_frames
    np.testing.assert_array_equal(a.xyz, b.xyz)


def test_a_hopf_link_keeps_its_linking_number_through_a_run(tmp_path):
    cfg = RunConfig.from_dict({
        "knot": {"kind": "knotinfo", "name": "hopf", "beads": 60},
        "run": {"duration": 4.0, "topology_check_interval": 0.5},
        "output": {"frame_interval": 1.0},
    })
    run(cfg, directory=tmp_path / "hopf", progress=False)
    facts = read_facts(tmp_path / "hopf")
    assert facts["linking_numbers"] == {"A-B": 1}
    assert facts["linking_numbers_now"] == {"A-B": 1}
    assert facts["linking_checks"] == 8 and facts["linking_number_changes"] == []
    traj = mdtraj.load(str(tmp_path / "hopf" / "trajectory.dcd"),
                       top=str(tmp_path / "hopf" / "topology.pdb"))
    last = traj.xyz[-1]
    assert abs(rm.gauss_linking(last[:30], last[30:]) - 1.0) < 0.05


def test_the_linking_watch_sees_two_rings_pass_apart():
    a = rm.circle(20)
    linked = np.vstack([a, rm.circle(20)[:, [0, 2, 1]] + [1.9, 0, 0]])
    apart = np.vstack([a, rm.circle(20)[:, [0, 2, 1]] + [8.0, 0, 0]])
    assert rm.gauss_linking(linked[:20], linked[20:]) == pytest.approx(1, abs=0.05) or \
        rm.gauss_linking(linked[:20], linked[20:]) == pytest.approx(-1, abs=0.05)
    watch = LinkingWatch(1.0, ChainLayout((20, 20)))
    sim = types.SimpleNamespace(positions=linked, time=1.0, currentStep=10)
    watch.report(sim, None)
    first = watch.current["A-B"]
    assert abs(first) == 1
    sim.positions, sim.time = apart, 2.0
    watch.report(sim, None)
    assert watch.changes == [(2.0, "A-B", first, 0)] and watch.checks == 2


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[[chains]]\nbeads = 40\n[[chains]]\nbeads = 40\n",
         r"chains\[0\] and chains\[1\] overlap"),
        ("[[chains]]\nbeads = 40\noffset = [1.0, 2.0]\n", r"chains\[0\]\.offset"),
        ("[knot]\nbeads = 40\n[[chains]]\nbeads = 40\n", r"\[knot\].*\[\[chains\]\]"),
        ("[knot]\nkind = 'helix'\nclosed = true\nbeads = 40\n", r"knot\.kind='helix'"),
        ("[knot]\nkind = 'torus'\np = 2\nq = 4\nbeads = 61\n", r"knot\.beads = 60 or 62"),
    ],
)
def test_bad_system_run_files_are_one_line_exit_2(tmp_path, capsys, text, message):
    path = tmp_path / "bad.toml"
    path.write_text(text + f"[output]\ndirectory = {str(tmp_path / 'out')!r}\n")
    assert main(["run", str(path), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("knotmm: error: "), err
    assert re.search(message, err[0]), err[0]
    assert not (tmp_path / "out" / "trajectory.dcd").exists()


def test_orbit_refuses_a_run_of_several_chains_in_one_line(system_run, capsys):
    assert main(["orbit", str(system_run)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "handles one closed chain" in err[0] and "3 chains" in err[0]


def test_the_analysis_of_the_system_names_each_chain(system_run):
    from knotmm.analysis.core import analyze_run

    d = analyze_run(system_run, plots=False, knot_samples=0).to_dict()
    assert [c["id"] for c in d["chains"]] == ["A", "B", "C"]
    assert [c["closed"] for c in d["chains"]] == [True, True, False]
    assert len(d["system"]["pairs"]) == 3
    assert d["system"]["linking_numbers"] == {"A-B": 0}
    for c in d["chains"]:
        assert c["sedimentation_velocity"] > 0


def test_the_knot_watch_names_each_ring_in_chain_order(tmp_path):
    pytest.importorskip("topoly")
    settings = {**TWO_RINGS, "run": {"duration": 2.0, "topology_check_interval": 1.0}}
    run(RunConfig.from_dict(settings), directory=tmp_path / "w", progress=False,
        wait_for_checks=True)
    facts = read_facts(tmp_path / "w")
    # ring A is the right-handed trefoil, ring B its mirror image; the rod has no type
    assert facts["knot_type_start"] == "+3_1, -3_1"
    assert facts["knot_type_checks"] == 2 and facts["knot_type_changes"] == []


def test_a_change_of_one_ring_is_a_change_of_the_system():
    from knotmm.engine.knot_checks import ChainsIdentifier
    from knotmm.engine.reporters import KnotTypeWatch

    class Fake:  # names a ring by its first bead's x: > 0 "+3_1", else "0_1"
        def submit(self, x):
            value = "+3_1" if x[0, 0] > 0 else "0_1"
            return types.SimpleNamespace(done=lambda: True, result=lambda: value)

        def start(self):
            pass

    layout = ChainLayout((4, 3, 5), (True, False, True))
    watch = KnotTypeWatch(1.0, identify=ChainsIdentifier(Fake(), layout))
    x = np.ones((12, 3))
    sim = types.SimpleNamespace(positions=x, time=1.0, currentStep=1)
    watch.report(sim, None)
    x2 = x.copy()
    x2[7, 0] = -1.0  # the third chain (beads 7-11), the second ring
    sim.positions, sim.time = x2, 2.0
    watch.report(sim, None)
    watch.collect(wait=True)
    assert watch.changes == [(2.0, "+3_1, +3_1", "+3_1, 0_1")]
