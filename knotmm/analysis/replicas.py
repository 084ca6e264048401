"""A sweep directory analysed: mean +- standard error per point over its replicas.

Reads only the sweep directory's layout (docs/architecture.md; written by
:mod:`knotmm.sweep`): a ``sweep.toml`` file and one run directory per point and replica,
named from the swept values, with ``,replica=K`` (or ``replica=K`` alone) for the K-th
replica of a point, e.g. ``knot.beads=90,replica=3``. Every run directory (a folder with a
``run.toml``) is analysed with :func:`knotmm.analysis.core.analyze_run`, which writes its
``analysis.json``; runs whose name differs only in the replica part form one point.

Per point and per numeric value of ``analysis.json`` (the top-level numbers, the booleans
as fractions, and the numbers of ``body_frame`` as ``body_frame.<name>``): the number of
replicas with a value ``n``, the ``mean``, the standard deviation ``std`` (ddof = 1) and the
standard error ``std_error = std / sqrt(n)`` (None for n = 1). Null values (e.g.
``tau_swirl`` of a replica without swirl) are left out and counted in ``missing``. Written
to ``DIR/replicas.json``.

The mean is over the runs that reached ``run.duration``: a researcher averaging replicas
expects replicas of one length, and a run cut short (a fault) or not yet at its end is
another sample. So by default a run still running (a live process holds its lock), one
that stopped early (``run.toml`` status ``fault``, ``interrupted``, or ``running`` left by a
killed process) and a replica not started (``replicas.toml`` counts more replicas than
there are directories) are left out of the statistics and named in the point's
``excluded`` with the reason (``"replica_1": "still running (t = 20 of 200 tau_d, process
4242)"``); ``knotmm analyze`` prints them as note lines. With ``include_partial`` the
unfinished runs are averaged too and named in ``partial``. ``runs`` lists the directories
averaged, ``failed`` the finished ones whose analysis failed (with the error).

``replicas.json`` is written whole or not at all, and never replaces an earlier one by less:
when a run's analysis cannot be written (a full or read-only disk) the command stops there
(:class:`~knotmm.io.rundir.WriteFault`, exit code 3), and when no run can be averaged at all
it says why (:class:`~knotmm.errors.TrajectoryFileError`, exit code 2); in both cases an
earlier ``replicas.json`` is kept as it was.
"""

from __future__ import annotations

import json
import logging
import math
import re
from pathlib import Path

from knotmm.errors import ConfigError, TrajectoryFileError
from knotmm.io.atomic import write_text_atomic
from knotmm.io.replica_set import is_replica_set, read_replica_set, replica_directory
from knotmm.io.rundir import (
    RUN_FILE,
    STATUS_FAULT,
    STATUS_FINISHED,
    STATUS_INTERRUPTED,
    STATUS_RUNNING,
    OutputError,
    WriteFault,
    lock_owner,
    writing_output,
)

__all__ = [
    "REPLICAS_FILE",
    "analyze_sweep",
    "is_sweep_directory",
    "point_of",
    "replica_statistics",
]

logger = logging.getLogger(__name__)

#: Written into the sweep directory.
REPLICAS_FILE = "replicas.json"
_SWEEP_FILE = "sweep.toml"  # the sweep directory's marker (knotmm.sweep writes it)
_REPLICA = re.compile(r"(^|,)replica[=_]\d+(?=,|$)")


def is_sweep_directory(path) -> bool:
    """Whether ``path`` is a sweep directory (holds a ``sweep.toml``) or a replicated run's
    directory (``replicas.toml``, :mod:`knotmm.io.replica_set`: one point, its replicas)."""
    return (Path(path) / _SWEEP_FILE).is_file() or is_replica_set(path)


def point_of(name: str) -> str:
    """A run directory's point: its name without the ``replica=K`` part.

    >>> point_of("knot.beads=90,replica=3")
    'knot.beads=90'
    >>> point_of("replica=0")
    'all'
    >>> point_of("replica_2")  # a replica of a replicated run
    'all'
    """
    point = _REPLICA.sub("", name).strip(",")
    return point or "all"


def _natural(name: str):
    return [int(s) if s.isdigit() else s for s in re.split(r"(\d+)", name)]


def _numbers(analysis: dict) -> dict[str, float]:
    out: dict[str, float] = {}
    for prefix, table in (("", analysis), ("body_frame.", analysis.get("body_frame") or {})):
        for key, value in table.items():
            if isinstance(value, bool):
                out[prefix + key] = float(value)
            elif isinstance(value, (int, float)) and key not in ("n_beads", "n_frames"):
                out[prefix + key] = float(value)
            elif value is None:
                out.setdefault(prefix + key, math.nan)
    return out


def replica_statistics(analyses: list[dict]) -> dict[str, dict]:
    """Mean, standard deviation and standard error of every numeric value over replicas.

    Parameters
    ----------
    analyses : list of dict
        The ``analysis.json`` contents of one point's replicas.

    Returns
    -------
    dict
        ``{name: {"n", "missing", "mean", "std", "std_error", "values"}}`` (module docstring).
    """
    table = [_numbers(a) for a in analyses]
    names = sorted({k for row in table for k in row})
    out: dict[str, dict] = {}
    for name in names:
        raw = [row.get(name, math.nan) for row in table]
        values = [v for v in raw if math.isfinite(v)]
        n = len(values)
        mean = sum(values) / n if n else None
        std = math.sqrt(sum((v - mean) ** 2 for v in values) / (n - 1)) if n > 1 else None
        out[name] = {
            "n": n,
            "missing": len(raw) - n,
            "mean": mean,
            "std": std,
            "std_error": std / math.sqrt(n) if std is not None else None,
            "values": [v if math.isfinite(v) else None for v in raw],
        }
    return out


def analyze_sweep(directory, include_partial: bool = False, **kwargs) -> dict:
    """Analyse every run of a sweep directory and write ``replicas.json``.

    Parameters
    ----------
    directory : str or Path
        A sweep directory (:func:`is_sweep_directory`).
    include_partial : bool
        Also average the runs that stopped before ``run.duration`` (fault, interrupted,
        killed) or are still running; they are then listed in ``partial`` (module
        docstring). Default: left out and listed in ``excluded``.
    **kwargs
        Passed to :func:`knotmm.analysis.core.analyze_run` for every run (``plots``,
        ``knot_samples``, ``t_from``, ...).

    Returns
    -------
    dict
        The content of ``replicas.json``: ``points`` (in natural order of their names), each
        with ``runs`` (the directories averaged), ``excluded`` and ``partial`` (name: why),
        ``failed`` (name: error) and ``statistics`` (:func:`replica_statistics`).

    Raises
    ------
    ConfigError
        If ``directory`` is not a sweep directory or holds no run.
    TrajectoryFileError
        If no run can be averaged (all unfinished, not started or failed); the earlier
        ``replicas.json`` is kept.
    knotmm.io.rundir.WriteFault
        If a run's analysis or ``replicas.json`` cannot be written (a full or read-only
        disk; exit code 3); the earlier ``replicas.json`` is kept.
    """
    from knotmm.analysis.core import analyze_run

    root = Path(directory)
    if not is_sweep_directory(root):
        raise ConfigError(f"{root}: not a sweep directory (no {_SWEEP_FILE}) nor a replica set")
    runs = sorted(
        (p for p in root.iterdir() if (p / RUN_FILE).is_file()), key=lambda p: _natural(p.name)
    )
    expected = _counted_replicas(root)
    if not runs and not expected:
        raise ConfigError(f"{root}: the sweep directory holds no run directory")
    groups: dict[str, dict] = {}

    def group_of(name: str) -> dict:
        return groups.setdefault(point_of(name), {"runs": [], "excluded": {}, "partial": {},
                                                  "failed": {}, "_data": []})

    for run in runs:
        group = group_of(run.name)
        state = _run_state(run)
        try:
            result = analyze_run(run, **kwargs)
        except OutputError as exc:  # a full or read-only disk: the next runs would fail too
            kept = " (the earlier one is kept)" if (root / REPLICAS_FILE).exists() else ""
            raise WriteFault(f"{exc}; {REPLICAS_FILE} not written{kept}: make room and run "
                             f"knotmm analyze {str(root)!r} again") from None
        except Exception as exc:  # one broken replica must not stop the others
            if state is not None:  # unfinished: its reason, not a failure
                group["excluded"][run.name] = f"{_why(state)}; not analysed: {exc}"
                continue
            logger.warning("analysis of %s failed: %s", run.name, exc)
            group["failed"][run.name] = f"{type(exc).__name__}: {exc}"
            continue
        if state is not None:
            if state["status"] == "running" and result.data is not None and len(
                    result.data.times):
                state["time"] = float(result.data.times[-1])
            if not include_partial:
                group["excluded"][run.name] = _why(state)
                continue
            group["partial"][run.name] = _why(state)
        group["runs"].append(run.name)
        group["_data"].append(result.to_dict())
    present = {run.name for run in runs}
    for name in expected:
        if name not in present:
            group_of(name)["excluded"][name] = _not_started(root, len(expected))
    if not any(g["runs"] for g in groups.values()):
        why = "; ".join(f"{name}: {reason}" for g in groups.values()
                        for name, reason in (*g["excluded"].items(), *g["failed"].items()))
        kept = " (the earlier one is kept)" if (root / REPLICAS_FILE).exists() else ""
        raise TrajectoryFileError(
            f"{str(root)!r}: no run can be averaged ({why}); {REPLICAS_FILE} not written{kept}: "
            f"analyse again when the runs have finished"
        )
    points = {
        name: {
            "runs": g["runs"],
            "excluded": _sorted(g["excluded"]),
            **({"partial": g["partial"]} if g["partial"] else {}),
            "failed": g["failed"],
            "statistics": replica_statistics(g.pop("_data")),
        }
        for name, g in groups.items()
    }
    out = {
        "method": "mean +- standard error (std / sqrt(n), ddof = 1) over the replicas of a point",
        "unfinished_runs": "included (listed in partial)" if include_partial
        else "left out (listed in excluded)",
        "points": dict(sorted(points.items(), key=lambda item: _natural(item[0]))),
    }
    path = root / REPLICAS_FILE
    text = json.dumps(out, indent=2, allow_nan=False) + "\n"
    with writing_output(path, len(text), kept="the runs' own analysis files are written"):
        write_text_atomic(path, text)  # whole or not at all: an earlier file stays otherwise
    return out


def _counted_replicas(root: Path) -> list[str]:
    """The replica directories a replica set's ``replicas.toml`` counts ([] for a sweep)."""
    if not is_replica_set(root):
        return []
    try:
        count = int(read_replica_set(root)["replicas"]["count"])
    except (ConfigError, KeyError, TypeError, ValueError) as exc:
        logger.warning("replicas not started cannot be counted: %s", exc)
        return []
    return [replica_directory(root, k).name for k in range(count)]


def _run_state(run: Path) -> dict | None:
    """How far an unfinished run got, or None for a finished one (or one of unknown status).

    ``{"status", "time", "duration", "owner", "message"}``: ``status`` is ``"running"`` when a
    live process holds the run's lock, else its ``run.toml`` status (``fault``,
    ``interrupted``, or ``running`` left by a killed process).
    """
    from knotmm.config import read_toml

    owner = lock_owner(run)
    try:
        tables = read_toml(run / RUN_FILE)
    except ConfigError:
        tables = {}  # the analysis names what is wrong with it
    facts = tables.get("knotmm") if isinstance(tables.get("knotmm"), dict) else {}
    status = "running" if owner is not None else str(facts.get("status", STATUS_FINISHED))
    if status not in (STATUS_RUNNING, STATUS_FAULT, STATUS_INTERRUPTED):
        return None
    run_table = tables.get("run") if isinstance(tables.get("run"), dict) else {}
    return {"status": status, "time": _number(facts.get("time_reached")),
            "duration": _number(run_table.get("duration")), "owner": owner,
            "message": facts.get("message")}


def _number(value) -> float | None:
    return float(value) if isinstance(value, (int, float)) and not isinstance(
        value, bool) else None


def _why(state: dict) -> str:
    """Why a run is not averaged: ``"fault at t = 12 of 40 tau_d: ..."``."""
    t = "?" if state["time"] is None else f"{state['time']:g}"
    of = "" if state["duration"] is None else f" of {state['duration']:g}"
    where = f"t = {t}{of} tau_d"
    if state["owner"] is not None:
        who = f", process {state['owner']}" if state["owner"] else ""
        return f"still running ({where}{who})"
    if state["status"] == STATUS_FAULT:  # the message's first sentence (run.toml has it all)
        message = str(state["message"] or "").split(". Hint:")[0]
        message = re.sub(r" \([^()]*\)", "", message).strip()  # without the details
        if len(message) > 120:
            message = message[:117].rstrip() + "..."
        return f"fault at {where}" + (f": {message}" if message else "")
    if state["status"] == STATUS_INTERRUPTED:
        return f"interrupted at {where} (knotmm run --resume continues it)"
    return (f"stopped at {where} without recording its end (killed?; knotmm run --resume "
            f"continues it)")


def _not_started(root: Path, count: int) -> str:
    """Why a replica counted in ``replicas.toml`` has no run directory."""
    if lock_owner(root) is not None:
        return f"not started yet (the set of {count} replicas is running)"
    return (f"not started (the set counts {count} replicas; knotmm run --resume "
            f"{str(root)!r} runs it)")


def _sorted(table: dict[str, str]) -> dict[str, str]:
    return dict(sorted(table.items(), key=lambda item: _natural(item[0])))
