"""The one bead Topology (knotmm.model.topology) and its mdtraj form in PDB files."""

from __future__ import annotations

import numpy as np
import pytest

from knotmm.io.pdb import mdtraj_topology, write_pdb
from knotmm.model.topology import bead_topology


@pytest.mark.parametrize("n", [4, 5, 90])
def test_topology_is_a_ring_of_bea_residues(n):
    top = bead_topology(n)
    residues = list(top.residues())
    assert len(residues) == n and all(r.name == "BEA" for r in residues)
    assert top.getNumAtoms() == n and top.getNumChains() == 1
    bonds = {tuple(sorted((b[0].index, b[1].index))) for b in top.bonds()}
    assert len(bonds) == n
    assert bonds == {tuple(sorted((i, (i + 1) % n))) for i in range(n)}
    assert (0, n - 1) in bonds  # the closure
    assert top.getPeriodicBoxVectors() is None



def test_open_chain_has_no_closing_bond():
    top = bead_topology(5, closed=False)
    bonds = {tuple(sorted((b[0].index, b[1].index))) for b in top.bonds()}
    assert bonds == {(0, 1), (1, 2), (2, 3), (3, 4)}


@pytest.mark.parametrize("n", [2, 2.5, True])
def test_bad_bead_counts_are_refused(n):
    with pytest.raises(ValueError, match="n_beads"):
        bead_topology(n)


def test_mdtraj_form_matches_the_openmm_one():
    top = mdtraj_topology(7)
    assert [r.name for r in top.residues] == ["BEA"] * 7
    assert [r.resSeq for r in top.residues] == list(range(1, 8))
    assert [a.name for a in top.atoms] == ["B"] * 7
    assert {tuple(sorted((a.index, b.index))) for a, b in top.bonds} == {
        tuple(sorted((i, (i + 1) % 7))) for i in range(7)
    }


def test_pdb_file_carries_every_ring_bond(tmp_path):
    # read back with a plain parser, independent of mdtraj and OpenMM
    n = 12
    x = np.random.default_rng(3).normal(size=(n, 3))
    path = tmp_path / "ring.pdb"
    write_pdb(path, x)
    lines = path.read_text().splitlines()
    atoms = [ln for ln in lines if ln.startswith(("ATOM", "HETATM"))]
    assert [int(ln[22:26]) for ln in atoms] == list(range(1, n + 1))
    assert {ln[17:20] for ln in atoms} == {"BEA"}
    bonds = set()
    for ln in lines:
        if ln.startswith("CONECT"):
            serials = [int(ln[i : i + 5]) for i in range(6, len(ln), 5) if ln[i : i + 5].strip()]
            bonds |= {tuple(sorted((serials[0], s))) for s in serials[1:]}
    assert bonds == {tuple(sorted((i + 1, (i + 1) % n + 1))) for i in range(n)}
