"""Parameter sweeps and ensembles: many runs, each analysed, collected in one table.

A sweep file is a run file (``[knot]``, ``[model]``, ``[run]``, ``[output]``) plus a
``[sweep]`` table that maps dotted keys to lists of values::

    [knot]
    kind = "torus"
    p = 2
    q = 3

    [run]
    duration = 800.0

    [output]
    directory = "sweeps/fig3"      # the sweep directory

    [sweep]
    "knot.beads" = [40, 50, 60, 70, 80, 90, 100, 110, 120]

The ``[sweep]`` table also takes these options (names without a dot):

=================  ==========================================================================
``mode``           ``"grid"`` (default: every combination, the last key varying fastest) or
                   ``"zip"`` (the i-th values of every list together; equal lengths)
``seeds``          ``K``: run every point K times, replica k with ``run.seed`` set to
                   ``SeedSequence(seed).spawn(K)[k]`` (the same K seeds at every point)
``seed``           the base seed of ``seeds``; default ``run.seed``
``x``              the swept key on the x axis of the plots (default: the first key; in zip
                   mode with several keys, ``"point"``: one tick per point)
``log_x``          log scale on the x axis (default: when the values span >= 100x)
``plots``          write each point's analysis plots (default true)
``knot_samples``   frames checked for a change of knot type per point (default 40; 0 skips)
``t_from``         analysis window start / end, in tau_d (default: detected per point)
``t_to``
=================  ==========================================================================

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
                         (:data:`ANALYSIS_COLUMNS`); rewritten atomically after every point
``DIR/ratios.png``       tau_swirl/tau_sed and tau_rot/tau_sed against the swept key
``DIR/shape.png``        rho0 (with N l0 / (2 pi p)), C and V against the swept key
=======================  ====================================================================

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
same function :func:`run_point`, so both give the same numbers.
"""

from __future__ import annotations

import copy
import csv
import io
import itertools
import json
import logging
import math
import multiprocessing
import os
import re
import sys
import time
import uuid
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from knotmm.config import RunConfig, read_toml, resolve_stepping, split_key
from knotmm.errors import ConfigError, RunDirectoryError

__all__ = [
    "ANALYSIS_COLUMNS",
    "SWEEP_OPTIONS",
    "STATUSES",
    "Sweep",
    "SweepOptions",
    "SweepPoint",
    "SweepResult",
    "describe_points",
    "expand",
    "load_sweep_file",
    "point_name",
    "read_summary",
    "replica_seeds",
    "run_point",
    "run_sweep",
    "summary_values",
]

log = logging.getLogger(__name__)

#: Name of the summary table written into the sweep directory.
SUMMARY_FILE = "summary.csv"
#: Copy of the sweep file written into the sweep directory.
SWEEP_FILE = "sweep.toml"

#: Sweep directory of a sweep file without ``output.directory`` (:func:`load_sweep_file`
#: uses ``sweeps/<file stem>``).
DEFAULT_DIRECTORY = "sweeps/sweep"

#: Values of the ``status`` column.
STATUSES = ("finished", "analysis_failed", "fault", "error", "pending")

#: Analysis values in ``summary.csv``, in column order (from ``analysis.json``; ``window``
#: becomes ``window_start``/``window_end``, ``fit_quality.r2`` becomes ``fit_r2``), then
#: ``time_reached`` (tau_d, from ``run.toml``).
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
    "knot_type_start",
    "knot_type_end",
    "knot_type_changed_at",
    "p",
    "q",
    "window_start",
    "window_end",
    "fit_r2",
    "time_reached",
)

#: Options of the ``[sweep]`` table (names without a dot), with their defaults.
SWEEP_OPTIONS: dict[str, Any] = {
    "mode": "grid",
    "seeds": None,
    "seed": None,
    "x": None,
    "log_x": None,
    "plots": True,
    "knot_samples": 40,
    "t_from": None,
    "t_to": None,
}


# ---------------------------------------------------------------------------------------------
# expansion
# ---------------------------------------------------------------------------------------------
def expand(values: Mapping[str, Sequence[Any]], mode: str = "grid") -> list[dict[str, Any]]:
    """Expand ``{key: [values...]}`` into a list of points ``{key: value}``.

    Parameters
    ----------
    values : mapping of str to sequence
        Swept keys and their values, in order.
    mode : {"grid", "zip"}
        ``"grid"``: the Cartesian product, the last key varying fastest
        (``len = prod(len(v))``); ``"zip"``: the i-th values together (all lists of equal
        length).

    Returns
    -------
    list of dict

    Examples
    --------
    >>> expand({"a": [1, 2], "b": [3, 4]})
    [{'a': 1, 'b': 3}, {'a': 1, 'b': 4}, {'a': 2, 'b': 3}, {'a': 2, 'b': 4}]
    >>> expand({"a": [1, 2], "b": [3, 4]}, mode="zip")
    [{'a': 1, 'b': 3}, {'a': 2, 'b': 4}]
    """
    keys = list(values)
    lists = [list(values[k]) for k in keys]
    if mode == "grid":
        return [dict(zip(keys, combo, strict=True)) for combo in itertools.product(*lists)]
    if mode == "zip":
        lengths = {k: len(v) for k, v in zip(keys, lists, strict=True)}
        if len(set(lengths.values())) > 1:
            listed = ", ".join(f"{k} has {n}" for k, n in lengths.items())
            raise ConfigError(
                f'[sweep] mode = "zip" needs lists of equal length: {listed}; make them equal '
                f'or use mode = "grid"'
            )
        return [dict(zip(keys, combo, strict=True)) for combo in zip(*lists, strict=True)]
    raise ConfigError(f'[sweep] mode = {mode!r}: expected "grid" or "zip"')


def replica_seeds(base_seed: int, count: int) -> list[int]:
    """Seeds of ``count`` replicas, derived reproducibly from ``base_seed``.

    Replica k gets the first 32-bit word of ``numpy.random.SeedSequence(base_seed).spawn(count)[k]``
    (spawn key ``(k,)``), so its seed does not depend on ``count``: adding replicas keeps the
    seeds of the existing ones.

    Returns
    -------
    list of int, length count, each in [0, 2**32)
    """
    children = np.random.SeedSequence(int(base_seed)).spawn(int(count))
    return [int(c.generate_state(1, dtype=np.uint32)[0]) for c in children]


def _format_value(value: Any) -> str:
    """A value as it appears in a point directory name (and in summary.csv)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, (list, tuple)):
        return "_".join(_format_value(v) for v in value)
    text = str(value)
    return "".join(c if c.isalnum() or c in "._-+" else "_" for c in text)


def point_name(values: Mapping[str, Any], replica: int | None = None) -> str:
    """The directory name of a point, from its swept values (stable, readable).

    Examples
    --------
    >>> point_name({"knot.beads": 40})
    'knot.beads=40'
    >>> point_name({"knot.p": 2, "model.bending_stiffness": 0.5}, replica=3)
    'knot.p=2,model.bending_stiffness=0.5,replica=3'
    """
    parts = [f"{k}={_format_value(v)}" for k, v in values.items()]
    if replica is not None:
        parts.append(f"replica={replica}")
    return ",".join(parts) if parts else "point"


# ---------------------------------------------------------------------------------------------
# the sweep description
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SweepOptions:
    """The options of a ``[sweep]`` table (see the module docstring)."""

    mode: str = "grid"
    seeds: int | None = None
    seed: int | None = None
    x: str | None = None
    log_x: bool | None = None
    plots: bool = True
    knot_samples: int = 40
    t_from: float | None = None
    t_to: float | None = None


@dataclass(frozen=True)
class SweepPoint:
    """One point of a sweep.

    Attributes
    ----------
    index : int
        Position in the sweep (row of ``summary.csv``).
    name : str
        Directory name inside the sweep directory.
    values : dict
        The swept keys and this point's values (plus ``run.seed`` for a replica).
    replica : int or None
        Replica index for ``seeds = K`` ensembles.
    config : RunConfig
        The full, validated run configuration (``output.directory`` = the point directory).
    """

    index: int
    name: str
    values: dict[str, Any]
    replica: int | None
    config: RunConfig


@dataclass
class Sweep:
    """A validated sweep: the base run, the swept keys and every expanded point.

    Build one with :meth:`from_dict` or :func:`load_sweep_file`; every point's configuration
    is validated with :class:`~knotmm.config.RunConfig` on construction.

    Attributes
    ----------
    base : RunConfig
        The run file without ``[sweep]``.
    values : dict of str to list
        The swept dotted keys and their values, in file order.
    options : SweepOptions
    directory : Path
        The sweep directory (``output.directory`` of the file, or the one given).
    points : list of SweepPoint
    data : dict
        The sweep file as parsed (nested tables), for ``DIR/sweep.toml``.
    notes : list of str
        Warnings found while reading (e.g. identical replicas).
    """

    base: RunConfig
    values: dict[str, list[Any]]
    options: SweepOptions
    directory: Path
    points: list[SweepPoint]
    data: dict[str, Any]
    notes: list[str] = field(default_factory=list)

    @property
    def keys(self) -> tuple[str, ...]:
        """The swept dotted keys (``run.seed`` not included for ``seeds = K``)."""
        return tuple(self.values)

    @property
    def columns(self) -> tuple[str, ...]:
        """Point-identifying columns of ``summary.csv``: swept keys, then replica, run.seed."""
        extra = ("replica", "run.seed") if self.options.seeds else ()
        return (*self.keys, *extra)

    @property
    def x_key(self) -> str:
        """The plots' x axis: a swept key, or ``"point"``."""
        if self.options.x is not None:
            return self.options.x
        if not self.keys:
            return "replica"
        if self.options.mode == "zip" and len(self.keys) > 1:
            return "point"
        return self.keys[0]

    @classmethod
    def from_dict(
        cls, data: Mapping[str, Any], directory: str | os.PathLike | None = None
    ) -> Sweep:
        """Validate a parsed sweep file and expand its points.

        Parameters
        ----------
        data : mapping
            The nested tables of a sweep file (a run file plus ``[sweep]``).
        directory : path, optional
            The sweep directory, replacing ``output.directory``.

        Raises
        ------
        ConfigError
            One line naming the key: an unknown key or option, a value that is not a list,
            an empty or duplicated list entry, unequal lists in zip mode, or any point whose
            run configuration is invalid.
        """
        if not isinstance(data, Mapping):
            raise ConfigError("a sweep file must be a table of tables")
        data = copy.deepcopy(dict(data))
        if "sweep" not in data:
            raise ConfigError(
                "the sweep file has no [sweep] table: add one mapping dotted keys to lists, "
                'e.g. "knot.beads" = [40, 60, 80] (or use `knotmm run` for a single run)'
            )
        table = data.pop("sweep")
        resolved = data.pop("knotmm", None) is not None  # a run's run.toml plus [sweep]
        if not isinstance(table, Mapping):
            raise ConfigError(f"[sweep] must be a table, got {table!r}")
        swept, raw_options = _split_sweep_table(table)
        options = _check_options(raw_options)
        if directory is None and "directory" not in data.get("output", {}):
            directory = DEFAULT_DIRECTORY
        base = RunConfig.from_dict(data)
        if directory is not None:
            base = base.replace({"output.directory": str(directory)})
        sweep_dir = Path(base["output.directory"])

        values: dict[str, list[Any]] = {}
        for dotted, entries in swept.items():
            try:
                table_name, _ = split_key(dotted)
            except ConfigError as exc:
                raise ConfigError(f"[sweep] {exc}") from None
            if table_name == "output" and dotted == "output.directory":
                raise ConfigError(
                    "[sweep] output.directory cannot be swept: every point gets its own "
                    "directory inside the sweep directory"
                )
            if not isinstance(entries, list):
                raise ConfigError(
                    f"[sweep] {dotted} = {entries!r}: expected a list of values, e.g. "
                    f"[{_format_value(entries)}]"
                )
            if not entries:
                raise ConfigError(f"[sweep] {dotted} = []: the list is empty")
            names = [_format_value(v) for v in entries]
            for i, name in enumerate(names):
                if name in names[:i] and options.mode == "grid":
                    raise ConfigError(f"[sweep] {dotted} lists {entries[i]!r} twice")
            values[dotted] = list(entries)
        if options.seeds is not None and "run.seed" in values:
            raise ConfigError("[sweep] sweeps run.seed and sets seeds = K: use one of the two")
        if not values and options.seeds is None:
            raise ConfigError(
                '[sweep] lists no keys: add e.g. "knot.beads" = [40, 60, 80], or seeds = K '
                "for an ensemble"
            )
        combos = expand(values, options.mode) if values else [{}]
        if options.x is not None and options.x not in (*values, "point", "replica"):
            raise ConfigError(
                f"[sweep] x = {options.x!r}: expected one of the swept keys "
                f'({", ".join(values) or "none"}), "point" or "replica"'
            )

        seeds: list[int | None] = [None]
        if options.seeds is not None:
            base_seed = options.seed if options.seed is not None else base["run.seed"]
            seeds = list(replica_seeds(base_seed, options.seeds))
        points: list[SweepPoint] = []
        for combo in combos:
            for replica, seed in enumerate(seeds):
                rep = replica if options.seeds is not None else None
                name = point_name(combo, rep)
                changes = dict(combo)
                if seed is not None:
                    changes["run.seed"] = seed
                changes["output.directory"] = str(sweep_dir / name)
                try:
                    cfg = base.replace(changes)
                except ConfigError as exc:
                    raise ConfigError(f"[sweep] point {name}: {exc}") from None
                point_values = dict(combo)
                if seed is not None:
                    point_values["run.seed"] = seed
                points.append(SweepPoint(len(points), name, point_values, rep, cfg))
        names = [p.name for p in points]
        dup = next((n for i, n in enumerate(names) if n in names[:i]), None)
        if dup is not None:
            raise ConfigError(
                "[sweep] two points get the same directory name; make values distinct"
            )

        notes = []
        if resolved and "knot.beads" in values and "knot.major_radius" not in values:
            # run.toml holds the radius resolved for its own bead count: let it follow N
            data.get("knot", {}).pop("major_radius", None)
            base = RunConfig.from_dict(data).replace({"output.directory": str(sweep_dir)})
            points = [
                SweepPoint(p.index, p.name, p.values, p.replica, _without_radius(p.config))
                for p in points
            ]
            notes.append(
                "knot.major_radius of the run.toml is dropped: the template radius follows "
                "the swept knot.beads"
            )
        if (
            options.seeds is not None
            and options.seeds > 1
            and base["knot.perturbation"] == 0
            and "knot.perturbation" not in values
            and math.isinf(base["run.peclet"])
        ):
            notes.append(
                f"seeds = {options.seeds} but the runs are deterministic (knot.perturbation = 0, "
                f"run.peclet = inf): the replicas will be identical; set knot.perturbation > 0"
            )
        data_out = copy.deepcopy(dict(data))
        data_out.setdefault("output", {})["directory"] = str(sweep_dir.resolve())
        data_out["sweep"] = copy.deepcopy(dict(table))
        return cls(base, values, options, sweep_dir, points, data_out, notes)

    def to_toml(self) -> str:
        """The sweep file text (as read, with the sweep directory as an absolute path)."""
        import tomli_w

        return (
            "# knotmm sweep file, as read by `knotmm sweep`; run it again with\n"
            "# `knotmm sweep sweep.toml` (finished points are skipped).\n\n"
            + tomli_w.dumps(self.data)
        )


def _without_radius(cfg: RunConfig) -> RunConfig:
    data = cfg.to_dict()
    data["knot"].pop("major_radius", None)
    return RunConfig.from_dict(data)


def _split_sweep_table(table: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """Separate swept keys (dotted, quoted or as nested tables) from options."""
    swept: dict[str, Any] = {}
    options: dict[str, Any] = {}

    def walk(prefix: str, node: Mapping[str, Any]) -> None:
        for key, value in node.items():
            dotted = f"{prefix}.{key}" if prefix else key
            if isinstance(value, Mapping):
                walk(dotted, value)
            elif "." in dotted:
                swept[dotted] = value
            else:
                options[dotted] = value

    walk("", table)
    return swept, options


def _check_options(raw: Mapping[str, Any]) -> SweepOptions:
    """Validate the ``[sweep]`` options; one-line ConfigError naming the option."""
    import difflib

    for name in raw:
        if name not in SWEEP_OPTIONS:
            close = difflib.get_close_matches(name, list(SWEEP_OPTIONS), n=1)
            hint = f"; did you mean '{close[0]}'?" if close else ""
            raise ConfigError(
                f'unknown [sweep] option {name!r}: swept keys are dotted ("knot.beads"), '
                f"options are {', '.join(SWEEP_OPTIONS)}{hint}"
            )
    opts = {**SWEEP_OPTIONS, **raw}

    def integer(name: str, minimum: int) -> int | None:
        v = opts[name]
        if v is None:
            return None
        if isinstance(v, bool) or not isinstance(v, int) or v < minimum:
            raise ConfigError(f"[sweep] {name} = {v!r}: expected an integer >= {minimum}")
        return int(v)

    def number(name: str) -> float | None:
        v = opts[name]
        if v is None:
            return None
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ConfigError(f"[sweep] {name} = {v!r}: expected a finite number (tau_d)")
        return float(v)

    def boolean(name: str) -> bool | None:
        v = opts[name]
        if v is not None and not isinstance(v, bool):
            raise ConfigError(f"[sweep] {name} = {v!r}: expected true or false")
        return v

    mode = opts["mode"]
    if mode not in ("grid", "zip"):
        raise ConfigError(f'[sweep] mode = {mode!r}: expected "grid" or "zip"')
    x = opts["x"]
    if x is not None and not isinstance(x, str):
        raise ConfigError(f'[sweep] x = {x!r}: expected a swept key such as "knot.beads"')
    plots = boolean("plots")
    return SweepOptions(
        mode=mode,
        seeds=integer("seeds", 1),
        seed=integer("seed", 0),
        x=x,
        log_x=boolean("log_x"),
        plots=True if plots is None else plots,
        knot_samples=integer("knot_samples", 0),
        t_from=number("t_from"),
        t_to=number("t_to"),
    )


def load_sweep_file(path: str | os.PathLike, directory: str | os.PathLike | None = None) -> Sweep:
    """Read and validate a sweep file (see the module docstring).

    Parameters
    ----------
    path : path
        The TOML sweep file.
    directory : path, optional
        The sweep directory, replacing the file's ``output.directory`` (default when the file
        has none: ``sweeps/<file stem>``).

    Raises
    ------
    ConfigError
        One line, prefixed with the file name, for any invalid key, option or point.
    """
    data = read_toml(path, what="sweep file")
    output = data.get("output")
    if directory is None and not (isinstance(output, Mapping) and "directory" in output):
        directory = Path("sweeps") / Path(path).stem
    try:
        return Sweep.from_dict(data, directory=directory)
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from None


# ---------------------------------------------------------------------------------------------
# one point (runs in a worker process, local or Dask)
# ---------------------------------------------------------------------------------------------
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
    return out


def _error_text(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or "no message"
    return f"{type(exc).__name__}: {text}"


def _time_reached(directory: Path) -> float | None:
    try:
        facts = read_toml(directory / "run.toml").get("knotmm", {})
    except ConfigError:
        return None
    value = facts.get("time_reached")
    return float(value) if isinstance(value, (int, float)) else None


def _leave() -> None:  # pragma: no cover - runs in the worker processes
    """End a local worker now, with the processes it started (the runs' knot-check workers)."""
    import signal

    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    children = multiprocessing.active_children()
    for child in children:
        child.kill()
    for child in children:
        child.join(timeout=2.0)
    os._exit(_INTERRUPT_EXIT)


def _interrupted(name: str) -> dict[str, Any]:
    if _STOPPING:  # a local worker told to stop: the run's files are closed, leave now
        _leave()
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
        ``knot_samples``).

    Returns
    -------
    dict
        ``name``, ``status`` (one of :data:`STATUSES`), ``error`` (one line or None),
        ``values`` (:func:`summary_values`, with ``time_reached``).
    """
    global _RUNNING
    _RUNNING = True
    # the run's warnings (a change of knot type, ...) are in its run.toml and analysis.json;
    # a sweep of many points would otherwise print them all, interleaved
    knotmm_log = logging.getLogger("knotmm")
    level = knotmm_log.level
    if knotmm_log.getEffectiveLevel() < logging.ERROR:
        knotmm_log.setLevel(logging.ERROR)
    try:
        return _run_point(task)
    finally:
        knotmm_log.setLevel(level)
        _RUNNING = False


def _run_point(task: Mapping[str, Any]) -> dict[str, Any]:
    from knotmm.errors import SimulationFault

    name = task["name"]
    directory = Path(task["directory"])
    status, error, analysis = "finished", None, None
    action = task.get("action", "run")
    try:
        if action == "resume":
            from knotmm.errors import RunDirectoryError, TrajectoryFileError
            from knotmm.workflow import resume

            try:
                resume(directory, progress=False)
            except (ConfigError, TrajectoryFileError, RunDirectoryError) as exc:
                log.info("point %s cannot be resumed (%s): running it again", name, exc)
                action = "run"
        if action == "run":
            from knotmm.workflow import run

            cfg = RunConfig.from_dict(task["config"])
            run(cfg, directory=directory, overwrite=True, progress=False)
    except SimulationFault as exc:
        status, error = "fault", _error_text(exc)
    except KeyboardInterrupt:
        return _interrupted(name)
    except Exception as exc:  # any failure of this point is reported, never raised
        status, error = "error", _error_text(exc)
        log.debug("point %s failed", name, exc_info=True)
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
            status, error = "analysis_failed", _error_text(exc)
            log.debug("analysis of point %s failed", name, exc_info=True)
    values = summary_values(analysis)
    values["time_reached"] = _time_reached(directory)
    return {"name": name, "status": status, "error": error, "values": values}


#: In a local worker process: a point is being computed / the sweep is being stopped.
_RUNNING = False
_STOPPING = False
#: Exit status of a local worker stopped by SIGINT.
_INTERRUPT_EXIT = 130


def _on_stop(signum, frame):  # pragma: no cover - runs in the worker processes
    """SIGINT in a local worker: interrupt the point (its run records ``interrupted``) and
    leave; an idle worker leaves at once.

    The first SIGINT lets a running simulation finish its step and checkpoint that state
    (:mod:`knotmm.engine.interrupt`); the parent repeats the signal every second, and a repeat
    interrupts at once (a point being analysed, or a step that takes that long).
    """
    from knotmm.engine.interrupt import request_stop

    global _STOPPING
    first = not _STOPPING
    _STOPPING = True
    if not _RUNNING:
        _leave()
    if first:
        request_stop()
        return
    raise KeyboardInterrupt


def _worker_init() -> None:  # pragma: no cover - runs in the worker processes
    """Initialise a local worker process: quiet logging, Agg backend, one thread each.

    SIGINT (Ctrl-C on the terminal, or sent by the parent when the sweep is stopped)
    interrupts the running point, so that its ``run.toml`` records ``interrupted``, and ends
    the worker. SIGINT is used rather than SIGTERM because topoly's C code replaces the
    SIGTERM handler once it has been called.
    """
    import signal
    import threading

    os.environ.setdefault("OMP_NUM_THREADS", "1")
    os.environ.setdefault("MPLBACKEND", "Agg")
    signal.signal(signal.SIGINT, _on_stop)
    # a worker whose parent died (killed) would wait for work forever: leave instead
    parent = os.getppid()
    threading.Thread(target=_watch_parent, args=(parent,), daemon=True).start()


def _watch_parent(parent: int) -> None:  # pragma: no cover - runs in the worker processes
    while True:
        time.sleep(1.0)
        if os.getppid() != parent:
            os._exit(1)


# ---------------------------------------------------------------------------------------------
# planning and resuming
# ---------------------------------------------------------------------------------------------
def _stored_config_matches(point: SweepPoint, directory: Path) -> bool:
    """Whether the run in ``directory`` was made with this point's parameters."""
    try:
        stored = read_toml(directory / "run.toml")
    except ConfigError:
        return False
    wanted = point.config.to_dict(include_unset=False)
    # a run file records the integrator and step it used ("auto" and an unset step resolved)
    name, timestep = resolve_stepping(point.config)
    wanted["run"].update(integrator=name, timestep=timestep)
    for table, keys in wanted.items():
        for key, value in keys.items():
            if table == "output" and key == "directory":
                continue
            if stored.get(table, {}).get(key) != value:
                return False
    return True


def _plan(point: SweepPoint, directory: Path, reanalyze: bool) -> tuple[str, dict | None]:
    """What to do with a point: ``("skip", values)``, or ``("analyze" | "resume" | "run", None)``.

    A finished run with this point's parameters is skipped (or only analysed when it has no
    ``analysis.json`` or ``reanalyze``); an interrupted or killed one with the same
    parameters is resumed from its checkpoint; anything else is run from the start.
    """
    from knotmm.workflow import run_status

    status = run_status(directory)
    if status is None:
        return "run", None
    same = _stored_config_matches(point, directory)
    if status in ("interrupted", "running") and same:
        log.info("point %s: %s run, resuming it", point.name, status)
        return "resume", None
    if status != "finished" or not same:
        why = "made with other parameters" if same is False and status == "finished" else status
        log.info("point %s: run %s, running it again", point.name, why)
        return "run", None
    if reanalyze:
        return "analyze", None
    try:
        analysis = json.loads((directory / "analysis.json").read_text())
    except (OSError, ValueError):
        return "analyze", None
    values = summary_values(analysis)
    values["time_reached"] = _time_reached(directory)
    return "skip", values


# ---------------------------------------------------------------------------------------------
# summary
# ---------------------------------------------------------------------------------------------
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


def _summary_text(sweep: Sweep, rows: Sequence[Mapping[str, Any]]) -> str:
    header = ["point", "directory", *sweep.columns, "status", "error", *ANALYSIS_COLUMNS]
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


# ---------------------------------------------------------------------------------------------
# execution
# ---------------------------------------------------------------------------------------------
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


def _lost_result(name: str, why: str) -> dict[str, Any]:
    return {"name": name, "status": "error", "error": why, "values": {}}


def _run_inline(tasks, on_result, func) -> None:
    for task in tasks:
        on_result(func(task))


_DIED = (
    "the worker process died while running this point (a crash in native code, or killed "
    "for memory)"
)


def _run_local(tasks, workers: int, on_result, func) -> None:
    """Run tasks in ``workers`` spawned processes; a crashed worker fails only its point.

    A process that dies takes down the points running or queued beside it; those are run
    again one at a time, each in a fresh process, so only the point that crashes it fails.
    A worker that ended because of Ctrl-C stops the whole sweep (KeyboardInterrupt).
    """
    executors: list = []
    try:
        lost = _run_pool(tasks, workers, on_result, func, executors)
        for task in lost:
            if _run_pool([task], 1, on_result, func, executors):
                on_result(_lost_result(task["name"], _DIED))
    except BaseException:
        for executor in executors:
            _abort_executor(executor)
        raise


def _run_pool(tasks, workers: int, on_result, func, executors: list) -> list[dict]:
    """One process pool over ``tasks``; returns the tasks lost to a dead worker process."""
    from concurrent.futures import ProcessPoolExecutor, as_completed
    from concurrent.futures.process import BrokenProcessPool

    lost: list[dict] = []
    executor = ProcessPoolExecutor(
        max_workers=max(1, min(workers, len(tasks))),
        mp_context=multiprocessing.get_context("spawn"),
        initializer=_worker_init,
    )
    executors.append(executor)
    futures = {executor.submit(func, t): t for t in tasks}
    processes = list(getattr(executor, "_processes", {}).values())
    for fut in as_completed(futures):
        task = futures[fut]
        try:
            result = fut.result()
        except BrokenProcessPool:
            lost.append(task)
            continue
        except Exception as exc:  # e.g. a result that cannot be sent back
            result = _lost_result(task["name"], _error_text(exc))
        on_result(result)
    executor.shutdown(wait=True)
    if lost and any(p.exitcode == _INTERRUPT_EXIT for p in processes):
        raise KeyboardInterrupt  # Ctrl-C reached the workers before this process
    return lost


def _abort_executor(executor) -> None:
    """Cancel queued points and stop this executor's own worker processes.

    Each worker gets SIGINT (again every second: a signal that lands on one of its other
    threads while its main thread waits is only seen late), interrupts its point
    (``run.toml`` then says ``interrupted``) and exits with the processes it started. A
    worker still alive after a few seconds is killed, with its descendants.
    """
    import signal

    processes = list(getattr(executor, "_processes", {}).values())
    executor.shutdown(wait=False, cancel_futures=True)
    deadline = time.monotonic() + 8.0
    while time.monotonic() < deadline:
        alive = [p for p in processes if p.is_alive() and p.pid is not None]
        if not alive:
            break
        for proc in alive:
            try:
                os.kill(proc.pid, signal.SIGINT)
            except ProcessLookupError:
                pass
        for proc in alive:
            proc.join(timeout=1.0 / len(alive))
    for proc in processes:
        if proc.is_alive() and proc.pid is not None:
            for pid in _descendants(proc.pid):
                try:
                    os.kill(pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
            proc.kill()
            proc.join(timeout=2.0)
    executor.shutdown(wait=True)  # its workers are gone: release its queues and threads


def _descendants(pid: int) -> list[int]:
    """Processes below ``pid`` (Linux ``/proc``; empty elsewhere)."""
    found: list[int] = []
    todo = [pid]
    while todo:
        current = todo.pop()
        try:
            tasks = os.listdir(f"/proc/{current}/task")
        except OSError:
            continue
        for tid in tasks:
            try:
                with open(f"/proc/{current}/task/{tid}/children") as fh:
                    children = [int(c) for c in fh.read().split()]
            except (OSError, ValueError):
                continue
            found += children
            todo += children
    return found


def _dask_client(scheduler):
    """A ``distributed.Client`` for ``scheduler`` (address, scheduler file or a Client)."""
    try:
        import distributed
    except ImportError:
        raise ConfigError(
            f"--scheduler {scheduler}: Dask is not installed; install the cluster extra: "
            f"pip install 'knotmm[cluster]'"
        ) from None
    if isinstance(scheduler, distributed.Client):
        return scheduler, False
    text = str(scheduler)
    try:
        if text.endswith(".json") and Path(text).is_file():
            client = distributed.Client(scheduler_file=text, timeout="20s")
        else:
            client = distributed.Client(text, timeout="20s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise ConfigError(
            f"--scheduler {text}: cannot connect to a Dask scheduler ({_error_text(exc)}); "
            f"start one with `dask scheduler` and give its tcp://host:port"
        ) from None
    return client, True


def _run_dask(tasks, scheduler, on_result, func) -> None:
    import distributed

    client, owned = _dask_client(scheduler)
    token = uuid.uuid4().hex[:8]
    futures = []
    try:
        futures = [
            client.submit(func, task, key=f"knotmm-point-{token}-{i}", pure=False)
            for i, task in enumerate(tasks)
        ]
        by_key = {f.key: t for f, t in zip(futures, tasks, strict=True)}
        for fut in distributed.as_completed(futures):
            task = by_key[fut.key]
            try:
                result = fut.result()
            except Exception as exc:  # KilledWorker, lost worker, ...
                result = _lost_result(task["name"], _error_text(exc))
            on_result(result)
    except BaseException:
        if futures:
            client.cancel(futures)
        raise
    finally:
        if owned:
            client.close()


def _default_workers(sweep: Sweep) -> int:
    threads = max(1, int(sweep.base["run.threads"]))
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not on Linux
        cores = os.cpu_count() or 1
    return max(1, cores // threads)


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
        Show an overall progress bar (points); default: only when stderr is a terminal.
    reanalyze : bool
        Analyse finished points again instead of skipping them.

    Returns
    -------
    SweepResult

    Raises
    ------
    RunDirectoryError
        If the sweep directory holds files but no knotmm sweep (nothing is written then).
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
    if (
        directory.exists()
        and any(directory.iterdir())
        and not (directory / SWEEP_FILE).exists()
        and not (directory / SUMMARY_FILE).exists()
    ):
        raise RunDirectoryError(
            f"sweep directory {str(directory)!r} is not empty and holds no knotmm sweep; "
            f"choose another output.directory (or --out)"
        )
    client, owned = None, False
    if scheduler is not None:
        client, owned = _dask_client(scheduler)  # fail before writing anything
    try:
        return _run_sweep(sweep, directory, workers, client, progress, reanalyze, func, wall0)
    finally:
        if owned:
            client.close()


def _run_sweep(sweep, directory, workers, client, progress, reanalyze, func, wall0):
    from knotmm.workflow import write_atomic

    directory.mkdir(parents=True, exist_ok=True)
    write_atomic(directory / SWEEP_FILE, sweep.to_toml())
    analysis_kwargs = {
        "t_from": sweep.options.t_from,
        "t_to": sweep.options.t_to,
        "plots": sweep.options.plots,
        "knot_samples": sweep.options.knot_samples,
    }
    rows: list[dict[str, Any]] = []
    tasks: list[dict[str, Any]] = []
    counts = {"run": 0, "resume": 0, "analyze": 0, "skip": 0}
    for point in sweep.points:
        point_dir = directory / point.name
        row: dict[str, Any] = {"point": point.name, "directory": point.name}
        row.update({k: point.values.get(k) for k in sweep.keys})
        if sweep.options.seeds:
            row["replica"] = point.replica
            row["run.seed"] = point.values["run.seed"]
        action, values = _plan(point, point_dir, reanalyze)
        counts[action] += 1
        if action == "skip":
            row.update(status="finished", error=None, **values)
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
    summary_path = directory / SUMMARY_FILE
    write_atomic(summary_path, _summary_text(sweep, rows))

    bar = None
    if progress is None:
        progress = hasattr(sys.stderr, "isatty") and sys.stderr.isatty()
    if progress and tasks:
        from tqdm import tqdm

        bar = tqdm(
            total=len(rows),
            initial=len(rows) - len(tasks),
            unit="point",
            desc="sweep",
            file=sys.stderr,
            dynamic_ncols=True,
        )
    n_failed = 0

    def on_result(result: Mapping[str, Any]) -> None:
        nonlocal n_failed
        row = by_name[result["name"]]
        row.update(result.get("values") or summary_values(None))
        row["status"], row["error"] = result["status"], result["error"]
        if result["status"] != "finished":
            n_failed += 1
            log.info("point %s: %s: %s", result["name"], result["status"], result["error"])
        else:
            log.info("point %s finished", result["name"])
        write_atomic(summary_path, _summary_text(sweep, rows))
        if bar is not None:
            bar.update(1)
            if n_failed:
                bar.set_postfix(failed=n_failed)

    try:
        if not tasks:
            pass
        elif client is not None:
            _run_dask(tasks, client, on_result, func)
        elif workers == 0:
            _run_inline(tasks, on_result, func)
        else:
            n = workers if workers is not None else _default_workers(sweep)
            _run_local(tasks, n, on_result, func)
    finally:
        if bar is not None:
            bar.close()
        write_atomic(summary_path, _summary_text(sweep, rows))

    plots = []
    try:
        from knotmm.sweep.plots import save_sweep_plots

        plots = save_sweep_plots(rows, sweep, directory)
    except Exception as exc:  # a plot must not lose the sweep's results
        log.warning("sweep plots not written: %s", _error_text(exc))
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


def describe_points(sweep: Sweep) -> str:
    """A listing of the points (for ``knotmm sweep --dry-run``)."""
    lines = [f"{len(sweep.points)} points in {sweep.directory} ({sweep.options.mode}):"]
    for p in sweep.points:
        lines.append(f"  {p.index:4d}  {p.name}")
    return "\n".join(lines)
