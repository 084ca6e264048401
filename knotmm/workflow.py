"""From a validated run configuration to a finished run directory.

A run directory is a contract other tools rely on:

=================== =========================================================================
``trajectory.dcd``  frames in Angstrom (1 d = 10 A), no unit cell; frame 0 is the start and
                    frame k the state at ``k * output.frame_interval`` tau_d
``topology.pdb``    the starting positions, one residue ``BEA`` per bead, CONECT records for
                    every bond including the ring closure
``run.toml``        every resolved parameter (a valid run file) plus a ``[knotmm]`` table:
                    version, status (running, finished, fault, interrupted), template facts,
                    and the run's summary
``observables.csv`` time (tau_d), step, centre of mass (d), energy per term (F0 d), longest
                    bond (d), current step size, velocity evaluations
``view.vmd``        a VMD script: ``vmd -e view.vmd`` loads the pair and draws the ring
=================== =========================================================================

Nothing is written until the configuration, the template and the platform have been checked,
and an existing run directory is never overwritten without ``overwrite=True``.
"""

from __future__ import annotations

import datetime as _dt
import logging
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from knotmm import __version__
from knotmm.config import RunConfig, read_toml, resolve_stepping
from knotmm.engine.reporters import DCDReporter, ObservablesReporter, ProgressReporter
from knotmm.engine.simulation import Simulation
from knotmm.errors import ConfigError, RunDirectoryError, SimulationFault, TrajectoryFileError
from knotmm.io.atomic import write_text_atomic as write_atomic
from knotmm.model.system import ChainModel

__all__ = ["RunResult", "run", "resume", "prepare_directory", "RUN_FILES", "write_atomic"]

log = logging.getLogger(__name__)

#: Files knotmm writes into a run directory (and may replace with ``overwrite``).
RUN_FILES = (
    "trajectory.dcd",
    "topology.pdb",
    "run.toml",
    "observables.csv",
    "view.vmd",
    "checkpoint.npz",
    "analysis.json",
)

VMD_SCRIPT = """\
# VMD script written by knotmm {version}: run `vmd -e view.vmd` in this directory.
# Lengths are in Angstrom: one bead diameter d = 10 A.
mol new topology.pdb type pdb waitfor all
mol addfile trajectory.dcd type dcd first 0 last -1 step 1 waitfor all
set beads [atomselect top all]
$beads set radius 5.0
mol delrep 0 top
mol representation VDW 1.0 16
mol color ResID
mol material AOChalky
mol addrep top
mol representation Bonds 2.0 12
mol color ResID
mol addrep top
display projection Orthographic
axes location LowerLeft
animate goto 0
"""


@dataclass
class RunResult:
    """Summary of a finished run.

    Attributes
    ----------
    directory : Path
    time : float
        Simulated time reached, in tau_d.
    steps, evaluations, rejected : int
    frames : int
        Frames in ``trajectory.dcd``.
    wall_time : float
        Seconds, start-up included.
    sedimentation_velocity : float
        Mean speed of the centre of mass along -z over the run, in d/tau_d.
    """

    directory: Path
    time: float
    steps: int
    evaluations: int
    rejected: int
    frames: int
    wall_time: float
    sedimentation_velocity: float
    session_steps: int = -1

    def summary(self) -> str:
        """The one-line summary the CLI prints."""
        steps = self.steps if self.session_steps < 0 else self.session_steps
        rate = steps / self.wall_time if self.wall_time > 0 else math.inf
        return (
            f"simulated {self.time:g} tau_d, mean sedimentation speed "
            f"{self.sedimentation_velocity:.4f} d/tau_d, wall time {self.wall_time:.1f} s, "
            f"{rate:.0f} steps/s ({self.steps} steps, {self.evaluations} force evaluations), "
            f"{self.frames} frames in {self.directory}"
        )


def run_status(directory: Path) -> str | None:
    """The ``[knotmm] status`` of a run directory, or None if it has no readable run.toml."""
    path = Path(directory) / "run.toml"
    if not path.exists():
        return None
    try:
        return str(read_toml(path).get("knotmm", {}).get("status", "unknown"))
    except ConfigError:
        return "unreadable"


def prepare_directory(directory: Path, overwrite: bool) -> None:
    """Check that ``directory`` may be written; with ``overwrite``, remove knotmm's files.

    Only the files of :data:`RUN_FILES` and knotmm's plots are removed, never anything else.

    Raises
    ------
    RunDirectoryError
        If the directory holds a run (or other files) and ``overwrite`` is false.
    """
    directory = Path(directory)
    if directory.exists() and not directory.is_dir():
        raise RunDirectoryError(
            f"output directory {str(directory)!r} is a file; choose another --out"
        )
    if not directory.exists() or not any(directory.iterdir()):
        return
    status = run_status(directory)
    if not overwrite:
        if status is None:
            raise RunDirectoryError(
                f"output directory {str(directory)!r} is not empty and holds no knotmm run; "
                f"choose another --out (or pass --overwrite to write knotmm's files there)"
            )
        raise RunDirectoryError(
            f"output directory {str(directory)!r} already holds a {status} run; pass "
            f"--overwrite to replace it, or choose another --out"
        )
    for name in RUN_FILES:
        p = directory / name
        if p.exists():
            p.unlink()
    for p in directory.glob("*.png"):
        p.unlink()


def _header() -> str:
    return (
        f"# knotmm run file, written by knotmm {__version__}.\n"
        f"# Every resolved parameter; use it again with `knotmm run run.toml`.\n"
        f"# Units: lengths in d, forces in F0, times in tau_d.\n\n"
    )


def write_run_toml(directory: Path, cfg: RunConfig, facts: dict) -> None:
    """Write ``run.toml``: the resolved run file plus the ``[knotmm]`` facts table."""
    import tomli_w

    data = cfg.to_dict()
    data["knotmm"] = {k: v for k, v in facts.items() if v is not None}
    write_atomic(Path(directory) / "run.toml", _header() + tomli_w.dumps(data))


def _make_simulation(cfg: RunConfig, positions, integrator) -> Simulation:
    """The Simulation of a run; fails (platform, starting positions) before any writing."""
    return Simulation(
        positions,
        ChainModel.from_config(cfg),
        integrator,
        platform=cfg["run.platform"],
        threads=cfg["run.threads"],
        max_bond_length=cfg["run.max_bond_length"],
        mobility_threads=cfg["run.mobility_threads"],
    )


def run(
    cfg: RunConfig,
    directory: str | os.PathLike | None = None,
    overwrite: bool = False,
    progress: bool | None = None,
) -> RunResult:
    """Run a simulation described by ``cfg`` and write its run directory.

    Parameters
    ----------
    cfg : RunConfig
        The validated run configuration.
    directory : path, optional
        Run directory; default ``cfg["output.directory"]``.
    overwrite : bool
        Replace an existing run in ``directory``.
    progress : bool, optional
        Show a progress bar; default: only when standard error is a terminal.

    Returns
    -------
    RunResult

    Raises
    ------
    ConfigError, TemplateError, RunDirectoryError
        Before anything is written.
    SimulationFault
        If the dynamics breaks down; the files written so far are kept, a last checkpoint
        of the last good state is written, and ``run.toml`` says ``status = "fault"`` with
        the message.
    """
    from knotmm.dynamics.brownian import integrator_from_config
    from knotmm.io.pdb import write_pdb
    from knotmm.shapes.templates import build_template

    wall0 = time.perf_counter()
    directory = Path(directory if directory is not None else cfg["output.directory"])
    name, timestep = resolve_stepping(cfg)  # run.toml records what is used, not "auto"
    cfg = cfg.replace({"run.integrator": name, "run.timestep": timestep})
    integrator = integrator_from_config(cfg)  # checks integrator against run.peclet
    template = build_template(cfg)
    if template.resolved:
        cfg = cfg.replace(template.resolved)
    n_beads = template.positions.shape[0]
    sim = _make_simulation(cfg, template.positions, integrator)
    prepare_directory(directory, overwrite)
    if cfg["output.directory"] != str(directory):
        cfg = cfg.replace({"output.directory": str(directory)})

    directory.mkdir(parents=True, exist_ok=True)
    write_pdb(directory / "topology.pdb", template.positions)
    write_atomic(directory / "view.vmd", VMD_SCRIPT.format(version=__version__))
    facts = {
        "version": __version__,
        "status": "running",
        "created": _dt.datetime.now().isoformat(timespec="seconds"),
        "template": template.description,
        "template_writhe": float(template.writhe),
        "template_knot_type": template.knot_type,
        "n_beads": int(n_beads),
        "integrator": sim.integrator.describe(),
        "platform": sim.platform_name,
        "frame_interval": cfg["output.frame_interval"],
        "start_z": float(sim.positions[:, 2].mean()),
    }
    if template.notes:
        facts["notes"] = list(template.notes)
    write_run_toml(directory, cfg, facts)
    return _drive(sim, cfg, directory, facts, None, progress, wall0)


def resume(directory: str | os.PathLike, progress: bool | None = None) -> RunResult:
    """Continue a run that was stopped or killed, from its last checkpoint.

    The trajectory and the observables are cut back to what the checkpoint counts and then
    appended to; a deterministic run continues exactly as if it had never stopped.

    Raises
    ------
    TrajectoryFileError, ConfigError
        If the directory holds no resumable run (no run.toml or checkpoint, damaged files).
    RunDirectoryError
        If the run already finished.
    """
    from knotmm.config import load_run_file
    from knotmm.engine.checkpoint import (
        CHECKPOINT_NAME,
        load_checkpoint,
        truncate_csv,
        truncate_dcd,
    )

    wall0 = time.perf_counter()
    directory = Path(directory)
    if not (directory / "run.toml").exists():
        raise TrajectoryFileError(
            f"--resume {str(directory)!r}: no run.toml there; give the directory of a knotmm run"
        )
    raw = read_toml(directory / "run.toml")
    facts = dict(raw.get("knotmm", {}))
    status = facts.get("status")
    if status == "finished":
        raise RunDirectoryError(
            f"--resume {str(directory)!r}: the run already finished; run longer with a new "
            f"run file (its run.toml, with a larger run.duration) in another directory"
        )
    from knotmm.dynamics.brownian import integrator_from_config

    cfg = load_run_file(directory / "run.toml")
    integrator = integrator_from_config(cfg)
    ckpt = load_checkpoint(directory / CHECKPOINT_NAME)
    if ckpt["integrator"] != cfg["run.integrator"]:
        raise TrajectoryFileError(
            f"checkpoint integrator {ckpt['integrator']!r} differs from run.integrator = "
            f"{cfg['run.integrator']!r} in run.toml; the files do not belong together"
        )
    counters = ckpt["counters"]
    truncate_dcd(directory / "trajectory.dcd", int(counters["frames"]))
    truncate_csv(directory / "observables.csv", int(counters["rows"]))
    sim = _make_simulation(cfg, ckpt["positions"], integrator)
    sim.integrator.set_state(ckpt["integrator_state"])
    sim.time = ckpt["time"]
    sim.currentStep = ckpt["step"]
    sim.n_evaluations = ckpt["evaluations"]
    facts.update(status="running", resumed_at=sim.time, message=None)
    write_run_toml(directory, cfg, facts)
    log.info("resuming %s at t = %g tau_d (step %d)", directory, sim.time, sim.currentStep)
    return _drive(sim, cfg, directory, facts, counters, progress, wall0)


def _drive(sim, cfg, directory, facts, counters, progress, wall0) -> RunResult:
    """Attach the reporters, run to ``run.duration``, and record the outcome in run.toml."""
    from knotmm.engine.checkpoint import CHECKPOINT_NAME, CheckpointReporter
    from knotmm.engine.interrupt import StopRequested
    from knotmm.engine.reporters import KnotTypeWatch
    from knotmm.knots.identify import topoly_available

    resuming = counters is not None
    counters = counters or {"frames": 0, "rows": 0, "checkpoints": 0, "checks": 0}
    frame_interval = cfg["output.frame_interval"]
    obs_interval = cfg["output.observables_interval"] or frame_interval
    ckpt_interval = frame_interval * max(1, math.ceil(cfg["output.checkpoint_interval"]
                                                      / frame_interval - 1e-9))
    dcd = DCDReporter(directory / "trajectory.dcd", frame_interval, sim.topology,
                      append=resuming, first_index=counters["frames"])
    obs = ObservablesReporter(directory / "observables.csv", obs_interval, append=resuming,
                              first_index=counters["rows"])
    reporters = [dcd, obs]
    watch = None
    if cfg["run.topology_check_interval"] > 0 and topoly_available():
        from knotmm.knots.identify import identify_knot

        expected = facts.get("knot_type") if resuming else None
        if expected is None:
            expected = identify_knot(sim.positions, chiral=True)
            facts["knot_type_start"] = expected
        watch = KnotTypeWatch(
            cfg["run.topology_check_interval"],
            expected=expected,
            on_change=cfg["run.on_topology_change"],
            first_index=max(1, counters.get("checks", 0)),
        )
        reporters.append(watch)

    def current_counters(next_checkpoint):
        return {
            "frames": dcd.index,
            "rows": obs.index,
            "checkpoints": next_checkpoint,
            "checks": watch.index if watch else 0,
        }

    ckpt = CheckpointReporter(directory / CHECKPOINT_NAME, ckpt_interval, current_counters,
                              first_index=counters.get("checkpoints", 0))
    reporters.append(ckpt)
    duration = cfg["run.duration"]
    bar = ProgressReporter(sim.time, duration, frame_interval, enabled=progress)
    reporters.append(bar)
    sim.reporters.extend(reporters)
    z0 = float(facts.get("start_z", sim.positions[:, 2].mean()))
    steps0 = sim.currentStep
    status, message = "finished", None
    try:
        if duration > sim.time:
            sim.run(duration - sim.time, write_at_start=not resuming)
        if watch is not None:
            watch.collect(wait=True)  # checks still running beside the simulation
    except SimulationFault as exc:
        status, message = "fault", str(exc)
        ckpt.save_now(sim)  # the last good state
        raise
    except StopRequested:
        # Stopped between two steps (knotmm.engine.interrupt): save this exact state, so that a
        # resumed run goes on from here rather than from the last periodic checkpoint.
        status, message = "interrupted", "interrupted by the user"
        ckpt.save_now(sim)  # knot checks still under way are dropped when closing, below
        raise
    except KeyboardInterrupt:
        status, message = "interrupted", "interrupted by the user"
        raise
    finally:
        for r in (dcd, obs, bar):
            r.close()
        if watch is not None:
            # an interrupted run must end promptly (a sweep repeats its stop signal every
            # second): checks still under way are dropped; the next one after resume sees
            # any change they would have seen
            watch.close(wait=status != "interrupted")
        wall = time.perf_counter() - wall0
        velocity = (z0 - float(sim.positions[:, 2].mean())) / sim.time if sim.time > 0 else 0.0
        result = RunResult(
            directory=directory,
            time=sim.time,
            steps=sim.currentStep,
            evaluations=sim.n_evaluations,
            rejected=sim.integrator.n_rejected,
            frames=dcd.index,
            wall_time=wall,
            sedimentation_velocity=velocity,
            session_steps=sim.currentStep - steps0,
        )
        facts.update(
            status=status,
            message=message,
            time_reached=sim.time,
            steps=sim.currentStep,
            evaluations=sim.n_evaluations,
            rejected_steps=sim.integrator.n_rejected,
            frames=dcd.index,
            wall_time_s=round(wall, 3),
            mean_sedimentation_velocity=velocity,
            final_max_bond=float(np.max(sim.bond_lengths())),
        )
        if watch is not None:
            facts["knot_type"] = watch.current
            facts["knot_type_checks"] = int(facts.get("knot_type_checks", 0)) + watch.checks
            if watch.dropped:
                facts["knot_type_checks_dropped"] = (
                    int(facts.get("knot_type_checks_dropped", 0)) + watch.dropped
                )
            changes = list(facts.get("knot_type_changes", []))
            changes += [{"time": t, "from": str(a), "to": str(b)} for t, a, b in watch.changes]
            facts["knot_type_changes"] = changes
        write_run_toml(directory, cfg, facts)
    return result
