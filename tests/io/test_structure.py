"""Reading a start frame from PDB/DCD files (knotmm.io.structure)."""

from __future__ import annotations

import mdtraj
import numpy as np
import pytest

from knotmm.errors import TemplateError, TrajectoryFileError
from knotmm.io.pdb import mdtraj_topology, write_pdb
from knotmm.io.structure import read_structure, ring_closed


def _ring(n=20, seed=0):
    t = 2 * np.pi * np.arange(n) / n
    x = np.stack([3 * np.cos(t), 3 * np.sin(t), np.zeros(n)], axis=1)
    return x + np.random.default_rng(seed).normal(scale=0.05, size=x.shape)


def test_pdb_frame_in_d(tmp_path):
    frames = np.stack([_ring(seed=0), _ring(seed=1)])
    write_pdb(tmp_path / "two.pdb", frames)
    s = read_structure(tmp_path / "two.pdb", frame=-1)
    assert s.frame == 1 and s.n_frames == 2 and s.ring_closed is True
    # PDB keeps 3 decimals of Angstrom: 1e-4 d
    np.testing.assert_allclose(s.positions, frames[1], atol=1e-4)
    assert s.positions.dtype == np.float64


def test_dcd_frame_and_its_topology(tmp_path):
    frames = np.stack([_ring(seed=k) for k in range(4)])
    write_pdb(tmp_path / "traj.pdb", frames[0])
    # mdtraj keeps nm and 1 d reads as 1 nm: the DCD holds Angstrom = 10 x d
    mdtraj.Trajectory(frames, mdtraj_topology(20)).save_dcd(str(tmp_path / "traj.dcd"))
    s = read_structure(tmp_path / "traj.dcd", frame=2)
    assert s.n_frames == 4 and s.frame == 2 and s.ring_closed is True
    np.testing.assert_allclose(s.positions, frames[2], atol=1e-5)


def test_ring_closure_is_read_from_the_bonds(tmp_path):
    write_pdb(tmp_path / "open.pdb", _ring(), closed=False)
    assert read_structure(tmp_path / "open.pdb").ring_closed is False
    assert ring_closed(mdtraj_topology(5, closed=False)) is False
    assert ring_closed(mdtraj_topology(5)) is True
    assert ring_closed(mdtraj.Topology()) is None


def test_errors_name_the_caller_argument(tmp_path):
    names = {"path": "knot.path", "frame": "knot.frame", "topology": "knot.topology"}
    with pytest.raises(TrajectoryFileError, match=r"^knot\.path=.*not found"):
        read_structure(tmp_path / "none.pdb", names=names)
    write_pdb(tmp_path / "r.pdb", _ring())
    with pytest.raises(TemplateError, match=r"^knot\.frame=5 is out of range"):
        read_structure(tmp_path / "r.pdb", frame=5, names=names)
    with pytest.raises(TemplateError, match=r"^frame=1.5: expected an integer"):
        read_structure(tmp_path / "r.pdb", frame=1.5)


def test_a_replica_set_is_named_as_such(tmp_path):
    (tmp_path / "set").mkdir()
    (tmp_path / "set" / "replicas.toml").write_text("")
    with pytest.raises(TrajectoryFileError, match=r"is a set of replicas; give one of them, "
                                                  r"e\.g\. '.*replica_0'"):
        read_structure(tmp_path / "set")
