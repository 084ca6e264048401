"""From a validated run configuration to a finished run directory: :func:`run`, :func:`resume`.

The run directory's files are described in :mod:`knotmm.io.rundir`; the simulation and its
reporters in :mod:`knotmm.engine` (``docs/architecture.md``). :func:`run`, as pseudocode::

    plan the run once (knotmm.plan.prepare: integrator, template, Simulation, reasons; a
        bad config fails here, nothing written); then the plan's parts, never the run file
    lock the directory (a live owner: refused); check it, clear it with overwrite
    write topology.pdb, view.vmd, run.toml (status = "running"; a failure removes them)
    attach reporters: trajectory, observables, knot checks, checkpoint, progress
    simulation.run(run.duration)   (frame 0 first)
    record the outcome in run.toml: finished, fault (also a file that cannot be written),
        interrupted (naming the signal); unlock

:func:`resume` locks the directory, checks that run.toml's parameters are the checkpoint's
(run.duration may grow), plans it again from run.toml (:func:`knotmm.plan.resume_plan`: the
choices run.toml records, the checkpoint's engine and chains), loads the checkpoint into the
plan's Simulation, cuts the trajectory and observables back to what the checkpoint counts,
and goes on the same way.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import logging
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from knotmm import __version__
from knotmm.config import RunConfig
from knotmm.engine.check_record import RECORD_KEY, checks_positions, checks_record, resumed_record
from knotmm.engine.checkpoint import CheckpointReporter, read_checkpoint
from knotmm.engine.copies import enter_group, leave_group
from knotmm.engine.interrupt import StopRequested, describe_signal, stop_signal
from knotmm.engine.knot_checks import (
    TemplateKnotCheck,
    TopologyChecks,
    finish_checks,
    knot_watch,
    linking_watch,
    record_checks,
    record_linking,
)
from knotmm.engine.reporters import DCDReporter, ObservablesReporter, ProgressReporter
from knotmm.errors import (
    ConfigError,
    KnotmmError,
    RunDirectoryError,
    SimulationFault,
    TrajectoryFileError,
)
from knotmm.io.dcd import truncate_dcd
from knotmm.io.observables import truncate_csv
from knotmm.io.rundir import (
    ANALYSIS_FILE,
    CHECKPOINT_FILE,
    OBSERVABLES_FILE,
    RUN_FILE,
    STATUS_FAULT,
    STATUS_FINISHED,
    STATUS_INTERRUPTED,
    STATUS_RUNNING,
    TOPOLOGY_FILE,
    TRAJECTORY_FILE,
    OutputError,
    RunLock,
    describe_os_error,
    prepare_directory,
    read_facts,
    retire_stale_analysis,
    starting,
    write_run_toml,
    writing,
)
from knotmm.io.vmd import write_vmd_script
from knotmm.model.layout import ChainLayout
from knotmm.plan import Output, RunPlan, prepare, resume_plan

__all__ = ["RESUMABLE_KEYS", "RunResult", "OutputFault", "build_run", "run", "resume"]

log = logging.getLogger(__name__)

#: Run-file keys that may differ between a checkpoint and run.toml when resuming: they do
#: not change the trajectory (run.duration may grow to extend a run).
RESUMABLE_KEYS = frozenset({
    "output.directory",
    "run.duration",
    "run.platform",
    "run.precision",
    "run.threads",
    "run.mobility_threads",
    "run.topology_check_interval",
    "run.on_topology_change",
})


class OutputFault(SimulationFault):
    """A file of the run directory could not be written during the run (exit code 3): the
    run stops (``status = "fault"``), its frames kept; ``knotmm run --resume`` goes on."""


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


def run(
    cfg: RunConfig,
    directory: str | os.PathLike | None = None,
    overwrite: bool = False,
    progress: bool | None = None,
    wait_for_checks: bool = False,
    copies=None,
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
        A progress bar; default: a bar on a terminal, else a line every 10 % or 30 s.
    wait_for_checks : bool, optional
        At the end, wait for the knot checks under way even while the knot worker starts
        (topoly's import, seconds). By default they are waited for only once it is up, else
        recorded as not made (``knot_type_checks_dropped``, a note for the template), so a
        short run does not wait for topoly; ``run.on_topology_change = "stop"`` always waits.
    copies : tuple or OneAfterAnother, optional
        ``(group, k)``: replica ``k`` of a :class:`knotmm.engine.copies.CopyGroup`; a
        :class:`knotmm.engine.copies.OneAfterAnother`: a replica of a set run one after
        another (run.toml's ``replica_stepping`` gives the reason).

    Returns
    -------
    RunResult

    Raises
    ------
    ConfigError, TemplateError, RunDirectoryError, OutputError
        Before the run starts (a live process owning ``directory`` included).
    SimulationFault
        If the dynamics breaks down, or a file cannot be written (:class:`OutputFault`);
        the files written so far are kept, a last checkpoint of the last good state is
        written, and ``run.toml`` says ``status = "fault"`` with the message.
    """
    from knotmm.io.pdb import write_pdb
    from knotmm.knots.identify import start_worker

    wall0 = time.perf_counter()
    start_worker()  # topoly's start-up in the knot worker overlaps building the run
    directory = Path(directory if directory is not None else cfg["output.directory"])
    if cfg["output.directory"] != str(directory):
        cfg = cfg.replace({"output.directory": str(directory)})
    built = prepare(cfg, identify="later")  # the template's knot type judged beside the run
    plan, template, sim = built.plan, built.template, built.simulation
    if directory.exists() and not directory.is_dir():
        prepare_directory(directory, overwrite)  # says it is a file
    lock = RunLock(directory, "run")
    try:
        with starting(lock, overwrite):  # a start that fails leaves nothing of it behind
            with writing(directory):
                write_pdb(directory / TOPOLOGY_FILE, template.positions, layout=template.layout)
                write_vmd_script(directory, __version__, template.layout.n_chains)
            facts = {
                "version": __version__,
                "status": STATUS_RUNNING,
                "created": _dt.datetime.now().isoformat(timespec="seconds"),
                **template.facts,
                "n_beads": int(template.positions.shape[0]),
                **({} if template.layout.is_single_ring
                   else {"layout": template.layout.to_record()}),
                "engine": sim.engine,
                "integrator": sim.integrator.describe(),
                **plan.reasons,
                "platform": sim.platform_name,
                "frame_interval": plan.output.frame_interval,
                "start_z": float(sim.positions[:, 2].mean()),
                **sim.model.elasto_gravitation_facts(template.layout.lengths),  # B per chain
            }
            if template.notes:
                facts["notes"] = list(template.notes)
            write_run_toml(directory, plan.record, facts)
    except BaseException:
        lock.release()
        raise
    return _drive(sim, _Course.of(plan), directory, facts, None, progress, wall0, lock, template,
                  wait_for_checks, copies=copies)


def build_run(cfg: RunConfig, identify: str = "now"):
    """What :func:`run` builds before it writes anything, also ``sweep --dry-run``'s check:
    the run plan and what it built (:func:`knotmm.plan.prepare`: the integrator and step
    resolved and checked, the template with its layout, ``identify`` as
    :func:`~knotmm.shapes.builder.build_template`'s, the Simulation on that layout).

    Returns
    -------
    tuple
        ``(cfg, template, sim, choice_reason)``: ``cfg`` resolved (the plan's record), and
        why ``auto`` chose the integrator (None when named).
    """
    built = prepare(cfg, identify=identify)
    plan = built.plan
    return plan.config, built.template, built.simulation, plan.reasons.get("integrator_choice")


def resume(
    directory: str | os.PathLike,
    progress: bool | None = None,
    duration: float | None = None,
    wait_for_checks: bool = False,
    copies=None,
) -> RunResult:
    """Continue a run that was stopped or killed, from its last checkpoint.

    The trajectory and the observables are cut back to what the checkpoint counts and then
    appended to; a run continues exactly as if it had never stopped.

    Parameters
    ----------
    directory : path
        A run directory.
    duration : float, optional
        A new ``run.duration``, in tau_d: extends the run (a finished one too).
    progress, wait_for_checks, copies : optional
        As for :func:`run`.

    Raises
    ------
    TrajectoryFileError, ConfigError
        If the directory holds no resumable run (no run.toml or checkpoint, damaged files),
        or run.toml's parameters are no longer the checkpoint's (the message names the
        changed keys).
    RunDirectoryError
        If the run already finished (and ``duration`` does not extend it), or another live
        process owns the directory.
    """
    from knotmm.config import load_run_file

    wall0 = time.perf_counter()
    directory = Path(directory)
    if not (directory / RUN_FILE).exists():
        raise TrajectoryFileError(
            f"--resume {str(directory)!r}: no {RUN_FILE} there; give the directory of a "
            f"knotmm run"
        )
    lock = RunLock(directory, "--resume")
    try:
        facts = read_facts(directory)
        cfg = load_run_file(directory / RUN_FILE)
        if duration is not None:
            cfg = cfg.replace({"run.duration": float(duration)})
        if facts.get("status") == STATUS_FINISHED and not (
            duration is not None and float(duration) > float(facts.get("time_reached", 0.0))
        ):
            raise RunDirectoryError(
                f"--resume {str(directory)!r}: the run already finished at t = "
                f"{facts.get('time_reached', cfg['run.duration'])} tau_d; pass --duration T "
                f"with a larger T to extend it"
            )
        if not (directory / CHECKPOINT_FILE).exists():  # stopped before its first one
            lock.release()  # run() takes it again, and starts from the start
            return run(cfg, directory, overwrite=True, progress=progress,
                       wait_for_checks=wait_for_checks, copies=copies)
        state = read_checkpoint(directory / CHECKPOINT_FILE)
        _check_same_physics(directory, cfg, state["counters"].get("config"))
        if duration is not None and float(duration) < state["time"]:
            raise ConfigError(
                f"--duration {duration:g}: the checkpoint in {str(directory)!r} is at t = "
                f"{state['time']:g} tau_d already; give a longer duration"
            )
        from knotmm.io.pdb import read_layout  # the chains as topology.pdb's CONECT say

        layout = ChainLayout.from_record(facts.get("layout"), len(state["positions"]),
                                         expected=read_layout(directory / TOPOLOGY_FILE),
                                         chains=facts.get("chains"))
        built = resume_plan(cfg, state["positions"], layout,
                            _checkpoint_engine(directory, state["engine"]))
        plan, sim = built.plan, built.simulation
        counters = sim.loadCheckpoint(directory / CHECKPOINT_FILE)
        resumed = resumed_record(state, facts, plan, directory / CHECKPOINT_FILE)
        truncate_dcd(directory / TRAJECTORY_FILE, int(counters["frames"]))
        truncate_csv(directory / OBSERVABLES_FILE, int(counters["rows"]))
        stale = directory / ANALYSIS_FILE
        if stale.exists():  # it describes the run as it was; `knotmm analyze` makes it anew
            stale.unlink()
        facts.update(status=STATUS_RUNNING, resumed_at=sim.time, message=None)
        write_run_toml(directory, cfg, facts)
    except BaseException as exc:
        lock.release()
        if isinstance(exc, OSError) and not isinstance(exc, KnotmmError):
            raise OutputError(describe_os_error(directory, exc)) from None
        raise
    log.info("resuming %s at t = %g tau_d (step %d)", directory, sim.time, sim.currentStep)
    return _drive(sim, _Course.of(plan), directory, facts, counters, progress, wall0, lock,
                  resumed.template, wait_for_checks, resumed, copies=copies)


def _checkpoint_engine(directory: Path, engine: str) -> str:
    """The engine a resumed run continues with: the one that wrote its checkpoint.

    A run goes on exactly only with the engine it was made with, whatever ``run.engine =
    "auto"`` would pick here now; a plugin run where the plugin is missing is refused. A
    plugin that needs a rebuild is named in one warning, as on every run
    (:func:`knotmm.engine.engines.resolve_engine`).
    """
    import knotmm.plugin

    if engine == "plugin" and not knotmm.plugin.available():
        raise ConfigError(
            f"--resume {str(directory)!r}: the run was made with the plugin engine, which "
            f"cannot be used here ({knotmm.plugin.load_error()}); resume it where the plugin "
            f"is built"
        )
    if knotmm.plugin.rebuild_needed():
        log.warning("%s; the run goes on with the %s engine it was made with",
                    knotmm.plugin.load_error(), engine)
    return engine


def _check_same_physics(directory: Path, cfg: RunConfig, stored: dict | None) -> None:
    """Refuse to resume when run.toml's parameters are no longer the checkpoint's.

    A key the checkpoint does not know (added to knotmm since) counts as its default.
    """
    from knotmm.config import SCHEMA

    if stored is None:  # a checkpoint from before knotmm stored its configuration
        return
    now = cfg.to_dict()
    changed = []
    if now.get("chains") != stored.get("chains"):  # the [[chains]] array as a whole
        changed.append("[[chains]]")
    for table in sorted((set(now) | set(stored)) - {"chains"}):
        keys = set(now.get(table, {})) | set(stored.get(table, {}))
        for key in sorted(keys):
            dotted = f"{table}.{key}"
            schema_key = SCHEMA.get(table, {}).get(key)
            default = None if schema_key is None else schema_key.default
            old = stored.get(table, {}).get(key, default)
            new = now.get(table, {}).get(key)
            if dotted not in RESUMABLE_KEYS and old != new:
                changed.append(f"{dotted} ({old!r} -> {new!r})")
    if changed:
        raise ConfigError(
            f"--resume {str(directory)!r}: {RUN_FILE} was edited since the checkpoint: "
            f"{', '.join(changed)}; a run cannot change its parameters half way: undo the "
            f"edit, or start a new run from this {RUN_FILE} in another directory"
        )


@dataclass(frozen=True)
class _Course:
    """What driving a run takes of its plan (:class:`knotmm.plan.RunPlan`'s parts): the
    record run.toml and the checkpoints write, the output, the duration, the checks."""

    record: dict
    output: Output
    duration: float
    checks: TopologyChecks

    @classmethod
    def of(cls, plan: RunPlan) -> _Course:
        """The course of ``plan``."""
        return cls(plan.record, plan.output, plan.duration, plan.checks)


def _drive(sim, course: _Course, directory, facts, counters, progress, wall0, lock,
           template=None, wait_for_checks=False, resumed=None, copies=None) -> RunResult:
    """Attach the reporters, run to ``run.duration``, and record the outcome in run.toml.

    ``template``: a new run's :class:`knotmm.shapes.builder.Template`, whose knot type is
    judged at the first frame after the knot worker answers (a wrong one stops the run).
    ``resumed``: what a resumed run's checks continue (``check_record.ResumedChecks``).
    ``copies``: ``(group, k)``, the replica's place in a ``CopyGroup`` (left at the end).
    """
    resuming = counters is not None
    counters = counters or {"frames": 0, "rows": 0, "checkpoints": 0, "checks": 0}
    output = course.output
    frame_interval = output.frame_interval
    obs_interval, ckpt_interval = output.observables_interval, output.checkpoint_interval
    reporters = []
    dcd = obs = watch = links = bar = None
    status, message = STATUS_FAULT, None
    z0 = float(facts.get("start_z", sim.positions[:, 2].mean()))
    steps0 = sim.currentStep
    enter_group(copies, sim, facts)
    try:
        try:
            with writing(directory / TRAJECTORY_FILE):
                dcd = DCDReporter(directory / TRAJECTORY_FILE, frame_interval, sim.topology,
                                  append=resuming, first_index=counters["frames"])
            with writing(directory / OBSERVABLES_FILE):
                obs = ObservablesReporter(directory / OBSERVABLES_FILE, obs_interval,
                                          append=resuming, first_index=counters["rows"])
        except OutputError as exc:  # a write failure, not bad input: exit 3, resumable
            raise OutputFault(f"{exc}; free the space (or fix the permissions) and run "
                              f"knotmm run --resume {directory}") from None
        reporters += [dcd, obs]
        record, positions, recorded, _ = resumed or (None, None, None, None)
        watch = knot_watch(sim, course.checks, facts, counters, record, positions)
        if watch is not None:
            reporters.append(watch)
        links = linking_watch(sim, course.checks, facts, record)
        if links is not None:
            reporters.append(links)
        judge = TemplateKnotCheck(template, facts, frame_interval, recorded=recorded)
        if template is not None and template.knot_type_pending:
            reporters.append(judge)
        config = course.record

        def current_counters(next_checkpoint):
            return {
                "frames": dcd.index,
                "rows": obs.index,
                "checkpoints": next_checkpoint,
                "checks": watch.index if watch else 0,
                "config": config,
                RECORD_KEY: checks_record(watch, links, judge),  # what a resumed run goes on
            }

        ckpt = CheckpointReporter(directory / CHECKPOINT_FILE, ckpt_interval, current_counters,
                                  first_index=counters.get("checkpoints", 0),
                                  arrays=lambda: checks_positions(watch))
        duration = course.duration
        bar = ProgressReporter(sim.time, duration, frame_interval, enabled=progress)
        reporters += [ckpt, bar]
        sim.reporters.extend(reporters)
        try:
            if duration > sim.time:
                # a resumed run first makes any report due at its start (a fault while
                # writing a frame leaves it due)
                sim.run(duration - sim.time, write_at_start=True)
            # checks still running beside the run; a run asked to stop at a change
            # waits for every one of them
            finish_checks(judge, watch,
                          wait_for_checks or course.checks.on_change == "stop")
            status, message = STATUS_FINISHED, None
        except SimulationFault as exc:
            status, message = STATUS_FAULT, str(exc)
            _quietly(ckpt.save_now, sim)  # the last good state
            raise
        except StopRequested as exc:
            # Stopped between two steps (knotmm.engine.interrupt): save this exact state, so
            # that a resumed run goes on from here rather than from the last checkpoint.
            status, message = STATUS_INTERRUPTED, f"interrupted by {describe_signal(exc.signal)}"
            _quietly(ckpt.save_now, sim)  # knot checks under way are dropped when closing
            raise
        except KeyboardInterrupt:
            status = STATUS_INTERRUPTED
            message = f"interrupted by {describe_signal(stop_signal() or 'SIGINT')}"
            raise
        except OSError as exc:
            status, message = STATUS_FAULT, describe_os_error(directory, exc)
            # cut the files back to the frames and rows counted (a partial one dropped, space
            # freed), then checkpoint the state: --resume goes on from here
            _close(dcd, obs)
            _quietly(truncate_dcd, directory / TRAJECTORY_FILE, dcd.index)
            _quietly(truncate_csv, directory / OBSERVABLES_FILE, obs.index)
            _quietly(ckpt.save_now, sim)
            raise OutputFault(message + "; the frames written so far are kept: free the "
                              "space (or fix the permissions) and run knotmm run --resume "
                              f"{directory}") from None
    except Exception as exc:
        if status == STATUS_FAULT and message is None:
            message = " ".join(f"{type(exc).__name__}: {exc}".split())
        raise
    finally:
        with _signals_held():  # a signal now must not leave status = "running" (raised after)
            leave_group(copies)
            _close(dcd, obs, bar)
            if watch is not None:
                # an interrupted run must end promptly (a sweep repeats its stop signal every
                # second): checks still under way are dropped; the next one after resume sees
                # any change they would have seen
                watch.close(wait=status != STATUS_INTERRUPTED)
            wall = time.perf_counter() - wall0
            velocity = (z0 - float(sim.positions[:, 2].mean())) / sim.time if sim.time > 0 else 0.0
            frames = dcd.index if dcd is not None else int(counters["frames"])
            result = RunResult(
                directory=directory,
                time=sim.time,
                steps=sim.currentStep,
                evaluations=sim.n_evaluations,
                rejected=sim.n_rejected,
                frames=frames,
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
                rejected_steps=sim.n_rejected,
                frames=frames,
                wall_time_s=round(wall, 3),
                mean_sedimentation_velocity=velocity,
                final_max_bond=float(np.max(sim.bond_lengths())),
            )
            if watch is not None:
                record_checks(facts, watch)
            if links is not None:
                record_linking(facts, links)
            try:
                retire_stale_analysis(directory)  # an analysis made while it ran
                write_run_toml(directory, course.record, facts)
            except OutputError as exc:  # after a failed run, that failure is the one reported
                if status == STATUS_FINISHED:  # frames and checkpoint whole: exit 3, resumable
                    raise OutputFault(f"{exc}; the frames and checkpoint are kept: free the "
                                      f"space and run knotmm run --resume {directory}") from None
                log.warning("%s", exc)
            finally:
                lock.release()
    return result


@contextlib.contextmanager
def _signals_held():
    """Hold SIGINT and SIGTERM back for the block (a run's end: files closed, run.toml
    written); they are raised again after it. Only in the main thread (Python's handlers)."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []
    previous = {sig: signal.signal(sig, lambda signum, frame: pending.append(signum))
                for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)
        for sig in pending:
            signal.raise_signal(sig)


def _close(*reporters) -> None:
    """Close writers; a write error while flushing was already reported by the run."""
    for r in reporters:
        if r is not None:
            with contextlib.suppress(OSError):
                r.close()


def _quietly(func, *args) -> None:
    """Best effort while a run is already failing: the first error is the one reported."""
    try:
        func(*args)
    except (OSError, TrajectoryFileError) as exc:
        log.info("while stopping: %s", exc)
