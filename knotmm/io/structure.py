"""One frame of a PDB or DCD file as bead positions: the start of a ``kind = "file"`` run.

:func:`read_structure` reads frame ``frame`` of a PDB file (any MODEL) or of a DCD file with
its topology PDB, converts Angstrom to d (1 d = 10 A, ``docs/model.md``) and reads the
file's chains: from the bonds of its topology (CONECT records,
:meth:`knotmm.model.layout.ChainLayout.from_bonds`: a chain is a run of consecutive beads,
closed when its last bead is bonded to its first), so a knotmm ``topology.pdb`` of one ring,
several chains, open chains or a link reads back as written; chains are never joined into
one. A run directory stands for its ``trajectory.dcd`` and ``topology.pdb``, and its
``run.toml`` (its ``[knotmm.layout]``, checked against the bonds, and the frame interval,
which gives the frame's time). DCD frame counts and truncation come from
:func:`knotmm.io.dcd.dcd_layout`.

Errors name the argument as the caller knows it: ``names`` maps ``"path"``, ``"frame"`` and
``"topology"`` to the names used in messages (``knot.path`` for a run file, ``path`` for
:func:`knotmm.shapes.from_file`).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from knotmm.errors import KnotmmError, TemplateError, TrajectoryFileError
from knotmm.io.dcd import c_path, dcd_layout, quiet_c_stdout
from knotmm.io.replica_set import REPLICA_SET_FILE
from knotmm.io.rundir import RUN_FILE, TOPOLOGY_FILE, TRAJECTORY_FILE
from knotmm.model.layout import ChainLayout
from knotmm.units import angstrom_to_d, mdtraj_to_angstrom

__all__ = ["Structure", "read_structure", "ring_closed"]

logger = logging.getLogger(__name__)

_PLAIN = {"path": "path", "frame": "frame", "topology": "topology"}


@dataclass(frozen=True)
class Structure:
    """One frame read from a file, and the chains its topology holds.

    Attributes
    ----------
    positions : ndarray, shape (n_beads, 3), float64, in d
        As stored (not centred), in atom order.
    path : Path
        The file read (a run directory resolved to its ``trajectory.dcd``).
    frame : int
        The frame read, counted from 0.
    n_frames : int
        Complete frames in the file.
    ring_closed : bool or None
        ``True``: the topology bonds the last bead to the first; ``False``: it lists bonds
        but not that one; ``None``: it lists no bonds at all.
    layout : ChainLayout or None
        The chains by the topology's bonds (CONECT records; a run's ``[knotmm.layout]``
        agrees with them): each a run of consecutive beads, closed or open. ``None`` when
        the topology lists no bonds, or bonds that are not those of bead chains in atom
        order (then ``ring_closed`` and ``pdb_chains`` are all that is known).
    pdb_chains : tuple of int
        The bead count of each chain of the PDB topology (its chain records), in order.
    topology : Path or None
        The PDB read for a DCD's topology (``None`` for a PDB file).
    run_directory : Path or None
        The knotmm run directory the file belongs to (a ``run.toml`` beside its
        ``trajectory.dcd`` or ``topology.pdb``), else ``None``.
    frame_time : float or None
        The frame's time in that run, in tau_d (frame ``k`` at ``k`` frame intervals, the
        run's ``frame_interval``); ``None`` when not known.
    """

    positions: np.ndarray
    path: Path
    frame: int
    n_frames: int
    ring_closed: bool | None
    layout: ChainLayout | None = None
    pdb_chains: tuple[int, ...] = ()
    topology: Path | None = None
    run_directory: Path | None = None
    frame_time: float | None = None


def read_structure(
    path, frame: int = 0, topology=None, names: Mapping[str, str] | None = None
) -> Structure:
    """Read one frame of a PDB or DCD file, and its chains.

    Parameters
    ----------
    path : str or Path
        A PDB file, a DCD file (lengths in Angstrom) or a run directory (its
        ``trajectory.dcd`` with its ``topology.pdb``).
    frame : int, optional
        Frame index; negative counts from the end (-1: the last complete frame).
    topology : str or Path, optional
        The PDB belonging to a DCD file. Default: ``path`` with suffix ``.pdb``, or
        ``topology.pdb`` in the same folder.
    names : mapping, optional
        Names of ``path``, ``frame`` and ``topology`` in messages.

    Returns
    -------
    Structure

    Raises
    ------
    TrajectoryFileError
        For a missing, empty, truncated or unreadable file, a DCD whose atom count does
        not match its topology, or a run whose ``run.toml`` records other chains
        (``[knotmm.layout]``) than its ``topology.pdb`` holds.
    TemplateError
        For a frame that is not an integer or is out of range, fewer than 4 beads, or a
        topology of several PDB chains whose bonds are not those of bead chains (it is
        never read as one chain).
    """
    import mdtraj  # noqa: PLC0415 - heavy import kept out of module import

    names = _PLAIN if names is None else names
    if path is None:
        raise TemplateError(f"{names['path']} is not set: give a PDB or DCD file")
    path = Path(os.fspath(path))
    if not path.exists():
        raise TrajectoryFileError(f"{names['path']}={str(path)!r}: file not found")
    if path.is_dir():
        if (path / TRAJECTORY_FILE).is_file():  # a run directory
            path = path / TRAJECTORY_FILE
        elif (path / REPLICA_SET_FILE).is_file():
            raise TrajectoryFileError(
                f"{names['path']}={str(path)!r} is a set of replicas; give one of them, e.g. "
                f"{str(path / 'replica_0')!r}"
            )
        else:
            raise TrajectoryFileError(
                f"{names['path']}={str(path)!r} is a directory without {TRAJECTORY_FILE}; give "
                "a PDB or DCD file"
            )
    if path.stat().st_size == 0:
        raise TrajectoryFileError(f"{names['path']}={str(path)!r} is empty")
    suffix = path.suffix.lower()
    top_path = None
    if suffix == ".pdb":
        xyz_angstrom, top, n_frames, index = _read_pdb(mdtraj, path, frame, names)
    elif suffix == ".dcd":
        top_path = _find_topology(path, topology, names)
        xyz_angstrom, top, n_frames, index = _read_dcd(mdtraj, path, frame, top_path, names)
    else:
        raise TrajectoryFileError(f"{names['path']}={str(path)!r}: expected a .pdb or .dcd file")
    x = angstrom_to_d(np.asarray(xyz_angstrom, dtype=np.float64))
    if not np.all(np.isfinite(x)):
        raise TrajectoryFileError(
            f"{names['path']}={str(path)!r}: frame {frame} holds non-finite coordinates"
        )
    if x.shape[0] < 4:
        raise TemplateError(
            f"{names['path']}={str(path)!r} holds {x.shape[0]} beads: a knot needs at least 4"
        )
    pdb_chains = tuple(int(c.n_atoms) for c in top.chains if c.n_atoms)
    layout = bond_layout(top)
    if layout is None and top.n_bonds and len(pdb_chains) > 1:
        raise TemplateError(
            f"{names['path']}={str(path)!r} holds {len(pdb_chains)} PDB chains whose bonds "
            "(CONECT records) are not those of bead chains in atom order (bead i bonded to "
            "i + 1, a ring's last bead to its first): knotmm does not join them into one "
            "chain; give a file of bead chains, such as a knotmm topology.pdb"
        )
    run_dir = _run_directory(path, top_path)
    frame_time = None
    if run_dir is not None:
        layout, frame_time = _run_record(run_dir, x.shape[0], layout, index, names)
    return Structure(x, path, index, n_frames, ring_closed(top), layout, pdb_chains,
                     top_path, run_dir, frame_time)


def bond_layout(top) -> ChainLayout | None:
    """The chains of an mdtraj Topology by its bonds (CONECT records), or ``None``.

    Read from the bonds, never from the PDB chain identifiers (they repeat past 62 chains):
    :meth:`knotmm.model.layout.ChainLayout.from_bonds`. ``None`` when the bonds are absent
    or are not those of bead chains in atom order.
    """
    bonds = [(a.index, b.index) for a, b in top.bonds]
    return ChainLayout.from_bonds(top.n_atoms, bonds) if bonds else None


def _run_directory(path: Path, top_path: Path | None) -> Path | None:
    """The knotmm run directory ``path`` belongs to: its ``trajectory.dcd`` (read with the
    run's ``topology.pdb``) or its ``topology.pdb``, with a ``run.toml`` beside them."""
    folder = path.parent
    if not (folder / RUN_FILE).is_file():
        return None
    if path.name == TOPOLOGY_FILE or (
            path.name == TRAJECTORY_FILE and top_path is not None
            and top_path.resolve() == (folder / TOPOLOGY_FILE).resolve()):
        return folder
    return None


def _run_record(run_dir: Path, n_beads: int, layout: ChainLayout | None, index: int,
                names) -> tuple[ChainLayout | None, float | None]:
    """The chains and the frame's time as the run's ``run.toml`` records them.

    Its ``[knotmm.layout]``, when present, must agree with the bonds of ``topology.pdb``
    (:meth:`ChainLayout.from_record`); a ``run.toml`` that cannot be read is passed over
    with a warning (the trajectory and its topology are what is read)."""
    from knotmm.config import read_toml  # noqa: PLC0415 - as rundir.read_facts

    try:
        data = read_toml(run_dir / RUN_FILE, "run.toml")
    except KnotmmError as exc:
        logger.warning("%s: %s; its record of the chains and times is not used", run_dir, exc)
        return layout, None
    facts = data.get("knotmm") if isinstance(data.get("knotmm"), Mapping) else {}
    record = facts.get("layout")
    if record is not None:
        where = f"{names['path']}: {str(run_dir / RUN_FILE)!r} [knotmm.layout]"
        layout = ChainLayout.from_record(record, n_beads, expected=layout, where=where)
    output = data.get("output") if isinstance(data.get("output"), Mapping) else {}
    interval = facts.get("frame_interval", output.get("frame_interval"))
    if isinstance(interval, bool) or not isinstance(interval, (int, float)) or not (
            0.0 < interval < float("inf")):
        return layout, None
    return layout, float(index) * float(interval)


def ring_closed(top) -> bool | None:
    """Whether an mdtraj Topology closes the ring.

    Parameters
    ----------
    top : mdtraj.Topology

    Returns
    -------
    bool or None
        ``True`` if it bonds its last atom to its first, ``False`` if it lists bonds but not
        that one (an open chain), ``None`` if it lists no bonds at all.
    """
    last = top.n_atoms - 1
    found = False
    for a, b in top.bonds:
        found = True
        if {a.index, b.index} == {0, last}:
            return True
    return False if found else None


def _read_pdb(mdtraj, path: Path, frame, names):
    if not _has_atoms(path):
        raise TrajectoryFileError(
            f"{names['path']}={str(path)!r} holds no ATOM or HETATM records: not a PDB file "
            "of beads"
        )
    try:
        traj = mdtraj.load_pdb(os.fspath(path), standard_names=False)
    except Exception as exc:  # mdtraj raises many kinds on a bad file
        raise TrajectoryFileError(
            f"{names['path']}={str(path)!r} cannot be read as PDB: {_one_line(exc)}"
        ) from None
    if traj.n_atoms == 0:
        raise TrajectoryFileError(f"{names['path']}={str(path)!r} holds no atoms")
    index = _frame_index(frame, traj.n_frames, path, names)
    return mdtraj_to_angstrom(traj.xyz[index]), traj.topology, traj.n_frames, index


def _read_dcd(mdtraj, path: Path, frame, top_path: Path, names):
    try:
        top = mdtraj.load_pdb(os.fspath(top_path), standard_names=False).topology
    except Exception as exc:
        raise TrajectoryFileError(
            f"{names['topology']}={str(top_path)!r} cannot be read as PDB: {_one_line(exc)}"
        ) from None
    try:
        claimed = dcd_layout(path).claimed_frames
    except TrajectoryFileError:
        claimed = 0  # mdtraj's message below says what is wrong
    try:
        with quiet_c_stdout(), mdtraj.formats.DCDTrajectoryFile(c_path(path), "r") as fh:
            n_frames = len(fh)
            n_atoms = _dcd_atoms(fh)
            if n_atoms is not None and n_atoms != top.n_atoms:
                raise TrajectoryFileError(
                    f"{names['path']}={str(path)!r} has {n_atoms} atoms per frame but its "
                    f"topology {top_path.name} has {top.n_atoms}; give the matching "
                    f"{names['topology']}"
                )
            index = _frame_index(frame, n_frames, path, names, claimed)
            fh.seek(index)
            xyz, _, _ = fh.read(n_frames=1)
    except (TemplateError, TrajectoryFileError):
        raise
    except Exception as exc:
        raise TrajectoryFileError(
            f"{names['path']}={str(path)!r} cannot be read as DCD (truncated or not a DCD "
            f"file?): {_one_line(exc)}"
        ) from None
    if claimed > n_frames:
        logger.warning(
            "%s is truncated: its header claims %d frames, %d are complete; using frame %d",
            path,
            claimed,
            n_frames,
            index,
        )
    if xyz.shape[0] != 1:
        raise TrajectoryFileError(
            f"{names['path']}={str(path)!r} is truncated: frame {index} could not be read"
        )
    if xyz.shape[1] != top.n_atoms:
        raise TrajectoryFileError(
            f"{names['path']}={str(path)!r} has {xyz.shape[1]} atoms per frame but its "
            f"topology {top_path.name} has {top.n_atoms}; give the matching "
            f"{names['topology']}"
        )
    return np.asarray(xyz[0], dtype=np.float64), top, n_frames, index


def _find_topology(path: Path, topology, names) -> Path:
    if topology is not None:
        top = Path(topology)
        if not top.is_file():
            raise TrajectoryFileError(
                f"{names['topology']}={str(topology)!r}: file not found; give the PDB written "
                "with the trajectory"
            )
        return top
    for candidate in (path.with_suffix(".pdb"), path.parent / TOPOLOGY_FILE):
        if candidate.is_file():
            return candidate
    raise TrajectoryFileError(
        f"{names['path']}={str(path)!r} is a DCD file, which holds no topology, and no "
        f"{path.with_suffix('.pdb').name} or {TOPOLOGY_FILE} lies beside it; set "
        f"{names['topology']} to its PDB file"
    )


def _frame_index(frame, n_frames: int, path: Path, names, claimed: int = 0) -> int:
    if isinstance(frame, bool) or not isinstance(frame, (int, np.integer)):
        raise TemplateError(f"{names['frame']}={frame!r}: expected an integer")
    frame = int(frame)
    if n_frames == 0:
        raise TrajectoryFileError(
            f"{names['path']}={str(path)!r} holds no complete frame"
            + (f" (its header claims {claimed}): the file is truncated" if claimed else "")
        )
    if claimed > n_frames and n_frames <= frame < claimed:
        raise TrajectoryFileError(
            f"{names['path']}={str(path)!r} is truncated: its header claims {claimed} frames but "
            f"only {n_frames} are complete, so {names['frame']}={frame} is missing; use "
            f"{names['frame']} < {n_frames} (or -1, the last complete frame)"
        )
    if not -n_frames <= frame < n_frames:
        raise TemplateError(
            f"{names['frame']}={frame} is out of range: {path.name} has {n_frames} frame"
            f"{'s' if n_frames != 1 else ''} (0..{n_frames - 1}, or -{n_frames}..-1 from the end)"
        )
    return frame % n_frames


def _has_atoms(path: Path) -> bool:
    try:
        with open(path, errors="replace") as fh:
            return any(line.startswith(("ATOM", "HETATM")) for line in fh)
    except OSError:
        return False


def _dcd_atoms(fh) -> int | None:
    for attr in ("n_atoms", "_n_atoms"):
        value = getattr(fh, attr, None)
        if isinstance(value, (int, np.integer)):
            return int(value)
    return None


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return text or type(exc).__name__
