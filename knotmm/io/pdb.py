"""PDB files of bead chains, written with the one bead Topology.

Every knotmm PDB holds the Topology of :func:`knotmm.model.topology.bead_topology` (one chain
of ``BEA`` residues, one atom ``B`` each, the ring closed from the last bead to the first),
converted to mdtraj's form by :func:`mdtraj_topology`. A system of several chains writes one
PDB chain per chain: the one-character chain identifiers repeat after 62 chains
(:attr:`~knotmm.model.layout.ChainLayout.pdb_chain_ids`), and each chain's unique name is its
segment name (columns 73-76, which VMD reads as ``segname``). Chains are told apart by their
CONECT records: :func:`read_layout` reads them back. Lengths are converted from model units
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

from knotmm.io.atomic import replacing
from knotmm.model.layout import ChainLayout
from knotmm.model.topology import bead_topology
from knotmm.units import d_to_mdtraj

__all__ = ["mdtraj_topology", "read_layout", "write_pdb"]

logger = logging.getLogger(__name__)


def mdtraj_topology(n_beads: int | ChainLayout, closed: bool = True):
    """The bead Topology (:func:`knotmm.model.topology.bead_topology`, same arguments: a bead
    count or a :class:`~knotmm.model.layout.ChainLayout`) as an mdtraj Topology.

    Several chains get their one-character PDB chain identifiers (repeating after 62) and
    their unique names as segment names."""
    import mdtraj  # noqa: PLC0415 - heavy import kept out of module import

    top = mdtraj.Topology.from_openmm(bead_topology(n_beads, closed=closed))
    if isinstance(n_beads, ChainLayout) and n_beads.n_chains > 1:
        for chain, pdb_id, name in zip(top.chains, n_beads.pdb_chain_ids, n_beads.ids,
                                       strict=True):
            chain.chain_id = pdb_id
            for residue in chain.residues:
                residue.segment_id = name
    return top


def read_layout(path) -> ChainLayout | None:
    """The chains of a knotmm PDB file, from its CONECT records.

    Parameters
    ----------
    path : str or Path
        A PDB file written by :func:`write_pdb` (a run's ``topology.pdb``).

    Returns
    -------
    ChainLayout or None
        The layout whose bonds are the file's (:meth:`ChainLayout.from_bonds`); ``None`` if
        the file cannot be read, lists no bonds, or its bonds are not those of bead chains.
    """
    try:
        lines = Path(path).read_text(errors="replace").splitlines()
        serials, pairs = _atoms_and_conect(lines)
    except (OSError, ValueError):
        return None
    index = {serial: i for i, serial in enumerate(serials)}
    if len(index) != len(serials):  # serials repeat (past 99999 atoms): not readable here
        return None
    try:
        bonds = [(index[a], index[b]) for a, b in pairs]
    except KeyError:
        return None
    return ChainLayout.from_bonds(len(serials), bonds)


def _atoms_and_conect(lines: list[str]) -> tuple[list[int], set[tuple[int, int]]]:
    """The atom serials of the first model, in order, and the bonded serial pairs of the
    CONECT records (each pair sorted)."""
    serials = []  # TER records between chains take serials too
    for line in lines:
        if line.startswith(("ATOM", "HETATM")):
            serials.append(int(line[6:11]))
        if line.startswith("ENDMDL"):
            break
    bonds = set()
    for line in lines:
        if line.startswith("CONECT"):
            fields = [line[i : i + 5] for i in range(6, len(line), 5)]
            numbers = [int(f) for f in fields if f.strip()]
            if numbers:
                a = numbers[0]
                for b in numbers[1:]:
                    bonds.add((min(a, b), max(a, b)))
    return serials, bonds


def write_pdb(path, positions, closed: bool = True, layout: ChainLayout | None = None) -> None:
    """Write bead positions as a PDB file with CONECT records for every bond.

    Parameters
    ----------
    path : str or Path
        File to write (replaced atomically: its old content or the whole new one).
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
    traj = mdtraj.Trajectory(d_to_mdtraj(x), top)  # no unit cell
    path = Path(path)
    with replacing(path) as tmp:  # whole or not at all
        traj.save_pdb(os.fspath(tmp))
        _check_conect(tmp, layout)
    logger.debug("wrote %s: %d frames of %d beads", path, x.shape[0], n_beads)


def _check_conect(path: Path, layout: ChainLayout) -> None:
    """Make sure the written file carries every bond; append CONECT lines if not."""
    lines = path.read_text().splitlines()
    atom_serials, bonds = _atoms_and_conect(lines)
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
