"""The sweep file: its schema, validation and the expanded points (:class:`Sweep`).

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
                   ``SeedSequence(seed).spawn(K)[k]`` (the same K seeds at every point);
                   ``[run] replicas = K`` runs as ``seeds = K`` (each run ``replicas = 1``)
``seed``           the base seed of ``seeds``; default ``run.seed``
``x``              the swept key on the x axis of the plots (default: the first key; in zip
                   mode with several keys, ``"point"``: one tick per point)
``log_x``          log scale on the x axis (default: when the values span >= 100x)
``plots``          write each point's analysis plots (default true)
``knot_samples``   frames checked for a change of knot type per point (default 40; 0 skips)
``t_from``         analysis window start / end, in tau_d (default: detected per point)
``t_to``
``set``            a table of dotted keys and values applied to every point, as
                   ``knotmm sweep --set KEY=VALUE`` / ``--duration T`` do (those add to
                   it); the sweep directory's ``sweep.toml`` records them here
=================  ==========================================================================

Keys set from the command line (``--set``, ``--duration``: :func:`load_sweep_file`'s
``overrides``) replace the file's values at every point, so each point's ``run.toml``
records them; a key the sweep varies (a ``[sweep]`` list, or ``run.seed`` with ``seeds =
K``) cannot be set. ``DIR/sweep.toml`` holds the sweep with them applied and lists them
under ``[sweep.set]``; a sweep directory is only continued with the same keys and values
set (:func:`knotmm.sweep.runner.run_sweep` refuses otherwise, in one line).

Running a sweep (:func:`knotmm.sweep.run_sweep`) writes ``DIR/sweep.toml`` (the sweep file as
read), one ordinary run directory per point and ``DIR/summary.csv``
(:mod:`knotmm.sweep.summary`); :mod:`knotmm.sweep.plan` expands the points and
:mod:`knotmm.sweep.runner` runs them. See ``docs/architecture.md``.
"""

from __future__ import annotations

import copy
import difflib
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from knotmm.config import RunConfig, read_toml, split_key
from knotmm.errors import ConfigError
from knotmm.replicas import identical_replicas_note
from knotmm.sweep.plan import (
    SweepPoint,
    expand,
    format_value,
    point_name,
    replica_seeds,
    replicas_as_seeds,
)

__all__ = [
    "DEFAULT_DIRECTORY",
    "SWEEP_FILE",
    "SWEEP_OPTIONS",
    "Sweep",
    "SweepOptions",
    "describe_points",
    "describe_set",
    "load_sweep_file",
    "set_table",
]

#: Copy of the sweep file written into the sweep directory.
SWEEP_FILE = "sweep.toml"

#: Sweep directory of a sweep file without ``output.directory`` (:func:`load_sweep_file`
#: uses ``sweeps/<file stem>``).
DEFAULT_DIRECTORY = "sweeps/sweep"

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
    overrides : dict of str to value
        Keys set at every point from outside the run tables (``[sweep.set]`` and the
        command line's ``--set``/``--duration``), in the order given.
    """

    base: RunConfig
    values: dict[str, list[Any]]
    options: SweepOptions
    directory: Path
    points: list[SweepPoint]
    data: dict[str, Any]
    notes: list[str] = field(default_factory=list)
    overrides: dict[str, Any] = field(default_factory=dict)

    def __repr__(self) -> str:
        swept = ", ".join(f"{k} x{len(v)}" for k, v in self.values.items()) or "no keys"
        seeds = f", seeds={self.options.seeds}" if self.options.seeds else ""
        return (f"Sweep({len(self.points)} points: {swept}{seeds}, mode={self.options.mode!r}, "
                f"directory={str(self.directory)!r})")

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
        cls,
        data: Mapping[str, Any],
        directory: str | os.PathLike | None = None,
        overrides: Mapping[str, Any] | None = None,
    ) -> Sweep:
        """Validate a parsed sweep file and expand its points.

        Parameters
        ----------
        data : mapping
            The nested tables of a sweep file (a run file plus ``[sweep]``).
        directory : path, optional
            The sweep directory, replacing ``output.directory``.
        overrides : mapping of dotted key to value, optional
            Keys set at every point (``--set``, ``--duration``), after the file's
            ``[sweep.set]``.

        Raises
        ------
        ConfigError
            One line naming the key: an unknown key or option, a value that is not a list,
            an empty or duplicated list entry, unequal lists in zip mode, a set key that the
            sweep varies, or any point whose run configuration is invalid.
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
        table = dict(table)
        given = {**set_table(table.pop("set", None)), **dict(overrides or {})}
        swept, raw_options = _split_sweep_table(table)
        options = _check_options(raw_options)
        _check_set(given, swept, options)
        _apply_set(data, given, resolved)
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
                    f"[{format_value(entries)}]"
                )
            if not entries:
                raise ConfigError(f"[sweep] {dotted} = []: the list is empty")
            names = [format_value(v) for v in entries]
            for i, name in enumerate(names):
                if name in names[:i] and options.mode == "grid":
                    raise ConfigError(f"[sweep] {dotted} lists {entries[i]!r} twice")
            values[dotted] = list(entries)
        count, base, replicas_note = replicas_as_seeds(base, values, options.seeds, options.seed)
        options = replace(options, seeds=count)
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

        notes = [replicas_note] if replicas_note else []
        if resolved and "knot.beads" in values and "knot.major_radius" not in values:
            # run.toml holds the radius resolved for its own bead count: let it follow N
            data.get("knot", {}).pop("major_radius", None)
            base = RunConfig.from_dict(data).replace(
                {"output.directory": str(sweep_dir), "run.replicas": base["run.replicas"]}
            )
            points = [
                SweepPoint(p.index, p.name, p.values, p.replica, _without_radius(p.config))
                for p in points
            ]
            notes.append(
                "knot.major_radius of the run.toml is dropped: the template radius follows "
                "the swept knot.beads"
            )
        identical = identical_replicas_note(base, options.seeds or 0, "seeds")
        if identical and "knot.perturbation" not in values:
            notes.append(identical)
        data_out = copy.deepcopy(dict(data))
        data_out.setdefault("output", {})["directory"] = str(sweep_dir.resolve())
        data_out["sweep"] = copy.deepcopy(dict(table))
        if given:
            data_out["sweep"]["set"] = copy.deepcopy(given)
        return cls(base, values, options, sweep_dir, points, data_out, notes, given)

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


def set_table(node: Any) -> dict[str, Any]:
    """The ``[sweep.set]`` table as ``{dotted key: value}`` (quoted or nested keys)."""
    if node is None:
        return {}
    if not isinstance(node, Mapping):
        raise ConfigError(
            f'[sweep] set = {node!r}: expected a table of keys, e.g. set = {{"run.duration" '
            f"= 100.0}}"
        )
    flat: dict[str, Any] = {}

    def walk(prefix: str, table: Mapping[str, Any]) -> None:
        for key, value in table.items():
            dotted = f"{prefix}.{key}" if prefix else key
            if isinstance(value, Mapping):
                walk(dotted, value)
            else:
                flat[dotted] = value

    walk("", node)
    return flat


def describe_set(overrides: Mapping[str, Any]) -> str:
    """The set keys as command-line options: ``"--set run.duration=100.0"`` or ``"no --set"``."""
    if not overrides:
        return "no --set"
    return " ".join(f"--set {k}={format_set_value(v)}" for k, v in overrides.items())


def format_set_value(value: Any) -> str:
    """A value as ``--set`` reads it back (TOML syntax; strings bare)."""
    if isinstance(value, str):
        return value
    import tomli_w

    return tomli_w.dumps({"v": value}).strip()[len("v = "):]


def _check_set(given: Mapping[str, Any], swept: Mapping[str, Any], options: SweepOptions) -> None:
    """Refuse an unknown set key, and one that the sweep varies (one line naming it)."""
    for dotted, value in given.items():
        try:
            split_key(dotted)
        except ConfigError as exc:
            raise ConfigError(f"--set {dotted}={format_set_value(value)}: {exc}") from None
        varied = dotted in swept or (dotted == "run.seed" and options.seeds is not None)
        if varied:
            how = "seeds = K gives every replica its own run.seed" if dotted == "run.seed" \
                else f"[sweep] lists {dotted} = {swept[dotted]!r}"
            flag = "--duration or --set" if dotted == "run.duration" else "--set"
            raise ConfigError(
                f"{flag} {dotted}={format_set_value(value)}: the sweep varies {dotted} ({how}); "
                f"a key set for every point cannot also be swept: drop it from the command "
                f"line, or change the list in the sweep file"
            )
        if dotted == "output.directory":
            raise ConfigError(
                f"--set output.directory={value}: the sweep directory is given with --out "
                f"(every point gets its own directory inside it)"
            )


def _apply_set(data: dict[str, Any], given: Mapping[str, Any], resolved: bool) -> None:
    """Write the set keys into the run tables of ``data`` (in place)."""
    for dotted, value in given.items():
        table, name = split_key(dotted)
        if not isinstance(data.get(table, {}), Mapping):
            raise ConfigError(f"--set {dotted}: [{table}] of the sweep file is not a table")
        data[table] = dict(data.get(table, {}))
        data[table][name] = copy.deepcopy(value)
    if resolved and "knot.beads" in given and "knot.major_radius" not in given:
        # a run.toml's resolved radius belongs to its bead count: let it follow knot.beads
        if isinstance(data.get("knot"), Mapping):
            data["knot"].pop("major_radius", None)


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


def load_sweep_file(
    path: str | os.PathLike,
    directory: str | os.PathLike | None = None,
    overrides: Mapping[str, Any] | None = None,
) -> Sweep:
    """Read and validate a sweep file (see the module docstring).

    Parameters
    ----------
    path : path
        The TOML sweep file.
    directory : path, optional
        The sweep directory, replacing the file's ``output.directory`` (default when the file
        has none: ``sweeps/<file stem>``).
    overrides : mapping of dotted key to value, optional
        Keys set at every point (``knotmm sweep --set``, ``--duration``; see the module
        docstring).

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
        return Sweep.from_dict(data, directory=directory, overrides=overrides)
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from None


def describe_points(sweep: Sweep, errors: Mapping[str, str] | None = None) -> str:
    """A listing of the points (for ``knotmm sweep --dry-run``).

    Parameters
    ----------
    sweep : Sweep
    errors : mapping of point name to message, optional
        Points that cannot run (:func:`knotmm.sweep.check.check_points`): marked in the
        listing, and counted at its end. Without it the points are only listed.
    """
    given = f"; every point with {describe_set(sweep.overrides)}" if sweep.overrides else ""
    k = sweep.options.seeds
    ensemble = f"; {len(sweep.points) // k} combinations x {k} replicas" if k else ""
    lines = [
        f"{len(sweep.points)} points in {sweep.directory} ({sweep.options.mode}{ensemble}{given}):"
    ]
    for p in sweep.points:
        mark = "  cannot run" if errors and p.name in errors else ""
        seed = f"  (run.seed = {p.values['run.seed']})" if p.replica is not None else ""
        lines.append(f"  {p.index:4d}  {p.name}{seed}{mark}")
    if errors is not None:
        n = len(sweep.points)
        lines.append(
            f"{len(errors)} of {n} points cannot run"
            if errors
            else f"all {n} points pass the checks `knotmm run` makes before it starts"
        )
    return "\n".join(lines)
