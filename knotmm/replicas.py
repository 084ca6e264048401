"""Replicas: K independent copies of one run in one process (``[run] replicas = K``).

Each replica is a complete run (:func:`knotmm.workflow.run`) in ``DIR/replica_k/``
(:mod:`knotmm.io.replica_set`), with ``run.replicas = 1`` and its own ``run.seed``: the
first 32-bit word of ``numpy.random.SeedSequence(run.seed).spawn(K)[k]`` (:func:`replica_seeds`,
the seeds of a sweep's ensembles too), so replica k equals a single run with that seed, bit
for bit when it runs alone, and adding replicas keeps the seeds of the others. Nothing
couples the copies' physics: each has its own System, Context, noise and step control.

Where the plugin can (:func:`knotmm.engine.copies.copies_refusal`: the plugin engine on a
platform that holds copies, systems small enough) the replicas run side by side, each in a
thread, and their steps are taken together by a :class:`knotmm.engine.copies.CopyGroup`: K
copies of the system in one Context, one force evaluation for all, each copy its own steps;
replica k then equals the single run to rounding. Elsewhere they run one after another.
On the host platforms ``run.replicas_at_once`` of them (auto: one per free core) step at the
same time, each in a thread: replicas one after another side by side, or groups of copies
(:func:`knotmm.engine.copies.replicas_at_once`). Either way the process pays the start-up
of Python, OpenMM, the plugin and numba once instead of K times
(``benchmarks/bench_workflow.py replicas`` measures it against K single runs); the choice
and its reason are in ``replicas.toml`` (``stepping``, ``stepping_reason``, ``at_once``,
``at_once_reason``) and in each replica's run.toml (``replica_stepping``).

A replica whose dynamics breaks down (:class:`knotmm.errors.SimulationFault`) is recorded
as a fault in its run.toml and the others go on; a file that cannot be written (a full disk)
and an interruption (Ctrl-C, SIGTERM) stop the set with the current replica checkpointed (or,
stopped at its start, leaving nothing), and :func:`resume_replicas` goes on with every
replica not finished. A set is checked whole (every refusal of its input) before the lock on
its directory is taken, and the directory before anything in it is deleted.
``DIR/replicas.toml`` records the set: the count, the seeds, the shared run file.
"""

from __future__ import annotations

import contextlib
import logging
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from knotmm.config import RunConfig
from knotmm.engine.copies import (
    MAX_TOGETHER,
    OneAfterAnother,
    copies_refusal,
    replicas_at_once,
    run_side_by_side,
    run_together,
)
from knotmm.errors import ConfigError, RunDirectoryError, SimulationFault
from knotmm.io.replica_set import (
    REPLICA_SET_FILE,
    is_replica_set,
    read_replica_set,
    replica_directory,
    replica_index,
    write_replica_set,
)
from knotmm.io.rundir import (
    CHECKPOINT_FILE,
    RUN_FILE,
    RUN_FILES,
    STATUS_FINISHED,
    OutputError,
    RunLock,
    WriteFault,
    lock_owner,
    read_facts,
    run_status,
    writing,
)
from knotmm.plan import prepare
from knotmm.workflow import OutputFault, RunResult, resume, run

__all__ = [
    "ReplicaSetResult",
    "identical_replicas_note",
    "replica_seeds",
    "resume_replicas",
    "run_replicas",
]

log = logging.getLogger(__name__)


def replica_seeds(base_seed: int, count: int) -> list[int]:
    """Seeds of ``count`` replicas, derived reproducibly from ``base_seed``.

    Replica k gets the first 32-bit word of
    ``numpy.random.SeedSequence(base_seed).spawn(count)[k]`` (spawn key ``(k,)``), so its seed
    does not depend on ``count``.

    Returns
    -------
    list of int, length count, each in [0, 2**32)
    """
    children = np.random.SeedSequence(int(base_seed)).spawn(int(count))
    return [int(c.generate_state(1, dtype=np.uint32)[0]) for c in children]


def identical_replicas_note(cfg: RunConfig, count: int, what: str = "run.replicas") -> str | None:
    """The note that ``count`` replicas of ``cfg`` would be identical, or None.

    Replicas differ only by their seeds, which act through the noise (finite ``run.peclet``)
    and the template's perturbation (``knot.perturbation``); with neither they repeat one
    run. The one wording, printed as ``knotmm: note:`` by ``knotmm run`` (``run.replicas``)
    and ``knotmm sweep`` (``seeds``).

    Parameters
    ----------
    cfg : RunConfig
    count : int
        How many replicas are asked for.
    what : str
        The key that asks for them, as the note names it.
    """
    if count > 1 and cfg["knot.perturbation"] == 0 and math.isinf(cfg["run.peclet"]):
        return (f"{what} = {count} but the runs are deterministic (knot.perturbation = 0, "
                f"run.peclet = inf): the replicas will be identical; set knot.perturbation > 0")
    return None


@dataclass
class ReplicaSetResult:
    """What a replicated run did.

    Attributes
    ----------
    directory : Path
        The set's directory.
    results : list of RunResult or None
        Per replica: its result, None where it broke down (see ``errors``).
    errors : dict
        Replica index -> the one-line message of its fault.
    wall_time : float
        Seconds for the whole set.
    stepping : str
        ``"stepped together"`` or ``"one after another"``, and how many at once where
        several (``replicas.toml`` says why).
    """

    directory: Path
    results: list[RunResult | None]
    errors: dict[int, str] = field(default_factory=dict)
    wall_time: float = 0.0
    stepping: str = ""

    @property
    def count(self) -> int:
        return len(self.results)

    def summary(self) -> str:
        """The one-line summary the CLI prints."""
        done = [r for r in self.results if r is not None]
        speeds = np.array([r.sedimentation_velocity for r in done])
        if len(speeds) > 1:
            se = speeds.std(ddof=1) / math.sqrt(len(speeds))
            speed = f"mean sedimentation speed {speeds.mean():.4f} +- {se:.4f} d/tau_d"
        elif len(speeds) == 1:
            speed = f"mean sedimentation speed {speeds[0]:.4f} d/tau_d (one replica)"
        else:
            speed = "no replica finished"
        faults = f", {len(self.errors)} broke down ({', '.join(map(str, self.errors))})" \
            if self.errors else ""
        t = done[0].time if done else 0.0
        how = f" ({self.stepping})" if self.stepping else ""
        return (f"{self.count} replicas{how}: {len(done)} simulated {t:g} tau_d{faults}; "
                f"{speed}; wall time {self.wall_time:.1f} s, in {self.directory}/replica_*")


def _set_record(cfg: RunConfig, seeds: list[int], refusal: str | None,
                at_once: tuple[int, str] = (1, "")) -> dict:
    stepping = ({"stepping": "together", "stepping_reason": _TOGETHER} if refusal is None
                else {"stepping": "one after another", "stepping_reason": refusal})
    return {"replicas": {"count": len(seeds), "seeds": seeds,
                         "directories": [f"replica_{k}" for k in range(len(seeds))],
                         **stepping, "at_once": at_once[0], "at_once_reason": at_once[1]},
            "run_file": cfg.to_dict()}


def _stepping(together: bool, at_once: int) -> str:
    """How the set stepped, for its summary line."""
    how = "stepped together" if together else "one after another"
    return how + (f", {at_once} {'groups' if together else 'replicas'} at once"
                  if at_once > 1 else "")


def _at_once(cfg: RunConfig, count: int, engine: str, platform: str) -> tuple[int, str]:
    """:func:`knotmm.engine.copies.replicas_at_once` for ``count`` replicas of ``cfg``."""
    return replicas_at_once(cfg["run.replicas_at_once"], count, engine, platform,
                            cfg["run.threads"] * cfg["run.mobility_threads"])


def _side_by_side(count: int, go, errors: dict[int, str], root: Path,
                  at_once: int) -> list[RunResult | None]:
    """Run replica k as ``go(k, lane)``, ``at_once`` at a time, each in a thread
    (:func:`knotmm.engine.copies.run_side_by_side`: lane 0's replicas show the progress);
    failures as :func:`_together`'s."""
    results: list[RunResult | None] = [None] * count

    def body(k, lane):
        results[k] = _one(k, lambda: go(k, lane), errors, root)

    _raise_first(run_side_by_side(count, body, at_once))
    return results


def _raise_first(failures: dict[int, BaseException]) -> None:
    """Raise the first failure of a set's runs, an interruption first."""
    if failures:
        stops = [e for e in failures.values() if isinstance(e, KeyboardInterrupt)]
        raise stops[0] if stops else failures[min(failures)]


_TOGETHER = ("the replicas are copies of one system in one OpenMM Context: one force "
             "evaluation for all, each its own steps (knotmm.engine.copies)")


def _together(count: int, go, errors: dict[int, str],
              root: Path, at_once: int = 1) -> list[RunResult | None]:
    """Run the replicas, each in a thread, stepped as copies of one Context
    (:func:`knotmm.engine.copies.run_together`, in groups of at most :data:`MAX_TOGETHER`,
    ``at_once`` groups at the same time): replica k runs ``go(k, (group, copy))``. The first
    failure (an interruption first) is raised once every replica of its group has ended."""
    results: list[RunResult | None] = [None] * count

    def body(k, copies):
        results[k] = _one(k, lambda: go(k, copies), errors, root)

    _raise_first(run_together(count, body, MAX_TOGETHER, at_once))
    return results


def _replica_config(cfg: RunConfig, seed: int, directory: Path) -> RunConfig:
    return cfg.replace({"run.replicas": 1, "run.seed": int(seed),
                        "output.directory": str(directory)})


def _check_replicas(cfg: RunConfig, root: Path,
                    seeds: list[int]) -> tuple[str | None, tuple[int, str]]:
    """Every check of the input that can refuse the set, before anything is written; why
    the replicas are not stepped together (None if they are) and how many step at once
    (:func:`_at_once`).

    Replica 0 is planned as :func:`knotmm.workflow.run` plans a run (the integrator against
    ``run.peclet``, the template and its geometry and overlap checks, the Simulation:
    :func:`knotmm.plan.prepare`); the templates of the others are checked too, with that
    plan's memory budget, when the template depends on ``run.seed`` (a perturbation), which
    replica 1's shows.
    """
    from knotmm.shapes.builder import build_template

    if root.exists() and not root.is_dir():
        raise RunDirectoryError(f"output directory {str(root)!r} is a file; choose another --out")
    first = resources = refusal = None
    at_once = (1, "")
    for k, seed in enumerate(seeds):
        sub = _replica_config(cfg, seed, replica_directory(root, k))
        if k == 0:
            built = prepare(sub, identify="skip")
            first, resources = built.template.positions, built.plan.resources
            sim = built.simulation
            at_once = _at_once(cfg, len(seeds), sim.engine, sim.platform_name)
            refusal = copies_refusal(sim.engine, sim.platform_name, len(seeds),
                                     cfg["run.replica_stepping"], sim.n_beads,
                                     math.isfinite(cfg["run.peclet"]), at_once[0])
            if refusal is None:  # groups of two copies at least
                at_once = (max(1, min(at_once[0], len(seeds) // 2)), at_once[1])
            continue
        positions = build_template(sub, identify="skip", resources=resources).positions
        if k == 1 and np.array_equal(positions, first):
            break  # the start does not depend on the seed: the others are replica 0's
    return refusal, at_once


def _prepare_set(root: Path, count: int, overwrite: bool, record: dict) -> bytes | None:
    """In the locked ``root``: refuse a directory holding something else, write the set's
    record, and with ``overwrite`` clear a former set's replicas beyond ``count`` and a
    former single run there (knotmm's files only). Nothing is deleted before every refusal
    and the record's write have passed. Returns the former record's bytes (None if none).
    """
    entries = [p for p in root.iterdir() if not p.name.startswith(".knotmm")]
    if entries and not overwrite:
        what = ("a replica set" if is_replica_set(root)
                else f"a {run_status(root)} run" if run_status(root) else "other files")
        raise RunDirectoryError(
            f"output directory {str(root)!r} already holds {what}; pass --overwrite to "
            f"replace it, --resume to continue it, or choose another --out"
        )
    if entries and not is_replica_set(root) and run_status(root) is None:
        raise RunDirectoryError(
            f"output directory {str(root)!r} is not empty and holds no knotmm run; choose "
            f"another --out"
        )
    for k in range(count):
        where = replica_directory(root, k)
        if where.exists() and not where.is_dir():
            raise RunDirectoryError(
                f"output directory {str(root)!r}: {where.name} is a file, where replica {k} "
                f"writes its run; move it away, or choose another --out"
            )
    for p in entries:  # a replica resumed on its own (knotmm run --resume DIR/replica_K)
        owner = lock_owner(p) if replica_index(p.name) is not None else None
        if owner is not None:
            raise RunDirectoryError(
                f"run refused: {str(p)!r} is in use by process {owner or '(unknown)'}; wait "
                f"for it to end or stop it first"
            )
    with writing(root / REPLICA_SET_FILE):
        previous = ((root / REPLICA_SET_FILE).read_bytes() if is_replica_set(root) else None)
    write_replica_set(root, record)  # atomic: the former record stays if it fails
    with writing(root):
        for name in RUN_FILES:  # a single run there before
            with contextlib.suppress(FileNotFoundError):
                (root / name).unlink()
        for p in root.iterdir():
            k = replica_index(p.name)
            if k is not None and k >= count and p.is_dir():
                for name in RUN_FILES:
                    with contextlib.suppress(FileNotFoundError):
                        (p / name).unlink()
                with contextlib.suppress(OSError):
                    p.rmdir()
    return previous


def _undo_start(root: Path, lock: RunLock, previous: bytes | None) -> None:
    """Take back the record of a set whose first replica was refused at its start: the
    former set's record is put back (``previous``), a new one removed; the directories this
    start made go when empty."""
    from knotmm.io.atomic import write_atomic

    with contextlib.suppress(OSError):
        if previous is None:
            (root / REPLICA_SET_FILE).unlink()
        else:
            write_atomic(root / REPLICA_SET_FILE, lambda fh: fh.write(previous))
    with contextlib.suppress(OSError):
        replica_directory(root, 0).rmdir()  # only when empty
    lock.release()
    if lock.created:
        with contextlib.suppress(OSError):
            root.rmdir()


def _one(k: int, go, errors: dict[int, str], root: Path) -> RunResult | None:
    """Run or resume replica ``k`` (``go()``); a breakdown of its dynamics is recorded and
    the set goes on.

    A file that cannot be written (a full disk, no permission: the place, not the replica)
    stops the set with :class:`~knotmm.io.rundir.WriteFault` (exit code 3): the replicas
    before it are kept, and a replica that could not start left nothing
    (:func:`knotmm.io.rundir.starting`), so ``knotmm run --resume`` goes on with it.
    """
    try:
        return go()
    except (OutputError, OutputFault) as exc:
        cause = " ".join(str(exc).split()).split("; the frames written so far")[0]
        raise WriteFault(
            f"replica {k} of the set in {str(root)!r} stopped: {cause}; what was written is "
            f"kept: free the space (or fix the permissions) and run knotmm run --resume {root}"
        ) from None
    except SimulationFault as exc:
        message = " ".join(str(exc).split())
        log.warning("replica %d broke down: %s", k, message)
        errors[k] = message
        return None


def run_replicas(cfg: RunConfig, directory=None, overwrite: bool = False,
                 progress: bool | None = None, wait_for_checks: bool = False):
    """Run ``cfg``: one run, or its ``run.replicas`` replicas (module docstring).

    Parameters are those of :func:`knotmm.workflow.run`.

    Returns
    -------
    RunResult or ReplicaSetResult

    Raises
    ------
    ConfigError, TemplateError, RunDirectoryError, OutputError
        Bad input, an unusable directory or a live process owning it, before anything in
        the directory is touched or deleted (the input is checked first, then the lock is
        taken, then the directory is checked).
    knotmm.io.rundir.WriteFault
        A replica's file cannot be written (exit code 3): the set stops, ``knotmm run
        --resume`` continues it once the cause is gone.
    KeyboardInterrupt, knotmm.engine.interrupt.StopRequested
        An interruption: the running replica is checkpointed, the set can be resumed.
    """
    count = int(cfg["run.replicas"])
    if count == 1:
        return run(cfg, directory=directory, overwrite=overwrite, progress=progress,
                   wait_for_checks=wait_for_checks)
    wall0 = time.perf_counter()
    root = Path(directory if directory is not None else cfg["output.directory"])
    seeds = replica_seeds(cfg["run.seed"], count)
    refusal, at_once = _check_replicas(cfg, root, seeds)
    lock = RunLock(root, "run")  # before anything in root is touched
    errors: dict[int, str] = {}
    results: list[RunResult | None] = []
    try:
        try:
            previous = _prepare_set(root, count, overwrite,
                                    _set_record(cfg, seeds, refusal, at_once))
        except BaseException:
            if lock.created:
                lock.release()
                with contextlib.suppress(OSError):
                    root.rmdir()
            raise
        def go(k, copies, shows_progress):
            where = replica_directory(root, k)
            return run(_replica_config(cfg, seeds[k], where), directory=where,
                       overwrite=overwrite, progress=progress if shows_progress else False,
                       wait_for_checks=wait_for_checks, copies=copies)

        if refusal is None or at_once[0] > 1:  # in threads: together, or side by side
            log.info("%d replicas stepped %s in %s, %d at once", count,
                     "together" if refusal is None else "one after another", root, at_once[0])
            alone = OneAfterAnother(refusal)
            try:
                results = (_together(count, lambda k, copies: go(k, copies, k == 0), errors,
                                     root, at_once[0]) if refusal is None
                           else _side_by_side(count, lambda k, lane: go(k, alone, lane == 0),
                                              errors, root, at_once[0]))
            except (ValueError, RunDirectoryError):
                if not any((replica_directory(root, k) / RUN_FILE).exists()
                           for k in range(count)):
                    _undo_start(root, lock, previous)
                raise
        for k, seed in enumerate(seeds if refusal is not None and at_once[0] == 1 else []):
            where = replica_directory(root, k)
            sub = _replica_config(cfg, seed, where)
            log.info("replica %d of %d (run.seed = %d) in %s", k + 1, count, seed, where)
            try:
                results.append(_one(k, lambda sub=sub, where=where: run(
                    sub, directory=where, overwrite=overwrite, progress=progress,
                    wait_for_checks=wait_for_checks, copies=OneAfterAnother(refusal)),
                    errors, root))
            except (ValueError, RunDirectoryError):  # refused: a live owner of replica_0, ...
                if k == 0:  # nothing run yet: leave no half-made set behind
                    _undo_start(root, lock, previous)
                raise
    finally:
        lock.release()
    return ReplicaSetResult(root, results, errors, time.perf_counter() - wall0,
                            _stepping(refusal is None, at_once[0]))


def resume_replicas(directory, progress: bool | None = None, duration: float | None = None,
                    wait_for_checks: bool = False):
    """Continue a run or a replica set: every replica not finished (or, with ``duration``,
    not that far) goes on from its checkpoint; one never started, or stopped before its
    first checkpoint, starts from its start.

    Returns
    -------
    RunResult or ReplicaSetResult

    Raises
    ------
    ConfigError
        A damaged ``replicas.toml`` (one line naming it).
    RunDirectoryError
        Every replica finished already, or a live process owns the directory.
    """
    root = Path(directory)
    if not is_replica_set(root):
        return resume(root, progress=progress, duration=duration,
                      wait_for_checks=wait_for_checks)
    wall0 = time.perf_counter()
    record = read_replica_set(root)  # checked: a damaged record is one line
    seeds = [int(s) for s in record["replicas"]["seeds"]]
    try:
        cfg = RunConfig.from_dict(record["run_file"])
    except ConfigError as exc:
        raise ConfigError(f"{root / REPLICA_SET_FILE} [run_file]: {exc}") from None
    if duration is not None:
        cfg = cfg.replace({"run.duration": float(duration)})
    target = float(duration) if duration is not None else cfg["run.duration"]
    before = [_facts(replica_directory(root, k)) for k in range(len(seeds))]  # (unlocked)
    if all(_reached(f, target) for f in before):
        reached = min(float(f.get("time_reached", 0.0) or 0.0) for f in before)
        raise RunDirectoryError(
            f"--resume {str(root)!r}: every replica already finished, at t = {reached:g} "
            f"tau_d or later; pass --duration T with T > {reached:g} to extend them"
        )
    lock = RunLock(root, "--resume")
    errors: dict[int, str] = {}
    results: list[RunResult | None] = []
    together = record["replicas"].get("stepping") == "together" and len(seeds) > 1
    alone = OneAfterAnother(record["replicas"].get("stepping_reason", "one after another"))
    ran = next((f for f in before if f and f.get("engine") and f.get("platform")), None)
    pending = sum(not _reached(f, target) for f in before)
    at_once = (_at_once(cfg, pending // 2 if together else pending, ran["engine"],
                        ran["platform"]) if ran else (1, "no replica had run: one at a time"))
    try:
        if together or at_once[0] > 1:  # in threads: together, or side by side
            def go(k, copies, shows_progress):
                return _resume_one(root, k, seeds[k], cfg, target, duration,
                                   progress if shows_progress else False, wait_for_checks,
                                   copies)

            results = (_together(len(seeds), lambda k, copies: go(k, copies, k == 0), errors,
                                 root, at_once[0]) if together
                       else _side_by_side(len(seeds), lambda k, lane: go(k, alone, lane == 0),
                                          errors, root, at_once[0]))
        for k, seed in enumerate([] if together or at_once[0] > 1 else seeds):
            results.append(_one(k, lambda k=k, seed=seed: _resume_one(
                root, k, seed, cfg, target, duration, progress, wait_for_checks, alone),
                errors, root))
        if duration is not None:
            refusal = None if together else record["replicas"].get(
                "stepping_reason", "one after another")
            write_replica_set(root, _set_record(cfg, seeds, refusal, at_once))
    finally:
        lock.release()
    return ReplicaSetResult(root, results, errors, time.perf_counter() - wall0,
                            _stepping(together, at_once[0]))


def _resume_one(root: Path, k: int, seed: int, cfg: RunConfig, target: float,
                duration: float | None, progress, wait_for_checks: bool, copies):
    """Go on with replica ``k`` of a set (``resume_replicas``): from its checkpoint, from its
    start, or (finished) its result as it stands."""
    where = replica_directory(root, k)
    facts = _facts(where)
    if facts is None:  # never started, or nothing of it worth keeping
        if (where / RUN_FILE).exists():
            log.info("replica %d stopped before its first checkpoint: it starts again from "
                     "its start", k)
        return run(_replica_config(cfg, seed, where), directory=where, overwrite=True,
                   progress=progress, wait_for_checks=wait_for_checks, copies=copies)
    if _reached(facts, target):
        return _finished(where, facts)
    return resume(where, progress=progress, duration=duration,
                  wait_for_checks=wait_for_checks, copies=copies)


def _facts(where: Path) -> dict | None:
    """The ``[knotmm]`` facts of the replica in ``where``; None when it has nothing to go on
    from: it never started, or it stopped before its first checkpoint (no checkpoint and a
    run.toml that is not finished, or unreadable), so it starts again from its start."""
    if not (where / RUN_FILE).is_file():
        return None
    checkpointed = (where / CHECKPOINT_FILE).is_file()
    try:
        facts = read_facts(where)
    except ConfigError:
        if checkpointed:
            raise
        return None
    if not checkpointed and facts.get("status") != STATUS_FINISHED:
        return None
    return facts


def _reached(facts: dict | None, target: float) -> bool:
    """Whether a replica with these facts finished at ``target`` tau_d or later."""
    if facts is None or facts.get("status") != "finished":
        return False
    return float(facts.get("time_reached", 0.0) or 0.0) >= target - 1e-9


def _finished(where: Path, facts: dict) -> RunResult:
    """The result of a replica finished before (from its run.toml)."""
    return RunResult(
        directory=where,
        time=float(facts.get("time_reached", 0.0)),
        steps=int(facts.get("steps", 0)),
        evaluations=int(facts.get("evaluations", 0)),
        rejected=int(facts.get("rejected_steps", 0)),
        frames=int(facts.get("frames", 0)),
        wall_time=0.0,
        sedimentation_velocity=float(facts.get("mean_sedimentation_velocity", 0.0)),
        session_steps=0,
    )
