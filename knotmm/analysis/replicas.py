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
"""

from __future__ import annotations

import json
import logging
import math
import re
from pathlib import Path

from knotmm.errors import ConfigError
from knotmm.io.replica_set import is_replica_set
from knotmm.io.rundir import RUN_FILE

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


def analyze_sweep(directory, **kwargs) -> dict:
    """Analyse every run of a sweep directory and write ``replicas.json``.

    Parameters
    ----------
    directory : str or Path
        A sweep directory (:func:`is_sweep_directory`).
    **kwargs
        Passed to :func:`knotmm.analysis.core.analyze_run` for every run (``plots``,
        ``knot_samples``, ``t_from``, ...).

    Returns
    -------
    dict
        The content of ``replicas.json``: ``points`` (in natural order of their names), each
        with ``runs`` (directory names), ``failed`` (name: error) and ``statistics``
        (:func:`replica_statistics`).

    Raises
    ------
    ConfigError
        If ``directory`` is not a sweep directory or holds no run.
    """
    from knotmm.analysis.core import analyze_run

    root = Path(directory)
    if not is_sweep_directory(root):
        raise ConfigError(f"{root}: not a sweep directory (no {_SWEEP_FILE}) nor a replica set")
    runs = sorted(
        (p for p in root.iterdir() if (p / RUN_FILE).is_file()), key=lambda p: _natural(p.name)
    )
    if not runs:
        raise ConfigError(f"{root}: the sweep directory holds no run directory")
    groups: dict[str, dict] = {}
    for run in runs:
        group = groups.setdefault(point_of(run.name), {"runs": [], "failed": {}, "_data": []})
        try:
            result = analyze_run(run, **kwargs)
        except Exception as exc:  # one broken replica must not stop the others
            logger.warning("analysis of %s failed: %s", run.name, exc)
            group["failed"][run.name] = f"{type(exc).__name__}: {exc}"
            continue
        group["runs"].append(run.name)
        group["_data"].append(result.to_dict())
    points = {
        name: {
            "runs": g["runs"],
            "failed": g["failed"],
            "statistics": replica_statistics(g.pop("_data")),
        }
        for name, g in groups.items()
    }
    out = {
        "method": "mean +- standard error (std / sqrt(n), ddof = 1) over the replicas of a point",
        "points": points,
    }
    (root / REPLICAS_FILE).write_text(json.dumps(out, indent=2, allow_nan=False) + "\n")
    return out
