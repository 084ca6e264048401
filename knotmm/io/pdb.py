"""PDB files of bead chains, written with the one bead Topology.

Every knotmm PDB holds the Topology of :func:`knotmm.model.topology.bead_topology` (one chain
of ``BEA`` residues, one atom ``B`` each, the ring closed from the last bead to the first),
converted to mdtraj's form by :func:`mdtraj_topology`. Lengths are converted from model units
(d) to Angstrom (1 d = 10 A) here, at the file boundary, and no unit cell is written (the
runs are not periodic). See ``docs/model.md``.

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

from knotmm.model.layout import ChainLayout
from knotmm.model.topology import bead_topology
from knotmm.units import ANGSTROM_PER_D

__all__ = ["mdtraj_topology", "write_pdb"]

logger = logging.getLogger(__name__)

# mdtraj keeps coordinates in nm; a PDB file holds Angstrom.
_NM_PER_ANGSTROM = 0.1


def mdtraj_topology(n_beads: int | ChainLayout, closed: bool = True):
    """The bead Topology (:func:`knotmm.model.topology.bead_topology`, same arguments: a bead
    count or a :class:`~knotmm.model.layout.ChainLayout`) as an mdtraj Topology."""
    import mdtraj  # noqa: PLC0415 - heavy import kept out of module import

    return mdtraj.Topology.from_openmm(bead_topology(n_beads, closed=closed))


def write_pdb(path, positions, closed: bool = True, layout: ChainLayout | None = None) -> None:
    """Write bead positions as a PDB file with CONECT records for every bond.

    Parameters
    ----------
    path : str or Path
        File to write (overwritten).
    positions : array_like, shape (n_beads, 3) or (n_frames, n_beads, 3), in d
        Bead coordinates in model units; written in Angstrom (x 10). Several frames are
        written as MODEL records.
    closed : bool, optional
        If true, the ring-closing bond ``n_beads - 1 -> 0`` is included (one chain).
    layout : ChainLayout, optional
        The chains, one PDB chain each (``A``, ``B``, ...), with their bonds; overrides
        ``closed``.

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
    layout = ChainLayout((n_beads,), (bool(closed),)) if layout is None else layout
    if layout.n_beads != n_beads:
        raise ValueError(
            f"positions has {n_beads} beads, the chains ({layout.describe()}) {layout.n_beads}"
        )
    top = mdtraj_topology(layout)
    xyz_nm = x * ANGSTROM_PER_D * _NM_PER_ANGSTROM
    traj = mdtraj.Trajectory(xyz_nm, top)  # no unit cell
    path = Path(path)
    traj.save_pdb(os.fspath(path))
    _check_conect(path, layout)
    logger.debug("wrote %s: %d frames of %d beads", path, x.shape[0], n_beads)


def _check_conect(path: Path, layout: ChainLayout) -> None:
    """Make sure the written file carries every bond; append CONECT lines if not."""
    bonds = set()
    lines = path.read_text().splitlines()
    atom_serials = []  # serial of each bead (TER records between chains take serials too)
    for line in lines:
        if line.startswith(("ATOM", "HETATM")):
            atom_serials.append(int(line[6:11]))
        if line.startswith("ENDMDL"):
            break
    for line in lines:
        if line.startswith("CONECT"):
            fields = [line[i : i + 5] for i in range(6, len(line), 5)]
            serials = [int(f) for f in fields if f.strip()]
            if serials:
                a = serials[0]
                for b in serials[1:]:
                    bonds.add((min(a, b), max(a, b)))
    wanted = {
        tuple(sorted((atom_serials[i], atom_serials[j]))) for i, j in layout.bonds()
    }
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
