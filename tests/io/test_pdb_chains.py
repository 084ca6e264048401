"""PDB files of many chains, read back by their CONECT records (BUG-15); a file of several
chains is read as those chains, never as one (BUG-24, issue 34); topology.pdb is written
whole or not at all."""

from __future__ import annotations

import errno

import mdtraj
import numpy as np
import pytest

import knotmm.io.pdb as pdb
from knotmm.errors import TemplateError
from knotmm.io.pdb import write_pdb
from knotmm.io.structure import read_structure
from knotmm.model.layout import ChainLayout


def _layout() -> ChainLayout:
    """70 open chains of 4 beads."""
    return ChainLayout((4,) * 70, (False,) * 70)


def _rods() -> np.ndarray:
    """70 straight rods of 4 beads, 0.6 d bonds, on a 6 d grid, shape (280, 3), in d."""
    rod = np.c_[np.arange(4) * 0.6, np.zeros(4), np.zeros(4)]
    return np.concatenate([rod + [0.0, 6.0 * (c % 10), 6.0 * (c // 10)] for c in range(70)])


def test_seventy_chains_are_written_and_read_back_as_seventy(tmp_path):
    path = tmp_path / "rods.pdb"
    rods = _layout()
    write_pdb(path, _rods(), layout=rods)
    assert pdb.read_layout(path) == rods
    top = mdtraj.load(str(path)).topology
    assert top.n_chains == 70 and [c.n_atoms for c in top.chains] == [4] * 70
    assert top.n_bonds == 70 * 3
    segments = [c.residue(0).segment_id for c in top.chains]
    assert segments == list(rods.ids) and len(set(segments)) == 70  # VMD's segname
    chain_ids = [c.chain_id for c in top.chains]
    assert chain_ids == list(rods.pdb_chain_ids) and chain_ids[62] == "A"


def test_one_ring_reads_back_as_one_ring(tmp_path):
    x = np.c_[np.cos(np.arange(12) / 12 * 2 * np.pi), np.sin(np.arange(12) / 12 * 2 * np.pi),
              np.zeros(12)] * 1.2
    write_pdb(tmp_path / "ring.pdb", x)
    assert pdb.read_layout(tmp_path / "ring.pdb") == ChainLayout.ring(12)
    assert pdb.read_layout(tmp_path / "missing.pdb") is None


def test_a_file_of_two_chains_is_read_as_two_chains_never_joined(tmp_path):
    x = _rods()[:8] + 0.0
    layout = ChainLayout((4, 4), (True, False))
    write_pdb(tmp_path / "two.pdb", x, layout=layout)
    mdtraj.load(str(tmp_path / "two.pdb")).save_dcd(str(tmp_path / "two.dcd"))
    for name in ("two.pdb", "two.dcd"):
        s = read_structure(tmp_path / name)
        assert s.layout == layout and s.pdb_chains == (4, 4)
        np.testing.assert_allclose(s.positions, x, atol=1e-4)
    write_pdb(tmp_path / "one.pdb", x, layout=ChainLayout((8,), (True,)))
    s = read_structure(tmp_path / "one.pdb")
    assert s.ring_closed is True and s.layout == ChainLayout.ring(8)


def test_two_pdb_chains_with_bonds_of_no_bead_chain_are_refused_in_one_line(tmp_path):
    path = tmp_path / "odd.pdb"
    write_pdb(path, _rods()[:8], layout=ChainLayout((4, 4), (False, False)))
    text = path.read_text().replace("END\n", "CONECT    1    7\nEND\n")  # a bond across
    path.write_text(text)
    with pytest.raises(TemplateError, match=r"2 PDB chains whose bonds .*does not join") as info:
        read_structure(path)
    assert "\n" not in str(info.value)


def test_a_pdb_that_cannot_be_finished_leaves_the_old_file(tmp_path, monkeypatch):
    path = tmp_path / "topology.pdb"
    write_pdb(path, _rods()[:12], layout=ChainLayout((4, 4, 4), (False,) * 3))
    before = path.read_bytes()

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(pdb, "_check_conect", full)
    with pytest.raises(OSError, match="No space left"):
        write_pdb(path, _rods()[:8], layout=ChainLayout((4, 4), (False, False)))
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["topology.pdb"]
