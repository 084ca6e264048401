"""The sweep's table: ``summary.csv`` rows, from each point's ``analysis.json`` and ``run.toml``.

``DIR/summary.csv`` has one row per point, in sweep order: ``point``, ``directory``, the
swept keys (by dotted name), ``replica`` and ``run.seed`` for ensembles, ``status``,
``error``, then the analysis values (:data:`ANALYSIS_COLUMNS`). It is rewritten atomically
after every point; its columns are those listed here (the API reference shows them).
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from knotmm.errors import ConfigError
from knotmm.io.rundir import read_facts

__all__ = [
    "ANALYSIS_COLUMNS",
    "STATUSES",
    "SUMMARY_FILE",
    "read_summary",
    "summary_text",
    "summary_values",
    "time_reached",
]

#: Name of the summary table written into the sweep directory.
SUMMARY_FILE = "summary.csv"

#: Values of the ``status`` column.
STATUSES = ("finished", "analysis_failed", "fault", "error", "pending")

#: Shape observables of every run (window means, with a block-bootstrap standard error).
SHAPE_COLUMNS = (
    "average_crossing_number",
    "radius_of_gyration",
    "radius_of_gyration_perp",
    "asphericity",
)

#: Analysis values in ``summary.csv``, in column order (from ``analysis.json``; ``window``
#: becomes ``window_start``/``window_end``, ``fit_quality.r2`` becomes ``fit_r2``; a shape
#: observable's ``_uncertainty`` is its ``uncertainties`` entry's ``std_error``;
#: ``knot_type_change_count`` is the length of ``knot_type_changes``), then ``time_reached``
#: (tau_d, from ``run.toml``).
ANALYSIS_COLUMNS = (
    "tau_swirl_over_tau_sed",
    "tau_swirl_over_tau_sed_uncertainty",
    "tau_rot_over_tau_sed",
    "tau_rot_over_tau_sed_uncertainty",
    "tau_sed",
    "tau_sed_uncertainty",
    "tau_swirl",
    "tau_swirl_uncertainty",
    "tau_rot",
    "tau_rot_uncertainty",
    "sedimentation_velocity",
    "sedimentation_velocity_uncertainty",
    "major_radius",
    "major_radius_std",
    "major_radius_geometric",
    "swirl_amplitude",
    "rotation_sense",
    "rotation_frequency",
    "writhe",
    "handedness",
    *(f"{name}{tail}" for name in SHAPE_COLUMNS for tail in ("", "_uncertainty")),
    "torus_fraction",
    "torus_fraction_window",
    "knot_type_start",
    "knot_type_end",
    "knot_type_changed_at",
    "knot_type_change_count",
    "p",
    "q",
    "window_start",
    "window_end",
    "fit_r2",
    "time_reached",
)


def summary_values(analysis: Mapping[str, Any] | None) -> dict[str, Any]:
    """The :data:`ANALYSIS_COLUMNS` values of an ``analysis.json`` dict (missing: None)."""
    out: dict[str, Any] = {k: None for k in ANALYSIS_COLUMNS}
    if not analysis:
        return out
    for key in ANALYSIS_COLUMNS:
        if key in analysis:
            out[key] = analysis[key]
    window = analysis.get("window") or [None, None]
    out["window_start"], out["window_end"] = window[0], window[1]
    quality = analysis.get("fit_quality") or {}
    out["fit_r2"] = quality.get("r2")
    errors = analysis.get("uncertainties") or {}
    for name in SHAPE_COLUMNS:
        out[f"{name}_uncertainty"] = (errors.get(name) or {}).get("std_error")
    changes = analysis.get("knot_type_changes")
    out["knot_type_change_count"] = len(changes) if isinstance(changes, list) else None
    return out


def time_reached(directory: Path) -> float | None:
    """``[knotmm] time_reached`` of a run directory's ``run.toml`` (tau_d), or None."""
    try:
        facts = read_facts(directory)
    except ConfigError:
        return None
    value = facts.get("time_reached")
    return float(value) if isinstance(value, (int, float)) else None


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else ""
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_cell(v) for v in value) + "]"
    return str(value)


def summary_text(columns: Sequence[str], rows: Sequence[Mapping[str, Any]]) -> str:
    """The text of ``summary.csv``.

    Parameters
    ----------
    columns : sequence of str
        The point-identifying columns (``Sweep.columns``: swept keys, then ``replica`` and
        ``run.seed`` for ensembles).
    rows : sequence of dict
        One dict per point; missing keys give empty cells.
    """
    header = ["point", "directory", *columns, "status", "error", *ANALYSIS_COLUMNS]
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(header)
    for row in rows:
        writer.writerow([_cell(row.get(k)) for k in header])
    return buf.getvalue()


_INT = re.compile(r"[+-]?\d+")
_FLOAT = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?|[+-]?(inf|nan)")


def _parse_cell(text: str) -> Any:
    """A summary cell back to a value (``3_1`` stays a string: Python's int() would accept it)."""
    if text == "":
        return None
    if text in ("true", "false"):
        return text == "true"
    if _INT.fullmatch(text):
        return int(text)
    if _FLOAT.fullmatch(text):
        return float(text)
    return text


def read_summary(path: str | os.PathLike) -> list[dict[str, Any]]:
    """Read a ``summary.csv`` (a file or a sweep directory) into a list of rows.

    Numbers become int or float, ``true``/``false`` bool, empty cells None.

    Returns
    -------
    list of dict
        One dict per point, keyed by column name (dotted keys for swept keys).
    """
    path = Path(path)
    if path.is_dir():
        path = path / SUMMARY_FILE
    if not path.exists():
        raise ConfigError(f"summary {str(path)!r} does not exist: run the sweep first")
    with path.open(newline="") as fh:
        return [{k: _parse_cell(v) for k, v in row.items()} for row in csv.DictReader(fh)]
