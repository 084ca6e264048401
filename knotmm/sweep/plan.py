"""Planning a sweep: its points, the seeds of replicas, and what to do with each point.

* :func:`expand` turns ``{key: [values...]}`` into points (``"grid"`` or ``"zip"``);
* :func:`replica_seeds` (:mod:`knotmm.replicas`) derives the seeds of ``seeds = K``
  replicas with ``numpy.random.SeedSequence.spawn``, so a replica's seed does not depend on K;
* :func:`replicas_as_seeds` runs a sweep's ``run.replicas = K`` as its ``seeds = K``;
* :func:`point_name` names a point's directory from its swept values;
* :func:`plan_point` decides, from a point's run directory, whether to skip it (finished,
  same parameters), only analyse it, resume it from its checkpoint, or run it from the start.

See ``docs/architecture.md`` for the sweep directory.
"""

from __future__ import annotations

import itertools
import json
import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from knotmm.config import RunConfig, read_toml, resolve_stepping
from knotmm.errors import ConfigError
from knotmm.io.rundir import (
    ANALYSIS_FILE,
    RUN_FILE,
    STATUS_FINISHED,
    STATUS_INTERRUPTED,
    STATUS_RUNNING,
    run_status,
)
from knotmm.replicas import replica_seeds  # the one owner: sweeps and replicated runs
from knotmm.sweep.summary import summary_values, time_reached

__all__ = [
    "ACTIONS",
    "SweepPoint",
    "expand",
    "format_value",
    "plan_point",
    "point_name",
    "replica_seeds",
    "replicas_as_seeds",
]

log = logging.getLogger(__name__)

#: What :func:`plan_point` may decide for a point.
ACTIONS = ("skip", "analyze", "resume", "run")


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


def format_value(value: Any) -> str:
    """A value as it appears in a point directory name (and in summary.csv)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, (list, tuple)):
        return "_".join(format_value(v) for v in value)
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
    parts = [f"{k}={format_value(v)}" for k, v in values.items()]
    if replica is not None:
        parts.append(f"replica={replica}")
    return ",".join(parts) if parts else "point"


def replicas_as_seeds(
    base: RunConfig, values: Mapping[str, Any], seeds: int | None, seed: int | None
) -> tuple[int | None, RunConfig, str | None]:
    """A sweep's ``run.replicas = K``, run as its own ensemble: ``seeds = K``.

    Every point then runs K times, replica k in ``<point>,replica=k``, a run with
    ``run.replicas = 1`` and the ``run.seed`` that replica k of ``knotmm run`` gets
    (:func:`replica_seeds` of ``run.seed``), analysed and summarised as a ``seeds = K``
    ensemble.

    Parameters
    ----------
    base : RunConfig
        The sweep's run configuration (``[sweep.set]`` and ``--set`` applied).
    values : mapping
        The swept keys and their lists.
    seeds, seed : int or None
        The ``[sweep]`` options ``seeds`` and ``seed``.

    Returns
    -------
    seeds : int or None
        The ensemble size: ``run.replicas`` when it is above 1, else ``seeds`` as given.
    base : RunConfig
        With ``run.replicas = 1`` (what each point's run does).
    note : str or None
        What was done, for the user (None when ``run.replicas = 1``).

    Raises
    ------
    ConfigError
        One line: ``run.replicas`` swept, or set together with another ``seeds``, another
        ``seed`` than ``run.seed``, or a swept ``run.seed``.
    """
    if "run.replicas" in values:
        raise ConfigError(
            f"[sweep] run.replicas = {values['run.replicas']!r}: run.replicas cannot be swept; "
            f"set seeds = K in [sweep] to run K replicas of every point"
        )
    count = base["run.replicas"]
    if count == 1:
        return seeds, base, None
    if seeds is not None and seeds != count:
        raise ConfigError(
            f"[sweep] seeds = {seeds} and run.replicas = {count}: a sweep runs run.replicas as "
            f"its seeds = K ensemble; drop one of them, or give both the same K"
        )
    base_seed = base["run.seed"]
    if seed is not None and seed != base_seed:
        raise ConfigError(
            f"[sweep] seed = {seed} and run.replicas = {count}: the replicas of run.replicas "
            f"take their seeds from run.seed = {base_seed}; drop seed, or set run.seed = {seed}"
        )
    if "run.seed" in values:
        raise ConfigError(
            f"[sweep] sweeps run.seed and sets run.replicas = {count}: each replica gets its "
            f"own run.seed; drop run.seed from [sweep], or set run.replicas = 1"
        )
    note = (
        f"run.replicas = {count}: every point runs {count} times, in <point>,replica=0 ... "
        f"replica={count - 1}, each a run with run.replicas = 1 and the run.seed of that "
        f"replica of `knotmm run` (from run.seed = {base_seed}), summarised as seeds = {count}"
    )
    return count, base.replace({"run.replicas": 1}), note


def _stored_config_matches(point: SweepPoint, directory: Path) -> bool:
    """Whether the run in ``directory`` was made with this point's parameters."""
    try:
        stored = read_toml(directory / RUN_FILE)
    except ConfigError:
        return False
    wanted = point.config.to_dict(include_unset=False)
    # a run file records the integrator and step it used ("auto" and an unset step resolved)
    name, timestep = resolve_stepping(point.config)
    wanted["run"].update(integrator=name, timestep=timestep)
    wanted.get("output", {}).pop("directory", None)  # the sweep directory may have moved
    return _recorded(wanted, stored)


def _recorded(wanted: Any, stored: Any) -> bool:
    """Whether ``stored`` (a run.toml's value) records ``wanted`` (a run file's value).

    Tables (``[model]``, each ``[[chains]]`` entry) match when every wanted key is stored with
    a matching value: a run.toml also records keys resolved at the start (``tolerance``, a
    chain's ``major_radius``), which the sweep file leaves unset. Arrays (``[[chains]]``,
    ``offset``) match entry by entry, with the same length; anything else by equality.
    """
    if isinstance(wanted, Mapping):
        return isinstance(stored, Mapping) and all(
            key in stored and _recorded(value, stored[key]) for key, value in wanted.items()
        )
    if isinstance(wanted, (list, tuple)):
        return (
            isinstance(stored, (list, tuple))
            and len(stored) == len(wanted)
            and all(_recorded(w, s) for w, s in zip(wanted, stored, strict=True))
        )
    return stored == wanted


def plan_point(point: SweepPoint, directory: Path, reanalyze: bool) -> tuple[str, dict | None]:
    """What to do with a point: ``("skip", values)``, or ``("analyze" | "resume" | "run", None)``.

    A finished run with this point's parameters is skipped (or only analysed when it has no
    ``analysis.json`` or ``reanalyze``); an interrupted or killed one with the same
    parameters is resumed from its checkpoint; anything else is run from the start.
    """
    status = run_status(directory)
    if status is None:
        return "run", None
    same = _stored_config_matches(point, directory)
    if status in (STATUS_INTERRUPTED, STATUS_RUNNING) and same:
        log.info("point %s: %s run, resuming it", point.name, status)
        return "resume", None
    if status != STATUS_FINISHED or not same:
        finished = status == STATUS_FINISHED
        why = "made with other parameters" if same is False and finished else status
        log.info("point %s: run %s, running it again", point.name, why)
        return "run", None
    if reanalyze:
        return "analyze", None
    try:
        analysis = json.loads((directory / ANALYSIS_FILE).read_text())
    except (OSError, ValueError):
        return "analyze", None
    values = summary_values(analysis)
    values["time_reached"] = time_reached(directory)
    return "skip", values
