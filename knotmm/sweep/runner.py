"""Running a sweep: plan every point, run the unfinished ones, write the summary and plots.

Running a sweep (:func:`run_sweep`, ``knotmm sweep``) writes into the sweep directory ``DIR``:

=======================  ====================================================================
``DIR/sweep.toml``       the sweep file as read (with the directory as an absolute path)
``DIR/<point>/``         one ordinary run directory per point (``knotmm analyze`` works on
                         it) plus its ``analysis.json`` and analysis plots. ``<point>`` is
                         built from the swept values: ``knot.beads=40``,
                         ``knot.p=2,knot.q=5``, ``knot.beads=90,replica=3``
``DIR/summary.csv``      one row per point, in sweep order: ``point``, ``directory``, the
                         swept keys (by dotted name), ``replica`` and ``run.seed`` for
                         ensembles, ``status``, ``error``, then the analysis values
                         (:data:`~knotmm.sweep.summary.ANALYSIS_COLUMNS`); rewritten
                         atomically after every point
``DIR/ratios.png``       tau_swirl/tau_sed and tau_rot/tau_sed against the swept key
``DIR/shape.png``        rho0 (with N l0 / (2 pi p)), C and V against the swept key
``DIR/.knotmm.lock``     held (``flock``) by the sweep running in ``DIR``, with its process id
=======================  ====================================================================

A sweep directory is continued only with the keys it was started with set at every point
(``--set``, ``--duration``; ``[sweep.set]`` of ``DIR/sweep.toml``): a call that sets other
keys or values, or none where the first set some, is refused in one line (exit status 2)
naming both, before anything is written. Forgetting ``--duration 100`` on a second call
would otherwise run every finished point again at the file's duration; to change them, give
another ``--out`` (or remove ``DIR``). ``knotmm sweep DIR/sweep.toml`` continues a sweep
with the keys it recorded.

One sweep at a time owns a sweep directory: a sweep holds its lock
(:class:`~knotmm.io.rundir.RunLock`, the run directory's lock) from before its first look at
the directory until it returns, and a second sweep on it is refused at once, naming the
owner's process id (a lock left by a killed sweep is taken over).

A point's ``status`` is ``finished`` (run finished and analysed), ``analysis_failed`` (run
finished, analysis raised), ``fault`` (the dynamics broke down), ``error`` (the point could
not run: a bad template, a crashed worker, ...) or ``pending`` (not run, e.g. after an
interrupt). Running a sweep again skips finished points whose run directory still matches the
sweep file, analyses a finished run that has no ``analysis.json``, resumes an interrupted or
killed run from its checkpoint, and runs everything else again from the start (a failed
point, or one whose parameters changed in the sweep file). One failing point never stops the
others; Ctrl-C stops the workers, marks their runs ``interrupted`` and leaves a valid
``summary.csv``. The seeds of ``seeds = K`` replicas do not depend on K or on the grid, so
extending a sweep keeps the points already run.

Points run in separate processes (``workers``), or on an existing Dask distributed cluster
(``scheduler="tcp://host:port"``; Dask is the optional extra ``knotmm[cluster]``), through the
same function :func:`~knotmm.sweep.point.run_point`, so both give the same numbers. See
``docs/architecture.md``.
"""

from __future__ import annotations

import contextlib
import logging
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from knotmm.errors import ConfigError, RunDirectoryError
from knotmm.io.atomic import write_text_atomic
from knotmm.io.rundir import (
    LOCK_FILE,
    RunLock,
    WriteFault,
    describe_os_error,
    lock_owner,
    writing,
)
from knotmm.progress import Progress
from knotmm.sweep.dask import dask_client, run_dask
from knotmm.sweep.local import default_workers, run_local
from knotmm.sweep.plan import plan_point
from knotmm.sweep.plots import save_sweep_plots
from knotmm.sweep.point import error_text, run_point
from knotmm.sweep.spec import SWEEP_FILE, Sweep, describe_set, set_table
from knotmm.sweep.summary import SUMMARY_FILE, summary_text, summary_values
from knotmm.sweep.together import group_tasks, point_results

__all__ = ["SweepResult", "run_sweep"]

log = logging.getLogger(__name__)


@dataclass
class SweepResult:
    """What a sweep run did.

    Attributes
    ----------
    directory : Path
        The sweep directory.
    rows : list of dict
        The rows of ``summary.csv``, in sweep order (values as Python objects).
    summary : Path
    plots : list of Path
    ran, resumed, analysed, skipped : int
        Points simulated from the start, resumed from a checkpoint, only analysed, and
        skipped as already finished, in this call.
    wall_time : float
        Seconds.
    """

    directory: Path
    rows: list[dict[str, Any]]
    summary: Path
    plots: list[Path]
    ran: int
    resumed: int
    analysed: int
    skipped: int
    wall_time: float

    def __repr__(self) -> str:
        return (f"SweepResult({len(self.rows)} points, {len(self.failed)} not finished, "
                f"ran={self.ran}, resumed={self.resumed}, analysed={self.analysed}, "
                f"skipped={self.skipped}, directory={str(self.directory)!r})")

    @property
    def failed(self) -> list[dict[str, Any]]:
        """Rows whose status is not ``finished``."""
        return [r for r in self.rows if r["status"] != "finished"]

    def report(self) -> str:
        """A short text report: counts, then one line per failed point."""
        n = len(self.rows)
        done = n - len(self.failed)
        did = [
            f"{self.ran} run",
            f"{self.resumed} resumed",
            f"{self.analysed} analysed",
            f"{self.skipped} already finished",
        ]
        lines = [
            f"sweep: {n} point{'s' * (n != 1)}: {done} finished, {len(self.failed)} failed "
            f"(this time {', '.join(did)}; {self.wall_time:.0f} s)",
            f"wrote {self.summary}"
            + (f", {', '.join(p.name for p in self.plots)}" if self.plots else ""),
        ]
        for row in self.failed:
            lines.append(f"  {row['point']}: {row['status']}: {row['error'] or ''}".rstrip())
        return "\n".join(lines)


def run_inline(tasks, on_result, func) -> None:
    """Run the tasks one after another in this process (``workers = 0``, for debugging).

    A point interrupted by Ctrl-C or SIGTERM (:func:`~knotmm.sweep.point.run_point` returns
    it ``pending``, its run recorded ``interrupted``) stops the sweep, as with workers.
    """
    for task in tasks:
        result = func(task)
        on_result(result)
        if result.get("status") == "pending":
            raise KeyboardInterrupt


def run_sweep(
    sweep: Sweep,
    workers: int | None = None,
    scheduler: Any = None,
    progress: bool | None = None,
    reanalyze: bool = False,
    _point_function: Callable[[Mapping[str, Any]], dict] | None = None,
) -> SweepResult:
    """Run every point of a sweep that is not finished yet, analyse it, write the summary.

    Parameters
    ----------
    sweep : Sweep
        From :func:`load_sweep_file` or :meth:`Sweep.from_dict`.
    workers : int, optional
        Local worker processes (spawned, one point each at a time); default: the number of
        CPU cores divided by ``run.threads``. ``0`` runs the points one after another in this
        process (for debugging). Ignored with ``scheduler``.
    scheduler : str or distributed.Client, optional
        A Dask scheduler address (``"tcp://host:port"``), a scheduler JSON file, or a Client:
        run the points on that cluster. Its workers must have knotmm installed and see the
        sweep directory at the same path.
    progress : bool, optional
        True: a progress bar (points); False: nothing; None (default): a bar when stderr is
        a terminal, else a line each time another 10 % of the points is done
        (:class:`knotmm.progress.Progress`).
    reanalyze : bool
        Analyse finished points again instead of skipping them.

    Returns
    -------
    SweepResult

    Raises
    ------
    RunDirectoryError
        If the sweep directory holds files but no knotmm sweep, or another live sweep owns it
        (the message names its process id), or it holds a sweep started with other keys set
        at every point (``sweep.overrides``: ``--set``, ``--duration``); nothing is written
        then.
    ConfigError
        Bad ``workers``; Dask missing or the scheduler unreachable.
    KeyboardInterrupt
        After writing the summary (unfinished points ``pending``); a rerun resumes.
    """
    wall0 = time.perf_counter()
    func = _point_function or run_point
    if workers is not None and (
        isinstance(workers, bool) or int(workers) != workers or workers < 0
    ):
        raise ConfigError(f"--workers {workers!r}: expected an integer >= 0")
    directory = sweep.directory.resolve()
    if directory.exists() and not directory.is_dir():
        raise RunDirectoryError(f"sweep directory {str(directory)!r} is a file; choose another")
    client, owned = None, False
    if scheduler is not None:
        client, owned = dask_client(scheduler)  # fail before writing anything
    try:
        existed = directory.exists()
        lock = _own(directory)  # before looking inside: a sweep may be creating it now
        try:
            if _foreign(directory):
                raise RunDirectoryError(
                    f"sweep directory {str(directory)!r} is not empty and holds no knotmm "
                    f"sweep; choose another output.directory (or --out)"
                )
            return _run_sweep(sweep, directory, workers, client, progress, reanalyze, func,
                              wall0)
        finally:
            lock.release()
            if not existed:  # refused or failed before writing: leave no empty directory
                with contextlib.suppress(OSError):
                    directory.rmdir()
    finally:
        if owned:
            client.close()


def _write_summary(path: Path, columns, rows) -> None:
    """Rewrite summary.csv atomically; a failure is a :class:`WriteFault` (exit code 3)."""
    try:
        write_text_atomic(path, summary_text(columns, rows))
    except OSError as exc:
        raise WriteFault(
            f"{describe_os_error(path, exc)}; the points' run directories are kept: run the "
            "sweep again to finish it"
        ) from None


def _own(directory: Path) -> RunLock:
    """Take the sweep directory's lock; refuse in one line naming a live owner's pid."""
    try:
        return RunLock(directory, "sweep")
    except RunDirectoryError:
        owner = lock_owner(directory)
        if owner is None:  # it has just ended: its message stands
            raise
        who = f"process {owner}" if owner else "another process"
        raise RunDirectoryError(
            f"sweep refused: sweep directory {str(directory)!r} is in use by {who} (another "
            f"knotmm sweep holds its lock {LOCK_FILE}); wait for it to end or stop it first"
        ) from None


def _foreign(directory: Path) -> bool:
    """Whether ``directory`` holds files but no knotmm sweep.

    The lock and the temporary files of knotmm's atomic writes (``.sweep.toml.*.tmp``, left
    by a sweep killed while writing) do not count.
    """
    if (directory / SWEEP_FILE).exists() or (directory / SUMMARY_FILE).exists():
        return False
    ours = (f".{SWEEP_FILE}.", f".{SUMMARY_FILE}.")
    return any(
        p.name != LOCK_FILE and not (p.name.startswith(ours) and p.name.endswith(".tmp"))
        for p in directory.iterdir()
    )


def _same_set(directory: Path, sweep: Sweep) -> None:
    """Refuse (one line) to continue a sweep directory started with other keys set."""
    from knotmm.config import read_toml

    previous = directory / SWEEP_FILE
    if not previous.is_file():
        return
    try:
        table = read_toml(previous, what="sweep file").get("sweep", {})
        before = set_table(table.get("set") if isinstance(table, Mapping) else None)
    except ConfigError:  # an unreadable record is replaced, as before
        return
    now = dict(sweep.overrides)
    if before.keys() == now.keys() and all(before[k] == now[k] for k in now):
        return
    raise RunDirectoryError(
        f"sweep refused: {str(directory)!r} was started with {describe_set(before)} (its "
        f"{SWEEP_FILE}) and this call gives {describe_set(now)}: give the same to continue "
        f"it (or run `knotmm sweep {previous}`), or another --out (its finished points would "
        f"be run again)"
    )


def _run_sweep(sweep, directory, workers, client, progress, reanalyze, func, wall0):
    _same_set(directory, sweep)
    with writing(directory / SWEEP_FILE):  # nothing run yet: one line, exit code 2
        write_text_atomic(directory / SWEEP_FILE, sweep.to_toml())
    analysis_kwargs = {
        "t_from": sweep.options.t_from,
        "t_to": sweep.options.t_to,
        "plots": sweep.options.plots,
        "knot_samples": sweep.options.knot_samples,
    }
    rows: list[dict[str, Any]] = []
    tasks: list[dict[str, Any]] = []
    same_point: dict[str, tuple] = {}  # name -> the point without its seed
    idle: list[dict[str, Any]] = []  # finished replicas of such points
    counts = {"run": 0, "resume": 0, "analyze": 0, "skip": 0}
    for point in sweep.points:
        point_dir = directory / point.name
        row: dict[str, Any] = {"point": point.name, "directory": point.name}
        row.update({k: point.values.get(k) for k in sweep.keys})
        if sweep.options.seeds:
            row["replica"] = point.replica
            row["run.seed"] = point.values["run.seed"]
            same_point[point.name] = tuple(repr(point.values.get(k)) for k in sweep.keys)
        action, values = plan_point(point, point_dir, reanalyze)
        counts[action] += 1
        if action == "skip":
            row.update(status="finished", error=None, **values)
            if sweep.options.seeds:  # a copy that stays put where its point's others step
                idle.append({"name": point.name, "directory": str(point_dir),
                             "action": "skip"})
        else:
            row.update(status="pending", error=None, **summary_values(None))
            cfg = point.config.replace({"output.directory": str(point_dir)})
            tasks.append(
                {
                    "name": point.name,
                    "directory": str(point_dir),
                    "config": cfg.to_dict(),
                    "action": action,
                    "analysis": dict(analysis_kwargs),
                }
            )
        rows.append(row)
    by_name = {r["point"]: r for r in rows}
    n = None
    if client is None and workers != 0:
        n = workers if workers is not None else default_workers(sweep.base["run.threads"])
    if same_point and func is run_point:  # a point's replicas as one replicated run
        tasks = group_tasks(tasks, same_point, n, idle)
    groups = {t["name"]: [m["name"] for m in t["members"] if m["action"] != "skip"]
              for t in tasks if "members" in t}
    summary_path = directory / SUMMARY_FILE
    with writing(summary_path):
        write_text_atomic(summary_path, summary_text(sweep.columns, rows))

    bar = None
    if tasks:  # a bar on a terminal, else a line every 10 % of the points (knotmm.progress)
        bar = Progress(len(rows), "sweep", "points", enabled=progress,
                       initial=len(rows) - len(tasks))
    n_failed = 0

    def on_result(result: Mapping[str, Any]) -> None:
        for one in point_results(result, groups):
            on_point(one)

    def on_point(result: Mapping[str, Any]) -> None:
        nonlocal n_failed
        row = by_name[result["name"]]
        row.update(result.get("values") or summary_values(None))
        row["status"], row["error"] = result["status"], result["error"]
        if result["status"] != "finished":
            n_failed += 1
            log.info("point %s: %s: %s", result["name"], result["status"], result["error"])
        else:
            log.info("point %s finished", result["name"])
        _write_summary(summary_path, sweep.columns, rows)
        if bar is not None:
            bar.update(1, f"{n_failed} failed" if n_failed else "")

    stopped = None
    try:
        if not tasks:
            pass
        elif client is not None:
            run_dask(tasks, client, on_result, func)
        elif workers == 0:
            run_inline(tasks, on_result, func)
        else:
            run_local(tasks, n, on_result, func)
    except BaseException as exc:
        stopped = exc
        raise
    finally:
        if bar is not None:
            bar.close()
        try:
            _write_summary(summary_path, sweep.columns, rows)
        except WriteFault as exc:
            if stopped is None:
                raise
            if not isinstance(stopped, WriteFault):  # the first failure is the one reported
                log.warning("%s", exc)

    plots = []
    try:
        plots = save_sweep_plots(
            rows,
            directory,
            sweep.x_key,
            sweep.keys,
            # in zip mode the other keys change together with x: one series
            group_by=[] if sweep.options.mode == "zip" else list(sweep.keys),
            log_x=sweep.options.log_x,
        )
    except Exception as exc:  # a plot must not lose the sweep's results
        from knotmm.io.rundir import describe_os_error

        why = describe_os_error(directory, exc) if isinstance(exc, OSError) else error_text(exc)
        log.warning("sweep plots not written: %s", why)
    return SweepResult(
        directory=directory,
        rows=rows,
        summary=summary_path,
        plots=plots,
        ran=counts["run"],
        resumed=counts["resume"],
        analysed=counts["analyze"],
        skipped=counts["skip"],
        wall_time=time.perf_counter() - wall0,
    )
