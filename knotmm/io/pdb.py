"""PDB files of bead chains: the topology every knotmm file shares, and a writer.

A knotmm chain is one chain of beads, one residue ``BEA`` per bead, one atom ``B`` per
residue (element carbon, only so that viewers draw it), bead ``i`` bonded to bead ``i + 1``
and the last bead bonded to the first. The residue name is non-standard on purpose: mdtraj
writes ``CONECT`` records only for non-standard residues, and without them VMD draws no
chain. Lengths are converted from model units (d) to Angstrom (1 d = 10 A) here, at the file
boundary, and no unit cell is written (the runs are not periodic).

Examples
--------
>>> import numpy as np, tempfile, os
>>> x = np.array([[0.0, 0.0, 0.0], [0.6, 0.0, 0.0], [0.3, 0.5, 0.0]])
>>> path = os.path.join(tempfile.mkdtemp(), "ring.pdb")
>>> write_pdb(path, x)
>>> sum(line.startswith("CONECT") for line in open(path))
3
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np

from knotmm.units import ANGSTROM_PER_D

__all__ = ["BEAD_RESIDUE", "BEAD_ATOM", "bead_topology", "write_pdb"]

logger = logging.getLogger(__name__)

#: Residue name of a bead (non-standard, so that mdtraj writes CONECT records).
BEAD_RESIDUE = "BEA"
#: Atom name of a bead.
BEAD_ATOM = "B"
# mdtraj keeps coordinates in nm; a PDB file holds Angstrom.
_NM_PER_ANGSTROM = 0.1


def bead_topology(n_beads: int, closed: bool = True):
    """The mdtraj Topology of a closed bead chain.

    Parameters
    ----------
    n_beads : int
        Number of beads, at least 3 for a closed chain (2 for an open one).
    closed : bool, optional
        If true (knotmm's chains), bead ``n_beads - 1`` is bonded back to bead 0.

    Returns
    -------
    mdtraj.Topology
        One chain, ``n_beads`` residues ``BEA`` numbered from 1, one atom ``B`` (carbon) each,
        bonds ``i -> i + 1`` and, if ``closed``, ``n_beads - 1 -> 0``.
    """
    import mdtraj  # noqa: PLC0415 - heavy import kept out of module import

    if isinstance(n_beads, bool) or not isinstance(n_beads, (int, np.integer)):
        raise ValueError(f"n_beads={n_beads!r}: expected an integer")
    minimum = 3 if closed else 2
    if n_beads < minimum:
        raise ValueError(
            f"n_beads={n_beads}: a {'closed' if closed else 'open'} chain needs "
            f"at least {minimum} beads"
        )
    top = mdtraj.Topology()
    chain = top.add_chain()
    atoms = []
    for i in range(int(n_beads)):
        residue = top.add_residue(BEAD_RESIDUE, chain, resSeq=i + 1)
        atoms.append(top.add_atom(BEAD_ATOM, mdtraj.element.carbon, residue))
    for i in range(int(n_beads) - 1):
        top.add_bond(atoms[i], atoms[i + 1])
    if closed:
        top.add_bond(atoms[-1], atoms[0])
    return top


def write_pdb(path, positions, closed: bool = True) -> None:
    """Write bead positions as a PDB file with CONECT records for every bond.

    Parameters
    ----------
    path : str or Path
        File to write (overwritten).
    positions : array_like, shape (n_beads, 3) or (n_frames, n_beads, 3), in d
        Bead coordinates in model units; written in Angstrom (x 10). Several frames are
        written as MODEL records.
    closed : bool, optional
        If true, the ring-closing bond ``n_beads - 1 -> 0`` is included.

    Raises
    ------
    ValueError
        For a wrong shape or non-finite coordinates.
    OSError
        If the file cannot be written.
    """
    import mdtraj  # noqa: PLC0415

    x = np.asarray(positions, dtype=np.float64)
    if x.ndim == 2:
        x = x[None]
    if x.ndim != 3 or x.shape[-1] != 3:
        raise ValueError(
            f"positions has shape {np.shape(positions)}: expected (n_beads, 3) or "
            "(n_frames, n_beads, 3)"
        )
    if not np.all(np.isfinite(x)):
        raise ValueError("positions contains non-finite coordinates")
    n_beads = x.shape[1]
    top = bead_topology(n_beads, closed=closed)
    xyz_nm = x * ANGSTROM_PER_D * _NM_PER_ANGSTROM
    traj = mdtraj.Trajectory(xyz_nm, top)  # no unit cell
    path = Path(path)
    traj.save_pdb(os.fspath(path))
    n_bonds = n_beads if closed else n_beads - 1
    _check_conect(path, n_beads, n_bonds, closed)
    logger.debug("wrote %s: %d frames of %d beads", path, x.shape[0], n_beads)


def _check_conect(path: Path, n_beads: int, n_bonds: int, closed: bool) -> None:
    """Make sure the written file carries every bond; append CONECT lines if not."""
    bonds = set()
    lines = path.read_text().splitlines()
    for line in lines:
        if line.startswith("CONECT"):
            fields = [line[i : i + 5] for i in range(6, len(line), 5)]
            serials = [int(f) for f in fields if f.strip()]
            if serials:
                a = serials[0]
                for b in serials[1:]:
                    bonds.add((min(a, b), max(a, b)))
    wanted = {(i + 1, i + 2) for i in range(n_beads - 1)}
    if closed:
        wanted.add((1, n_beads))
    missing = sorted(wanted - bonds)
    if not missing:
        return
    logger.debug("adding %d CONECT records mdtraj did not write", len(missing))
    extra = [f"CONECT{a:5d}{b:5d}" for a, b in missing]
    if lines and lines[-1].strip() == "END":
        lines = lines[:-1] + extra + ["END"]
    else:
        lines = lines + extra + ["END"]
    path.write_text("\n".join(lines) + "\n")
