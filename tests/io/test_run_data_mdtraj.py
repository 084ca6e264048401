"""RunData in a notebook: its one-line repr and RunData.to_mdtraj (units, centring, bonds)."""

from __future__ import annotations

import mdtraj
import numpy as np
import pytest
from synthetic import vortex_knot_positions, write_run_directory

import knotmm
from knotmm.io.run_data import RunData, load_run
from knotmm.units import ANGSTROM_PER_D, PS_PER_TAU

DT = 0.5
N_FRAMES = 9


@pytest.fixture(scope="module")
def positions():
    times = np.arange(N_FRAMES) * DT
    x = vortex_knot_positions(times, n_beads=24, rho0=1.5, swirl_amplitude=0.3)
    return x + np.array([0.3, -0.2, 0.0])  # off the axis: centring has something to remove


@pytest.fixture(scope="module")
def run(tmp_path_factory, positions):
    config = {"knot": {"kind": "torus", "p": 2, "q": 3}, "model": {"bond_length": 0.6}}
    return write_run_directory(tmp_path_factory.mktemp("mdtraj") / "run", positions, DT, config)


def test_load_run_at_the_top_is_the_io_one(run):
    assert knotmm.load_run is load_run
    assert isinstance(knotmm.load_run(run), RunData)
    assert "load_run" in knotmm.__all__ and "load_run" in dir(knotmm)


def test_repr_is_one_short_line(run):
    text = repr(load_run(run))
    assert "\n" not in text and len(text) < 200 and "array" not in text
    assert str(run) in text
    assert f"{N_FRAMES} frames" in text
    assert f"t = 0 to {(N_FRAMES - 1) * DT:g} tau_d every {DT:g}" in text
    assert "24 beads, 1 closed chain" in text


def test_repr_of_arrays_open_chains_and_one_frame():
    x = np.zeros((1, 10, 3))
    x[0, :, 0] = 0.6 * np.arange(10)
    two_open = [[i, i + 1] for i in range(4)] + [[i, i + 1] for i in range(5, 9)]
    text = repr(RunData.from_arrays(x, 0.25, bonds=two_open))
    assert text.startswith("RunData(in-memory trajectory: 1 frame, t = 0 to 0 tau_d")
    assert "10 beads, 2 chains (0 closed)" in text
    assert "1 open chain" in repr(RunData.from_arrays(x, 0.25, bonds=two_open[:4] + [[4, 5]]
                                                      + two_open[4:]))


def test_coordinates_are_the_files_angstrom(run, positions):
    data = load_run(run)
    traj = data.to_mdtraj(center=False)
    assert isinstance(traj, mdtraj.Trajectory)
    assert traj.n_frames == N_FRAMES and traj.n_atoms == 24
    # mdtraj holds nm; 10 A per nm, independently of knotmm's factor
    angstrom = traj.xyz.astype(np.float64) * 10.0
    np.testing.assert_allclose(angstrom, data.positions * ANGSTROM_PER_D, atol=1e-4)
    np.testing.assert_allclose(angstrom, positions * 10.0, atol=1e-3)  # 10 A per d, float32
    # the same numbers as mdtraj reading the run's own DCD and PDB
    ref = mdtraj.load(str(run / "trajectory.dcd"), top=str(run / "topology.pdb"))
    np.testing.assert_allclose(traj.xyz, ref.xyz, atol=1e-5)
    np.testing.assert_allclose(traj.time, data.times * PS_PER_TAU)
    assert traj.unitcell_vectors is None


def test_written_dcd_reads_back_in_angstrom(run, tmp_path):
    from mdtraj.formats import DCDTrajectoryFile

    path = tmp_path / "again.dcd"
    load_run(run).to_mdtraj(center=False).save_dcd(str(path))
    with DCDTrajectoryFile(str(path)) as fh:
        mine = fh.read()[0]
    with DCDTrajectoryFile(str(run / "trajectory.dcd")) as fh:
        theirs = fh.read()[0]
    np.testing.assert_allclose(mine, theirs, atol=1e-3)  # Angstrom, as the run wrote them


def test_center_puts_the_centre_of_mass_at_the_origin(run):
    data = load_run(run)
    centred = data.to_mdtraj().xyz.astype(np.float64)
    raw = data.to_mdtraj(center=False).xyz.astype(np.float64)
    n = data.n_beads
    for k in range(data.n_frames):
        com = [sum(centred[k, i, axis] for i in range(n)) / n for axis in range(3)]
        np.testing.assert_allclose(com, 0.0, atol=1e-5)
        # a rigid shift: every bead moved by the same vector, the raw frame's mean
        shift = raw[k] - centred[k]
        np.testing.assert_allclose(shift, np.broadcast_to(shift[0], shift.shape), atol=1e-5)
        np.testing.assert_allclose(shift[0], raw[k].mean(axis=0), atol=1e-5)
    assert np.abs(raw.mean(axis=1)).max() > 0.1  # there was something to remove


def test_topology_has_the_runs_bonds(run):
    data = load_run(run)
    top = data.to_mdtraj().topology
    assert top.n_bonds == len(data.bonds) == 24
    bonds = {tuple(sorted((a.index, b.index))) for a, b in top.bonds}
    assert bonds == {tuple(sorted(map(int, b))) for b in data.bonds}
    assert {(0, 23), (5, 6)} <= bonds
    assert top.n_chains == 1 and {r.name for r in top.residues} == {"BEA"}
    # laid out as the run's topology.pdb
    pdb = mdtraj.load_topology(str(run / "topology.pdb"))
    assert [c.chain_id for c in top.chains] == [c.chain_id for c in pdb.chains]
    assert [(a.name, a.residue.name, a.element) for a in top.atoms] == [
        (a.name, a.residue.name, a.element) for a in pdb.atoms]


def test_topology_of_several_open_chains():
    x = np.random.default_rng(3).normal(size=(2, 12, 3))
    first = [[i, i + 1] for i in range(6)]   # chain A: beads 0-6, open
    second = [[i, i + 1] for i in range(7, 11)] + [[7, 11]]   # chain B: 7-11, a ring
    data = RunData.from_arrays(x, 1.0, bonds=first + second)
    top = data.to_mdtraj().topology
    assert top.n_bonds == len(first) + len(second)
    assert [c.n_atoms for c in top.chains] == [7, 5]
    assert [c.chain_id for c in top.chains] == ["A", "B"]
    assert data.chains() == [(0, 7, False), (7, 5, True)]
