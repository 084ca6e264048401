"""The bead Topology: the one description of a knotmm system's atoms and bonds.

A knotmm chain is one PDB chain of beads (``A``, then ``B``, ... for the further chains of a
:class:`knotmm.model.layout.ChainLayout`, named by :func:`knotmm.model.layout.chain_ids`
without limit: ``AA``, ``AB``, ... past 62 chains), one residue ``BEA`` per bead (numbered from 1 in
each chain), one atom ``B`` per residue (element carbon, only so that viewers draw it), bead
``i`` bonded to bead ``i + 1`` and, in a ring, the last bead bonded to the first. The
residue name is non-standard on purpose: mdtraj writes ``CONECT`` records only for
non-standard residues, and without them VMD draws no chain. The engine, the PDB writer
(:mod:`knotmm.io.pdb`, through ``mdtraj.Topology.from_openmm``) and the synthetic run
directories all use :func:`bead_topology`; see ``docs/architecture.md``.
"""

from __future__ import annotations

import openmm.app

from knotmm.model.layout import ChainLayout

__all__ = ["BEAD_ATOM", "BEAD_RESIDUE", "bead_topology"]

#: Residue name of a bead (non-standard, so that mdtraj writes CONECT records).
BEAD_RESIDUE = "BEA"
#: Atom name of a bead.
BEAD_ATOM = "B"


def bead_topology(n_beads: int | ChainLayout, closed: bool = True) -> openmm.app.Topology:
    """The OpenMM Topology of a bead chain, or of the chains of a layout.

    Parameters
    ----------
    n_beads : int or ChainLayout
        Number of beads, at least 3 for a closed chain (2 for an open one); or the chains.
    closed : bool, optional
        If true (knotmm's chains), bead ``n_beads - 1`` is bonded back to bead 0 (ignored for
        a layout, which says it per chain).

    Returns
    -------
    openmm.app.Topology
        One chain ``A`` (``B``, ..., ``AA``, ... for a layout's further chains: the chain's
        name, :attr:`ChainLayout.ids`), residues ``BEA``
        numbered from 1 in each chain, one atom ``B`` (carbon) each, the bonds of
        :meth:`ChainLayout.bonds` (``i -> i + 1`` and, if ``closed``, ``n_beads - 1 -> 0``).

    Raises
    ------
    ValueError
        For a bead count that is not an integer or too small.
    """
    if isinstance(n_beads, ChainLayout):
        return _layout_topology(n_beads)
    try:  # the layout checks the count
        layout = ChainLayout((n_beads,), (bool(closed),))
    except ValueError as exc:
        raise ValueError(f"n_beads={n_beads!r}: {str(exc).split(': ', 1)[-1]}") from None
    return _layout_topology(layout)


def _layout_topology(layout: ChainLayout) -> openmm.app.Topology:
    top = openmm.app.Topology()
    element = openmm.app.Element.getBySymbol("C")
    atoms = []
    for cid, n in zip(layout.ids, layout.lengths, strict=True):
        chain = top.addChain(cid)
        for i in range(n):
            res = top.addResidue(BEAD_RESIDUE, chain, id=str(i + 1))
            atoms.append(top.addAtom(BEAD_ATOM, element, res))
    for i, j in layout.bonds():
        top.addBond(atoms[int(i)], atoms[int(j)])
    return top
