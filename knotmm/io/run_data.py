"""Loading saved trajectories into model units.

A run directory written by ``knotmm run`` holds ``trajectory.dcd`` (Angstrom, 1 d = 10 A),
``topology.pdb`` (one residue ``BEA`` per bead, CONECT records for every bond) and
``run.toml`` (the resolved run file). :func:`load_run` reads such a directory, or any DCD
with a matching PDB topology, and returns a :class:`RunData` with times in tau_d and
positions in d. :meth:`RunData.to_mdtraj` goes back to an ``mdtraj.Trajectory`` (for
viewers such as nglview or py3Dmol, and mdtraj's own analyses).

Examples
--------
>>> data = load_run("runs/trefoil")                                   # doctest: +SKIP
>>> data                                                              # doctest: +SKIP
RunData(runs/trefoil: 401 frames, t = 0 to 200 tau_d every 0.5, 90 beads, 1 closed chain)
>>> data.positions.shape, data.frame_interval                         # doctest: +SKIP
((401, 90, 3), 0.5)
>>> traj = data.to_mdtraj()   # as in the files, centre of mass at 0    # doctest: +SKIP
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from knotmm.config import read_toml
from knotmm.errors import ConfigError, TrajectoryFileError
from knotmm.io.dcd import dcd_layout, read_dcd
from knotmm.io.replica_set import REPLICA_SET_FILE, is_replica_set, read_replica_set, replica_index
from knotmm.io.rundir import RUN_FILE, TOPOLOGY_FILE, TRAJECTORY_FILE
from knotmm.model.layout import ChainLayout
from knotmm.units import PS_PER_TAU, angstrom_to_d, d_to_mdtraj

__all__ = ["RunData", "load_run", "config_value"]

logger = logging.getLogger(__name__)


@dataclass(repr=False)
class RunData:
    """A trajectory in model units, with what is known about the run that made it.

    Attributes
    ----------
    times : ndarray, shape (n_frames,)
        Time of each frame, in tau_d; frame 0 is t = 0.
    positions : ndarray, shape (n_frames, n_beads, 3)
        Bead positions, in d (gravity along -z).
    bonds : ndarray, shape (n_bonds, 2)
        Bonded bead pairs (indices), from the topology's CONECT records.
    config : dict
        The parsed ``run.toml`` (nested tables), or ``{}`` when there is none.
    frame_interval : float
        Time between frames, in tau_d.
    trajectory, topology : Path or None
        The files read.
    run_file : Path or None
        The ``run.toml`` read, if any.
    directory : Path or None
        Where results are written by default (the run directory, or the DCD's folder).
    notes : list of str
        Things noticed while loading (a truncated last frame, a missing bond, ...).
    """

    times: np.ndarray
    positions: np.ndarray
    bonds: np.ndarray
    config: dict[str, Any] = field(default_factory=dict)
    frame_interval: float = 1.0
    trajectory: Path | None = None
    topology: Path | None = None
    run_file: Path | None = None
    directory: Path | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def n_frames(self) -> int:
        """Number of frames."""
        return int(self.positions.shape[0])

    @property
    def n_beads(self) -> int:
        """Number of beads N."""
        return int(self.positions.shape[1])

    def get(self, dotted: str, default: Any = None) -> Any:
        """A run-file value by dotted key (``"knot.p"``), or ``default`` when absent."""
        return config_value(self.config, dotted, default)

    @classmethod
    def from_arrays(
        cls, positions, frame_interval: float, config: dict | None = None, bonds=None
    ) -> RunData:
        """Wrap in-memory arrays (positions in d, frames ``frame_interval`` tau_d apart)."""
        x = np.array(positions, dtype=np.float64)
        if x.ndim != 3 or x.shape[2] != 3:
            raise ValueError(f"positions has shape {x.shape}: expected (n_frames, n_beads, 3) in d")
        n = x.shape[1]
        if bonds is None:
            bonds = ChainLayout.ring(n).bonds()
        times = np.arange(x.shape[0]) * float(frame_interval)
        return cls(
            times, x, np.asarray(bonds, dtype=int), dict(config or {}), float(frame_interval)
        )

    def chains(self) -> list[tuple[int, int, bool]]:
        """The chains as the bonds give them: ``(first bead, bead count, closed)`` each.

        A chain is a run of consecutive beads bonded ``i - (i + 1)``; it is closed when its
        last bead is bonded to its first. (:func:`knotmm.analysis.shape.chains_of` also reads
        the run file's ``knot.closed``.)
        """
        pairs = {tuple(sorted(map(int, b))) for b in np.asarray(self.bonds).reshape(-1, 2)}
        out: list[tuple[int, int, bool]] = []
        start = 0
        for i in range(self.n_beads):
            if i == self.n_beads - 1 or (i, i + 1) not in pairs:
                out.append((start, i + 1 - start, i - start >= 2 and (start, i) in pairs))
                start = i + 1
        return out

    def __repr__(self) -> str:
        """One line: the run, its frames and time span in tau_d, beads and chains."""
        where = self.directory
        traj = self.trajectory
        if traj is not None and (where is None or traj.name != TRAJECTORY_FILE):
            where = traj  # a bare DCD: name the file
        what = "in-memory trajectory" if where is None else str(where)
        if self.n_frames:
            span = (f"t = {float(self.times[0]):g} to {float(self.times[-1]):g} tau_d "
                    f"every {self.frame_interval:g}")
        else:
            span = "no time span"
        chains = self.chains() if self.n_beads else []
        closed = sum(c[2] for c in chains)
        if len(chains) == 1:
            kind = "1 closed chain" if closed else "1 open chain"
        else:
            kind = f"{len(chains)} chains ({closed} closed)"
        frames = "1 frame" if self.n_frames == 1 else f"{self.n_frames} frames"
        return f"RunData({what}: {frames}, {span}, {self.n_beads} beads, {kind})"

    def to_mdtraj(self, center: bool = True):
        """The run as an ``mdtraj.Trajectory``, in the units of its DCD and PDB files.

        The coordinates are those of ``trajectory.dcd``: 10 Angstrom per bead diameter
        (:data:`knotmm.units.ANGSTROM_PER_D`), held by mdtraj in nm as always (so
        ``traj.xyz`` reads 1 nm per d and ``traj.save_dcd`` writes the run's Angstrom).
        Frame times are in ps, 1 ps per tau_d (:data:`knotmm.units.PS_PER_TAU`). The
        topology is laid out as ``topology.pdb`` is: one chain per chain of beads (``A``,
        ``B``, ...), one residue ``BEA`` and one atom ``B`` (carbon) per bead, and exactly the
        bonds listed in :attr:`RunData.bonds`.

        Parameters
        ----------
        center : bool, optional
            Shift each frame so that the centre of mass (all beads weigh the same) is at
            the origin: the sedimenting chain then stays in view. False keeps the positions
            as they are (the chain falls along -z).

        Returns
        -------
        mdtraj.Trajectory
            ``n_frames`` frames of ``n_beads`` atoms; ``xyz`` has shape
            (n_frames, n_beads, 3), in nm (= d), float32; ``time`` in ps (= tau_d).
        """
        import mdtraj  # noqa: PLC0415 - heavy import kept out of module import

        from knotmm.model.layout import CHAIN_IDS  # noqa: PLC0415
        from knotmm.model.topology import BEAD_ATOM, BEAD_RESIDUE  # noqa: PLC0415

        x = np.asarray(self.positions, dtype=np.float64)
        if center:
            x = x - x.mean(axis=1, keepdims=True)
        top = mdtraj.Topology()
        carbon = mdtraj.element.carbon
        atoms = []
        for c, (_first, count, _closed) in enumerate(self.chains()):
            chain = top.add_chain(CHAIN_IDS[c % len(CHAIN_IDS)])  # as topology.pdb: repeats
            for k in range(count):
                residue = top.add_residue(BEAD_RESIDUE, chain, resSeq=k + 1)
                atoms.append(top.add_atom(BEAD_ATOM, carbon, residue))
        pairs = sorted({tuple(sorted(map(int, b))) for b in np.asarray(self.bonds).reshape(-1, 2)})
        for i, j in pairs:
            top.add_bond(atoms[i], atoms[j])
        xyz_nm = d_to_mdtraj(x)
        return mdtraj.Trajectory(
            xyz_nm, top, time=np.asarray(self.times, dtype=np.float64) * PS_PER_TAU
        )


def config_value(config: dict, dotted: str, default: Any = None) -> Any:
    """Look up ``"table.key"`` in a nested run-file mapping; ``default`` when absent."""
    node: Any = config
    for part in dotted.split("."):
        if not isinstance(node, dict) or part not in node:
            return default
        node = node[part]
    return node


def _find_one(directory: Path, pattern: str, preferred: str) -> Path | None:
    if (directory / preferred).is_file():
        return directory / preferred
    found = sorted(directory.glob(pattern))
    return found[0] if len(found) == 1 else None


def _locate(path: Path, topology) -> tuple[Path, Path, Path | None, Path]:
    """Resolve (trajectory, topology, run file or None, output directory) from a path."""
    if not path.exists():
        raise TrajectoryFileError(
            f"{path}: no such run directory or trajectory file; give a run directory "
            f"(with {TRAJECTORY_FILE}, {TOPOLOGY_FILE}, {RUN_FILE}) or a DCD file"
        )
    if path.is_dir():
        traj = _find_one(path, "*.dcd", TRAJECTORY_FILE)
        if traj is None and is_replica_set(path):
            raise TrajectoryFileError(_replica_set_message(path))
        if traj is None:
            raise TrajectoryFileError(
                f"{path}: no {TRAJECTORY_FILE} in this directory (and not exactly one "
                "*.dcd); is it a run directory? give the DCD file itself"
            )
        directory = path
    else:
        if path.suffix.lower() != ".dcd":
            raise TrajectoryFileError(
                f"{path}: expected a run directory or a .dcd trajectory, got a "
                f"'{path.suffix or 'suffix-less'}' file"
            )
        traj = path
        directory = path.parent
    if topology is not None:
        top = Path(topology)
        if not top.is_file():
            raise TrajectoryFileError(f"--topology {top}: no such file; give the run's PDB")
    else:
        top = None
        for candidate in (traj.with_suffix(".pdb"), directory / TOPOLOGY_FILE):
            if candidate.is_file():
                top = candidate
                break
        if top is None:
            top = _find_one(directory, "*.pdb", TOPOLOGY_FILE)
        if top is None:
            raise TrajectoryFileError(
                f"{traj}: no topology found (looked for {traj.with_suffix('.pdb').name} and "
                f"{TOPOLOGY_FILE} beside it); give one with --topology PDB"
            )
    run_file = directory / RUN_FILE
    return traj, top, (run_file if run_file.is_file() else None), directory


def _replica_set_message(path: Path) -> str:
    """The one line for a replica set's directory given where one run is expected."""
    try:
        count = int(read_replica_set(path)["replicas"]["count"])
    except ConfigError:  # a damaged replicas.toml: count the replica directories
        count = sum(1 for p in path.iterdir()
                    if p.is_dir() and replica_index(p.name) is not None)
    which = f"K = 0 ... {count - 1}" if count > 1 else "K = 0"
    return (f"{path}: this is a replica set of {count} replica{'s' if count != 1 else ''} "
            f"({REPLICA_SET_FILE}), not one run: give one of them, "
            f"{path / 'replica_K'} with {which}")


def _check_interval(value, what: str) -> float:
    try:
        dt = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{what} = {value!r}: expected a positive number of tau_d") from None
    if not math.isfinite(dt) or dt <= 0:
        raise ConfigError(f"{what} = {value!r}: expected a positive number of tau_d")
    return dt


def _ring_notes(bonds: np.ndarray, n: int, top: Path, layout=None) -> list[str]:
    """What the topology's bonds lack of one ring, unless they are the chains run.toml's
    ``[knotmm.layout]`` records (``layout``: an open chain has no closing bond)."""
    pairs = {tuple(sorted(map(int, b))) for b in bonds}
    if isinstance(layout, dict) and pairs:
        chains = ChainLayout.from_bonds(n, bonds)
        if chains is not None and (list(chains.lengths), list(chains.closed)) == (
                layout.get("lengths"), layout.get("closed")):
            return []
    ring = {tuple(sorted(map(int, b))) for b in ChainLayout.ring(n).bonds()}
    missing = ring - pairs
    if not pairs:
        return [
            f"{top.name} has no CONECT records: the chain is taken as the closed ring "
            "0-1-...-(N-1)-0"
        ]
    if missing == {(0, n - 1)}:
        return [
            f"{top.name} has no bond closing the ring ({n - 1}-0): the chain is open there, "
            "and is analysed as the closed ring 0-1-...-(N-1)-0 (writhe and knot type close "
            "it with that bond)"
        ]
    if missing:
        example = sorted(missing)[0]
        return [
            f"{top.name} lacks {len(missing)} of the ring bonds i-(i+1) (e.g. "
            f"{example[0]}-{example[1]}): writhe and knot type assume bead order is "
            "chain order"
        ]
    return []


def _header_interval(traj_path: Path) -> float | None:
    """The frame interval a DCD's header states (:attr:`DCDLayout.frame_interval`), or None
    (no step in the header, or a file that is not a DCD: read_dcd says what is wrong)."""
    try:
        return dcd_layout(traj_path).frame_interval
    except TrajectoryFileError:
        return None


def load_run(path, frame_interval: float | None = None, topology=None) -> RunData:
    """Load a run directory or a DCD/PDB pair, in model units.

    Parameters
    ----------
    path : str or Path
        A run directory (``trajectory.dcd``, ``topology.pdb``, ``run.toml``) or a DCD file.
        For a DCD file the topology is ``--topology``, else a PDB with the same stem, else
        ``topology.pdb`` beside it; a ``run.toml`` beside it is read if present.
    frame_interval : float, optional
        Time between frames in tau_d. Without it: ``run.toml``'s ``output.frame_interval``,
        else the DCD header's (its steps between frames times its step, read as ps = tau_d;
        a note says so); when both this and ``run.toml`` are given this value wins (a
        warning is logged if they differ).
    topology : str or Path, optional
        A PDB topology to use instead of the one found beside the trajectory.

    Returns
    -------
    RunData
        ``times`` (n_frames,) in tau_d and ``positions`` (n_frames, n_beads, 3) in d.

    Raises
    ------
    TrajectoryFileError
        A file is missing, unreadable, truncated to nothing, or the DCD and PDB disagree on
        the number of beads (or disagree with ``knot.beads`` in ``run.toml``).
    ConfigError
        ``run.toml`` is not valid TOML, or no frame interval is known (none given, no
        ``run.toml``, none in the DCD header).
    """
    import mdtraj

    traj_path, top_path, run_file, directory = _locate(Path(path), topology)
    config: dict[str, Any] = read_toml(run_file) if run_file is not None else {}
    notes: list[str] = []

    from_file = config_value(config, "output.frame_interval")
    if frame_interval is not None:
        dt = _check_interval(frame_interval, "--frame-interval")
        if from_file is not None and not math.isclose(float(from_file), dt, rel_tol=1e-9):
            logger.warning("frame interval %g given; %s says %s", dt, run_file, from_file)
            notes.append(f"frame interval {dt:g} tau_d given; {RUN_FILE} says {from_file}")
    elif from_file is not None:
        dt = _check_interval(from_file, f"{run_file}: output.frame_interval")
    elif (header := _header_interval(traj_path)) is not None:
        dt = header / PS_PER_TAU
        notes.append(f"frame interval {dt:g} tau_d from the header of {traj_path.name} "
                     "(1 ps = 1 tau_d; give --frame-interval T if the file means otherwise)")
    else:
        where = (
            f"{run_file} has no output.frame_interval"
            if run_file
            else (f"no {RUN_FILE} beside {traj_path} and its header has no time step")
        )
        raise ConfigError(
            f"{where}: give the time between frames with --frame-interval T (in tau_d)"
        )

    try:
        top = mdtraj.load_topology(str(top_path))
    except Exception as exc:  # mdtraj raises many kinds on a bad PDB
        raise TrajectoryFileError(
            f"{top_path}: cannot be read as a PDB topology ({exc}); give the run's PDB"
        ) from None
    if top.n_atoms == 0:
        raise TrajectoryFileError(f"{top_path}: the topology has no atoms; give the run's PDB")

    xyz, dcd_notes = read_dcd(traj_path)
    notes += dcd_notes
    if xyz.ndim != 3 or xyz.shape[0] == 0:
        raise TrajectoryFileError(
            f"{traj_path}: the trajectory holds no complete frame; the run wrote nothing "
            "or the file was cut short"
        )
    n_frames, n_beads = xyz.shape[:2]
    if n_beads != top.n_atoms:
        raise TrajectoryFileError(
            f"{traj_path} has {n_beads} beads per frame but {top_path} has {top.n_atoms}: "
            "they come from different runs; give the matching --topology"
        )
    beads = config_value(config, "knot.beads")
    if beads is not None and int(beads) != n_beads:
        raise TrajectoryFileError(
            f"{traj_path} has {n_beads} beads per frame but {run_file} says knot.beads = "
            f"{beads}: the files come from different runs"
        )

    positions = angstrom_to_d(xyz.astype(np.float64))
    finite = np.isfinite(positions).all(axis=(1, 2))
    if not finite.all():
        first_bad = int(np.argmin(finite))
        if first_bad == 0:
            raise TrajectoryFileError(
                f"{traj_path}: frame 0 has non-finite coordinates; the file is corrupt"
            )
        notes.append(
            f"{traj_path.name}: frame {first_bad} and later dropped (non-finite coordinates)"
        )
        positions = positions[:first_bad]

    bonds = np.array([[b[0].index, b[1].index] for b in top.bonds], dtype=int).reshape(-1, 2)
    notes += _ring_notes(bonds, n_beads, top_path, config_value(config, "knotmm.layout"))
    if bonds.size == 0:
        bonds = ChainLayout.ring(n_beads).bonds()

    duration = config_value(config, "run.duration")
    if duration is not None:
        expected = int(round(float(duration) / dt)) + 1
        if positions.shape[0] < expected:
            notes.append(
                f"{positions.shape[0]} of the {expected} frames run.duration = {duration} "
                "implies: the run stopped early"
            )
    times = np.arange(positions.shape[0]) * dt
    for note in notes:
        logger.info(note)
    return RunData(
        times=times,
        positions=positions,
        bonds=bonds,
        config=config,
        frame_interval=dt,
        trajectory=traj_path,
        topology=top_path,
        run_file=run_file,
        directory=directory,
        notes=notes,
    )
