"""One sweep point: run (or resume, or only analyse) it and return its summary values.

:func:`run_point` is the function every executor runs (inline, in a local worker process,
on a Dask worker), so every executor gives the same numbers. It depends only on its
argument and the files, and never raises for a failure of the point: the failure becomes
the point's ``status`` and ``error``.
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from knotmm.config import RunConfig
from knotmm.errors import ConfigError
from knotmm.sweep.summary import summary_values, time_reached

__all__ = ["INTERRUPT_EXIT", "error_text", "lost_result", "run_group", "run_point"]

log = logging.getLogger(__name__)

#: Exit status of a local worker stopped by SIGINT.
INTERRUPT_EXIT = 130


class WorkerState:
    """In a local worker process: a point is being computed / the sweep is being stopped."""

    running = False
    stopping = False


def error_text(exc: BaseException) -> str:
    """An exception as one line: ``"TypeName: message"``."""
    text = " ".join(str(exc).split()) or "no message"
    return f"{type(exc).__name__}: {text}"


def lost_result(name: str, why: str) -> dict[str, Any]:
    """The result of a point whose worker never returned one (``status = "error"``)."""
    return {"name": name, "status": "error", "error": why, "values": {}}


def leave() -> None:  # pragma: no cover - runs in the worker processes
    """End a local worker now, with the processes it started (the runs' knot-check workers)."""
    import signal

    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    children = multiprocessing.active_children()
    for child in children:
        child.kill()
    for child in children:
        child.join(timeout=2.0)
    os._exit(INTERRUPT_EXIT)


def _interrupted(name: str) -> dict[str, Any]:
    if WorkerState.stopping:  # a local worker told to stop: the run's files are closed, leave
        leave()
    return _interrupted_quietly(name)


def _interrupted_quietly(name: str) -> dict[str, Any]:
    return {"name": name, "status": "pending", "error": "interrupted", "values": {}}


def run_point(task: Mapping[str, Any]) -> dict[str, Any]:
    """Run (or only analyse) one sweep point; never raises for a failure of the point.

    This is the function that worker processes and Dask workers execute. It depends only on
    its argument and the files, so local and Dask execution give the same numbers.

    Parameters
    ----------
    task : dict
        ``name`` (str), ``directory`` (absolute path of the point's run directory),
        ``config`` (nested run-file dict), ``action`` (``"run"``: simulate then analyse,
        ``"resume"``: continue an interrupted run from its checkpoint, or run it again when
        that is not possible, then analyse, ``"analyze"``: analyse an existing finished
        run), ``analysis`` (keyword arguments of
        :func:`knotmm.analysis.analyze_run`: ``t_from``, ``t_to``, ``plots``,
        ``knot_samples``). Or the replicas of one point to step together: ``name`` and
        ``members``, each such a task (:func:`run_group`, which then returns).

    Returns
    -------
    dict
        ``name``, ``status`` (one of :data:`knotmm.sweep.summary.STATUSES`), ``error``
        (one line or None), ``values`` (:func:`knotmm.sweep.summary.summary_values`, with
        ``time_reached``).
    """
    if "members" in task:
        return run_group(task)
    with _computing():
        return _run_point(task)


@contextlib.contextmanager
def _computing():
    """A point (or a group of them) is being computed: :class:`WorkerState` says so, and
    the runs' warnings (a change of knot type, ...), which are in their run.toml and
    analysis.json, are not printed (a sweep of many points would print them interleaved)."""
    WorkerState.running = True
    knotmm_log = logging.getLogger("knotmm")
    level = knotmm_log.level
    if knotmm_log.getEffectiveLevel() < logging.ERROR:
        knotmm_log.setLevel(logging.ERROR)
    try:
        yield
    finally:
        knotmm_log.setLevel(level)
        WorkerState.running = False


def _run_point(task: Mapping[str, Any]) -> dict[str, Any]:
    from knotmm.engine.copies import OneAfterAnother

    why = task.get("stepping")  # a replica whose point's replicas run one by one
    outcome = _simulate(task, None if why is None else OneAfterAnother(why))
    if outcome is None:
        return _interrupted(task["name"])
    return _analyse(task, *outcome)


def _simulate(task: Mapping[str, Any], copies=None) -> tuple[str, str | None] | None:
    """Run or resume the point's simulation: ``(status, error)``, or None if interrupted.
    ``copies``: ``(group, k)`` where the point is copy k of a
    :class:`~knotmm.engine.copies.CopyGroup` (:func:`run_group`), a
    :class:`~knotmm.engine.copies.OneAfterAnother` where it is a replica run on its own."""
    from knotmm.errors import SimulationFault

    name = task["name"]
    directory = Path(task["directory"])
    action = task.get("action", "run")
    if action == "skip":  # a finished replica beside its point's others: it stays put
        return "finished", None
    try:
        if action == "resume":
            from knotmm.errors import RunDirectoryError, TrajectoryFileError
            from knotmm.workflow import resume

            try:
                resume(directory, progress=False, wait_for_checks=True, copies=copies)
            except (ConfigError, TrajectoryFileError, RunDirectoryError) as exc:
                log.info("point %s cannot be resumed (%s): running it again", name, exc)
                action = "run"
        if action == "run":
            from knotmm.workflow import run

            cfg = RunConfig.from_dict(task["config"])
            # a sweep's analysis waits for topoly next anyway: the run's checks are kept
            run(cfg, directory=directory, overwrite=True, progress=False, wait_for_checks=True,
                copies=copies)
    except SimulationFault as exc:
        return "fault", error_text(exc)
    except KeyboardInterrupt:
        return None
    except Exception as exc:  # any failure of this point is reported, never raised
        log.debug("point %s failed", name, exc_info=True)
        return "error", error_text(exc)
    return "finished", None


def _analyse(task: Mapping[str, Any], status: str, error: str | None) -> dict[str, Any]:
    """The point's result: its run analysed where it finished (``run_point``'s return)."""
    name = task["name"]
    directory = Path(task["directory"])
    analysis = None
    if status == "finished":
        try:
            import matplotlib

            matplotlib.use("Agg")
            from knotmm.analysis import analyze_run

            result = analyze_run(directory, **task.get("analysis", {}))
            analysis = result.to_dict()
        except KeyboardInterrupt:
            return _interrupted(name)
        except Exception as exc:
            status, error = "analysis_failed", error_text(exc)
            log.debug("analysis of point %s failed", name, exc_info=True)
    values = summary_values(analysis)
    values["time_reached"] = time_reached(directory)
    return {"name": name, "status": status, "error": error, "values": values}


def run_group(task: Mapping[str, Any]) -> dict[str, Any]:
    """Run the replicas of one sweep point (``seeds = K``) stepped together, as one replicated
    run steps its replicas (:func:`knotmm.engine.copies.run_together`: copies of one OpenMM
    Context, each its own steps); then analyse each. A replica that cannot be a copy of the
    others (its engine, its system) runs alone beside them, as in a replicated run.

    Parameters
    ----------
    task : dict
        ``name`` (the group's), ``members``: the points' own tasks (:func:`run_point`); a
        member ``"skip"`` (finished) is a copy that stays put and gets no result.

    Returns
    -------
    dict
        ``name``, ``status`` (``"pending"`` if any replica was interrupted, else
        ``"finished"``), ``group``: the members' results, each as :func:`run_point`'s.
    """
    from knotmm.engine.copies import run_together
    from knotmm.engine.interrupt import request_stop

    members = list(task["members"])
    outcomes: list[tuple[str, str | None] | None] = [None] * len(members)

    def body(k, copies):
        outcomes[k] = _simulate(members[k], copies)
        if outcomes[k] is None:
            request_stop()  # the other replicas stop at their next step too

    with _computing():
        failures = run_together(len(members), body)
        shown = [k for k, m in enumerate(members) if m.get("action") != "skip"]
        if failures or any(o is None for o in outcomes):
            results = [_interrupted_quietly(members[k]["name"]) for k in shown]
        else:
            results = [_analyse(members[k], *outcomes[k]) for k in shown]
    if any(r["status"] == "pending" for r in results) and WorkerState.stopping:
        leave()
    status = "pending" if any(r["status"] == "pending" for r in results) else "finished"
    return {"name": task["name"], "status": status, "error": None, "group": results}
