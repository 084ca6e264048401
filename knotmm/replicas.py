"""Replicas: K independent copies of one run in one process (``[run] replicas = K``).

Each replica is a complete run (:func:`knotmm.workflow.run`) in ``DIR/replica_k/``
(:mod:`knotmm.io.replica_set`), with ``run.replicas = 1`` and its own ``run.seed``: the
first 32-bit word of ``numpy.random.SeedSequence(run.seed).spawn(K)[k]`` (:func:`replica_seeds`,
the seeds of a sweep's ensembles too), so replica k equals a single run with that seed, bit
for bit, and adding replicas keeps the seeds of the others. Nothing couples the copies: each
has its own System, Context, noise and step control. They run one after another in this
process, which pays the start-up of Python, OpenMM, the plugin and numba once instead of K
times (benchmarks/bench_replicas.py measures it against K single runs).

A replica whose dynamics breaks down (:class:`knotmm.errors.SimulationFault`) is recorded
as a fault in its run.toml and the others go on; an interruption (Ctrl-C, SIGTERM) stops the
set with the current replica checkpointed, and :func:`resume_replicas` goes on with every
replica not finished. ``DIR/replicas.toml`` records the set: the count, the seeds, the
shared run file.
"""

from __future__ import annotations

import contextlib
import logging
import math
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from knotmm.config import RunConfig
from knotmm.errors import RunDirectoryError, SimulationFault
from knotmm.io.replica_set import (
    REPLICA_SET_FILE,
    is_replica_set,
    read_replica_set,
    replica_directory,
    replica_index,
    write_replica_set,
)
from knotmm.io.rundir import RUN_FILE, RUN_FILES, RunLock, read_facts, run_status, writing
from knotmm.workflow import RunResult, resume, run

__all__ = ["ReplicaSetResult", "replica_seeds", "resume_replicas", "run_replicas"]

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
    """

    directory: Path
    results: list[RunResult | None]
    errors: dict[int, str] = field(default_factory=dict)
    wall_time: float = 0.0

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
        return (f"{self.count} replicas: {len(done)} simulated {t:g} tau_d{faults}; {speed}; "
                f"wall time {self.wall_time:.1f} s, in {self.directory}/replica_*")


def _set_record(cfg: RunConfig, seeds: list[int]) -> dict:
    return {"replicas": {"count": len(seeds), "seeds": seeds,
                         "directories": [f"replica_{k}" for k in range(len(seeds))]},
            "run_file": cfg.to_dict()}


def _replica_config(cfg: RunConfig, seed: int, directory: Path) -> RunConfig:
    return cfg.replace({"run.replicas": 1, "run.seed": int(seed),
                        "output.directory": str(directory)})


def _prepare_set(root: Path, count: int, overwrite: bool) -> None:
    """Refuse a directory holding something else; with ``overwrite``, clear a former set's
    replicas beyond ``count`` (knotmm's files only) and the former record."""
    if root.exists() and not root.is_dir():
        raise RunDirectoryError(f"output directory {str(root)!r} is a file; choose another --out")
    if not root.exists():
        return
    entries = [p for p in root.iterdir() if not p.name.startswith(".knotmm")]
    if not entries:
        return
    if not overwrite:
        what = ("a replica set" if is_replica_set(root)
                else f"a {run_status(root)} run" if run_status(root) else "other files")
        raise RunDirectoryError(
            f"output directory {str(root)!r} already holds {what}; pass --overwrite to "
            f"replace it, --resume to continue it, or choose another --out"
        )
    if not is_replica_set(root) and run_status(root) is None:
        raise RunDirectoryError(
            f"output directory {str(root)!r} is not empty and holds no knotmm run; choose "
            f"another --out"
        )
    with writing(root):
        for name in (*RUN_FILES, REPLICA_SET_FILE):  # a single run there before
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


def _undo_start(root: Path, lock: RunLock, existed: bool) -> None:
    """Remove what a set that failed at its first replica's start wrote."""
    lock.release()
    if not existed:
        shutil.rmtree(root, ignore_errors=True)
        return
    with contextlib.suppress(OSError):
        (root / REPLICA_SET_FILE).unlink()
    first = replica_directory(root, 0)
    if first.is_dir() and not any(first.iterdir()):
        first.rmdir()


def _one(k: int, go, errors: dict[int, str]) -> RunResult | None:
    """Run or resume replica ``k`` (``go()``); a breakdown is recorded and the set goes on."""
    try:
        return go()
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
        Bad input or an unusable directory, before anything is written (a bad run file is
        found by the first replica; the set's directory is then removed if it made it).
    KeyboardInterrupt, knotmm.engine.interrupt.StopRequested
        An interruption: the running replica is checkpointed, the set can be resumed.
    """
    count = int(cfg["run.replicas"])
    if count == 1:
        return run(cfg, directory=directory, overwrite=overwrite, progress=progress,
                   wait_for_checks=wait_for_checks)
    wall0 = time.perf_counter()
    root = Path(directory if directory is not None else cfg["output.directory"])
    existed = root.exists()
    _prepare_set(root, count, overwrite)
    seeds = replica_seeds(cfg["run.seed"], count)
    lock = RunLock(root, "run")
    errors: dict[int, str] = {}
    results: list[RunResult | None] = []
    try:
        write_replica_set(root, _set_record(cfg, seeds))
        for k, seed in enumerate(seeds):
            where = replica_directory(root, k)
            sub = _replica_config(cfg, seed, where)
            log.info("replica %d of %d (run.seed = %d) in %s", k + 1, count, seed, where)
            try:
                results.append(_one(k, lambda sub=sub, where=where: run(
                    sub, directory=where, overwrite=overwrite, progress=progress,
                    wait_for_checks=wait_for_checks), errors))
            except (ValueError, RunDirectoryError):  # bad input: ConfigError, TemplateError
                if k == 0:  # nothing run yet: leave no half-made set behind
                    _undo_start(root, lock, existed)
                raise
    finally:
        lock.release()
    return ReplicaSetResult(root, results, errors, time.perf_counter() - wall0)


def resume_replicas(directory, progress: bool | None = None, duration: float | None = None,
                    wait_for_checks: bool = False):
    """Continue a run or a replica set: every replica not finished (or, with ``duration``,
    not that far) goes on from its checkpoint; one never started starts.

    Returns
    -------
    RunResult or ReplicaSetResult
    """
    root = Path(directory)
    if not is_replica_set(root):
        return resume(root, progress=progress, duration=duration,
                      wait_for_checks=wait_for_checks)
    wall0 = time.perf_counter()
    record = read_replica_set(root)
    seeds = [int(s) for s in record.get("replicas", {}).get("seeds", [])]
    cfg = RunConfig.from_dict(record["run_file"])
    if duration is not None:
        cfg = cfg.replace({"run.duration": float(duration)})
    target = float(duration) if duration is not None else cfg["run.duration"]
    if all(_reached(_facts(replica_directory(root, k)), target) for k in range(len(seeds))):
        raise RunDirectoryError(
            f"--resume {str(root)!r}: every replica already finished at t = {target:g} tau_d; "
            f"pass --duration T with a larger T to extend them"
        )
    lock = RunLock(root, "--resume")
    errors: dict[int, str] = {}
    results: list[RunResult | None] = []
    try:
        for k, seed in enumerate(seeds):
            where = replica_directory(root, k)
            facts = _facts(where)
            if facts is None:  # never started
                sub = _replica_config(cfg, seed, where)
                results.append(_one(k, lambda sub=sub, where=where: run(
                    sub, directory=where, overwrite=True, progress=progress,
                    wait_for_checks=wait_for_checks), errors))
                continue
            if _reached(facts, target):
                results.append(_finished(where, facts))
                continue
            results.append(_one(k, lambda where=where: resume(
                where, progress=progress, duration=duration,
                wait_for_checks=wait_for_checks), errors))
        if duration is not None:
            write_replica_set(root, _set_record(cfg, seeds))
    finally:
        lock.release()
    return ReplicaSetResult(root, results, errors, time.perf_counter() - wall0)


def _facts(where: Path) -> dict | None:
    """The ``[knotmm]`` facts of the replica in ``where``; None when it never started."""
    return read_facts(where) if (where / RUN_FILE).is_file() else None


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
