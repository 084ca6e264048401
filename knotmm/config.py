"""Run files (TOML) -> validated, resolved run parameters.

A run file has four tables, ``[knot]``, ``[model]``, ``[run]`` and ``[output]``; every key has
a default (the study's values), so an empty file is the default run. Several chains in one
fluid are an array of tables ``[[chains]]`` in place of ``[knot]``: each holds the keys of
``[knot]`` plus ``offset`` and ``rotation`` (:data:`CHAIN_KEYS`). :data:`SCHEMA` is the
single source of truth for key names, types, defaults, ranges and documentation. Validation
is strict: unknown keys (with a did-you-mean), wrong types and impossible values raise
:class:`knotmm.errors.ConfigError` with one line that names the key.

Keys are addressed with dotted names, ``"knot.beads"``, everywhere (command-line overrides,
sweeps, error messages).

Examples
--------
>>> cfg = RunConfig.from_dict({"knot": {"beads": 60}})
>>> cfg["knot.beads"], cfg["model.bond_length"]
(60, 0.6)
>>> cfg.replace({"run.duration": 10.0})["run.duration"]
10.0
"""

from __future__ import annotations

import copy
import difflib
import math
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import tomli_w

from knotmm import limits
from knotmm.dynamics import registry
from knotmm.errors import ConfigError
from knotmm.limits import MAX_BEADS, MAX_LENGTH, as_float, shown

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = [
    "CHAIN_KEYS",
    "SCHEMA",
    "Key",
    "RunConfig",
    "load_run_file",
    "parse_override",
]

@dataclass(frozen=True)
class Key:
    """One run-file key: its type, default, allowed range and meaning.

    Parameters
    ----------
    kind : {"int", "float", "bool", "str", "int_list", "float_list"}
        The TOML type expected. Integers are accepted where floats are expected.
    default : object
        The value used when the key is absent; ``None`` means "absent unless given" (such a
        key is left out of a written run file while unset).
    doc : str
        Meaning and unit, shown in documentation and error messages.
    minimum, maximum : float, optional
        Inclusive bounds; ``exclusive_minimum`` makes the lower bound strict.
    choices : tuple of str, optional
        Allowed values of a string key.
    allow_inf : bool, optional
        Whether ``inf`` is valid (float keys).
    why : str, optional
        The reason for the limit from ``knotmm.limits``, told with a value past it: the upper
        bound, or the lower one of a key without an upper bound (``run.peclet``).
    """

    kind: str
    default: Any
    doc: str
    minimum: float | None = None
    maximum: float | None = None
    exclusive_minimum: bool = False
    choices: tuple[str, ...] | None = None
    allow_inf: bool = False
    why: str = ""


def resolve_stepping(cfg) -> tuple[str, float]:
    """The integrator and step a run uses, ``(name, step in tau_d)``: ``run.integrator`` and
    ``run.timestep`` resolved by :func:`knotmm.dynamics.registry.resolve`, which holds the
    policy (``"auto"``, default steps). ``cfg``: a RunConfig or a mapping of dotted keys."""
    return registry.resolve(cfg["run.integrator"], cfg["run.peclet"], cfg["run.timestep"])


def resolve_tolerance(cfg, integrator: str) -> float:
    """``run.tolerance`` for ``integrator`` (a resolved name): as given, or its default in d."""
    return registry.resolve_tolerance(integrator, cfg["run.tolerance"], cfg["run.peclet"])


#: Every key a run file may hold, by table. Defaults are the study's parameters.
SCHEMA: dict[str, dict[str, Key]] = {
    "knot": {
        "kind": Key(
            "str", "torus", "template kind: torus, braid, knotinfo (a knot or link name), file; "
            "open filaments: straight, arc, helix",
            choices=("torus", "braid", "knotinfo", "file", "straight", "arc", "helix"),
        ),
        "p": Key("int", 2, "torus knot: number of loops (windings around the torus axis)", 1),
        "q": Key("int", 3, "torus knot: windings through the torus hole", 1),
        "word": Key("int_list", None, "braid: signed generator indices, e.g. [1, -2, 1, -2]"),
        "name": Key("str", None, "knotinfo: knot name such as '5_2', or a link such as 'L4a1'"),
        "path": Key("str", None, "file: PDB or DCD path (a DCD needs its PDB beside it)"),
        "frame": Key("int", 0, "file: frame index (negative counts from the end)"),
        "topology": Key("str", None, "file: topology PDB for a DCD path"),
        "beads": Key("int", 90, "number of beads N", 4, MAX_BEADS, why=limits.BEADS_WHY),
        "minor_radius": Key("float", 0.6, "minor radius a of the template torus, in d", 0.0,
                            MAX_LENGTH, True, why=limits.LENGTH_WHY),
        "major_radius": Key(
            "float", None,
            "major radius r0 of the template torus, in d; default: bonds exactly bond_length",
            0.0, MAX_LENGTH, True, why=limits.LENGTH_WHY,
        ),
        "mirror": Key("bool", False, "true: the mirror image (left-handed for T(2,3))"),
        "closed": Key(
            "bool", None, "false: an open filament (no closing bond, no bending at its ends); "
            "default: true, false for straight, arc and helix, and for a file as its bonds say "
            "(false cuts each ring open, true closes each open chain)",
        ),
        "arc_degrees": Key("float", 180.0, "arc: the angle the arc spans, in degrees", 0.0,
                           360.0, True),
        "helix_radius": Key("float", 2.0, "helix: radius, in d", 0.0, MAX_LENGTH, True,
                            why=limits.LENGTH_WHY),
        "helix_pitch": Key("float", 3.0, "helix: rise per turn along its axis (z), in d", 0.0,
                           MAX_LENGTH, why=limits.LENGTH_WHY),
        "perturbation": Key("float", 0.0, "random displacement of each bead (std), in d", 0.0,
                            MAX_LENGTH, why=limits.LENGTH_WHY),
        "seed": Key("int", None, "seed of the template perturbation; default: run.seed", 0),
    },
    "model": {
        "bond_length": Key("float", 0.6, "equilibrium bond length l0, in d", 0.0, MAX_LENGTH,
                           True, why=limits.LENGTH_WHY),
        "bond_stiffness": Key("float", 50.0, "bond stiffness B, in F0/d", 0.0, None, True),
        "bending_stiffness": Key("float", 5.0, "bending stiffness A, in F0 d", 0.0),
        "lj_sigma": Key("float", 0.5, "steric length sigma, in d", 0.0, MAX_LENGTH, True,
                        why=limits.LENGTH_WHY),
        "lj_epsilon": Key("float", 0.25, "steric energy eps, in F0 d", 0.0),
        "gravity": Key("float", 1.0, "force on each bead along -z, in F0", 0.0,
                       limits.MAX_GRAVITY, why=limits.GRAVITY_WHY),
        "segment_repulsion": Key(
            "bool", False,
            "true: steric sites at bond midpoints forbid strand passage (not the study's model)",
        ),
    },
    "run": {
        "duration": Key("float", 200.0, "simulated time, in tau_d", 0.0, None, True),
        "integrator": Key("str", registry.AUTO, registry.integrator_help(),
                          choices=(registry.AUTO, *registry.NAMES)),
        "timestep": Key("float", None, registry.timestep_help(), 0.0, None, True),
        "tolerance": Key("float", None, registry.tolerance_help(), 0.0, None, True),
        "max_timestep": Key("float", registry.DEFAULT_MAX_TIMESTEP,
                            "adaptive integrators: largest step, in tau_d", 0.0, None, True),
        "min_timestep": Key(
            "float", registry.DEFAULT_MIN_TIMESTEP,
            "adaptive integrators: a step below this stops the run, in tau_d", 0.0, None, True,
        ),
        "max_bond_length": Key(
            "float", 3.0, "a bond longer than this stops the run, in d", 0.0, None, True,
        ),
        "peclet": Key(
            "float", math.inf, "Peclet number d F0/(kT); inf: deterministic", limits.MIN_PECLET,
            allow_inf=True, why=limits.PECLET_WHY,
        ),
        "platform": Key("str", "auto", "OpenMM platform: auto, " + ", ".join(registry.PLATFORMS),
                        choices=("auto", *registry.PLATFORMS)),
        "engine": Key(
            "str", "auto",
            "who integrates: plugin (the compiled knotmm.plugin.RPYIntegrator: every step in "
            "C++, same steps as python for deterministic methods; Cholesky or Lanczos noise; "
            "on every platform it has a kernel for, which knotmm --version lists), python "
            "(the Python integrators, the reference), auto (plugin when it is built and has "
            "a kernel on the platform, Brownian runs too; python otherwise)",
            choices=("auto", registry.PLUGIN_ENGINE, registry.PYTHON_ENGINE),
        ),
        "precision": Key(
            "str", "auto",
            "precision on a device platform (CUDA, HIP, OpenCL): auto (= mixed: "
            "single-precision forces, double-precision positions and sums) or double; the "
            "Reference platform is double throughout, the CPU platform's forces are single "
            "(double is refused there)", choices=registry.PRECISIONS,
        ),
        "threads": Key("int", 1, "CPU platform threads", 1, limits.MAX_THREADS,
                       why=limits.THREADS_WHY),
        "mobility_threads": Key("int", 1, "threads of the RPY pair loop (same trajectory); 2 "
                                "threads on 2 cores: 1.3x at N = 120, 1.6x at 240, 1.7x at "
                                "480; keep 1 when sweep workers fill the cores", 1,
                                limits.MAX_THREADS, why=limits.THREADS_WHY),
        "seed": Key("int", 1, "random seed (noise, perturbations)", 0),
        "replicas": Key("int", 1, "independent copies of the run, in one process, written to "
                        "DIR/replica_0 ... (each seeded from run.seed; knotmm.replicas)", 1,
                        limits.MAX_REPLICAS, why=limits.REPLICAS_WHY),
        "replica_stepping": Key("str", "auto", "together (copies of one Context, where the "
                                "plugin can), one_after_another (each equal to its single run "
                                "bit for bit), or auto (together where measured faster)",
                                choices=("auto", "together", "one_after_another")),
        "replicas_at_once": Key("int", 0, "replicas (or groups of copies) stepping at the "
                                "same time, each in a thread; 0: auto (the CPU cores over "
                                "run.threads x run.mobility_threads; 1 on a device or the "
                                "Python engine)", 0, limits.MAX_THREADS, why=limits.THREADS_WHY),
        "noise": Key(
            "str", "auto",
            "Brownian noise sqrt(mu) xi: auto (cholesky up to 300 beads, else lanczos), "
            "cholesky (exact), lanczos (Krylov, matrix-free)",
            choices=("auto", "cholesky", "lanczos"),
        ),
        "lanczos_tolerance": Key(
            "float", registry.DEFAULT_LANCZOS_TOLERANCE,
            "lanczos noise: relative change between successive iterates", 0.0, None, True,
        ),
        "topology_check_interval": Key(
            "float", 10.0,
            "time between knot-type checks (topoly), in tau_d; 0 switches them off", 0.0,
        ),
        "on_topology_change": Key(
            "str", "warn", "when the knot type changes: warn (record it) or stop the run",
            choices=("warn", "stop"),
        ),
    },
    "output": {
        "directory": Key("str", "runs/trefoil", "run directory"),
        "frame_interval": Key("float", 0.5, "time between trajectory frames, in tau_d",
                              0.0, None, True),
        "observables_interval": Key(
            "float", None, "time between observables rows, in tau_d; default: frame_interval",
            0.0, None, True,
        ),
        "checkpoint_interval": Key(
            "float", 10.0,
            "time between checkpoints, in tau_d (rounded up to whole frame intervals)",
            0.0, None, True,
        ),
    },
}


#: Keys of one ``[[chains]]`` entry: those of ``[knot]``, plus where the chain starts.
CHAIN_KEYS: dict[str, Key] = {
    **SCHEMA["knot"],
    "offset": Key(
        "float_list", [0.0, 0.0, 0.0], "[x, y, z]: where the chain's centre of mass starts, in d"
    ),
    "rotation": Key(
        "float_list", None,
        "[x, y, z, degrees]: the chain's template turned by that angle about that axis "
        "(through its centre of mass) before the offset",
    ),
}


def _check_chains(entries: Any) -> list[dict[str, Any]]:
    """Validate a run file's ``[[chains]]`` array; return it with every key filled in."""
    if not isinstance(entries, (list, tuple)) or not entries or not all(
        isinstance(e, Mapping) for e in entries
    ):
        raise ConfigError(
            "chains must be an array of tables ([[chains]] entries, one per chain), got "
            f"{entries!r}"
        )
    out = []
    for c, entry in enumerate(entries):
        values = {}
        for name in entry:
            if name not in CHAIN_KEYS:
                raise ConfigError(f"unknown key chains[{c}].{name}" + _suggest(name, CHAIN_KEYS))
        for name, key in CHAIN_KEYS.items():
            if name in entry:
                values[name] = _check_value(f"chains[{c}].{name}", key, entry[name])
            else:
                values[name] = copy.deepcopy(key.default)
        limits.check_placement(values["offset"], values["rotation"], f"chains[{c}].")
        limits.check_shape_sizes(values, f"chains[{c}].")
        out.append(values)
    limits.check_total_beads(out)
    return out


def _suggest(name: str, options) -> str:
    close = difflib.get_close_matches(name, list(options), n=1)
    return f"; did you mean '{close[0]}'?" if close else ""


def _check_value(dotted: str, key: Key, value: Any) -> Any:
    """Validate one value against its :class:`Key`; return it normalised."""
    expected = {
        "int": "an integer",
        "float": "a number",
        "bool": "true or false",
        "str": "a string",
        "int_list": "a list of integers",
        "float_list": "a list of numbers",
    }[key.kind]
    if key.kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{dotted} = {shown(value)}: expected {expected}")
    elif key.kind == "float":
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{dotted} = {shown(value)}: expected {expected}")
        number = as_float(value)  # NaN for an integer past the float range
        if math.isnan(number) or (math.isinf(number) and not (key.allow_inf and number > 0)):
            raise ConfigError(f"{dotted} = {shown(value)}: expected a finite number")
        value = number
    elif key.kind == "bool":
        if not isinstance(value, bool):
            raise ConfigError(f"{dotted} = {shown(value)}: expected {expected}")
    elif key.kind == "str":
        if not isinstance(value, str):
            raise ConfigError(f"{dotted} = {shown(value)}: expected {expected}")
        if key.choices is not None and value not in key.choices:
            # accept case-insensitive platform names etc.
            lowered = {c.lower(): c for c in key.choices}
            if value.lower() in lowered:
                value = lowered[value.lower()]
            else:
                raise ConfigError(
                    f"{dotted} = {shown(value)}: expected one of {', '.join(key.choices)}"
                    + _suggest(value, key.choices)
                )
    elif key.kind == "int_list":
        if not isinstance(value, (list, tuple)) or not all(
            isinstance(v, int) and not isinstance(v, bool) for v in value
        ):
            raise ConfigError(f"{dotted} = {shown(value)}: expected {expected}")
        value = [int(v) for v in value]
    elif key.kind == "float_list":
        if not isinstance(value, (list, tuple)) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(as_float(v))
            for v in value
        ):
            raise ConfigError(f"{dotted} = {shown(value)}: expected {expected} (finite)")
        value = [float(v) for v in value]
    if key.kind in ("int", "float"):
        why = f" ({key.why})" if key.why else ""  # the limit's: the upper bound's, if any
        low = "" if key.maximum is not None else why
        if key.minimum is not None:
            if key.exclusive_minimum and not value > key.minimum:
                raise ConfigError(f"{dotted} = {shown(value)}: must be > {key.minimum:g}{low}")
            if not key.exclusive_minimum and not value >= key.minimum:
                raise ConfigError(f"{dotted} = {shown(value)}: must be >= {key.minimum:g}{low}")
        if key.maximum is not None and not value <= key.maximum:
            raise ConfigError(f"{dotted} = {shown(value)}: must be <= {key.maximum:g}{why}")
    return value


def split_key(dotted: str) -> tuple[str, str]:
    """Split ``"table.key"`` and check that it names a known key."""
    table, sep, name = dotted.partition(".")
    if not sep or table not in SCHEMA:
        raise ConfigError(
            f"unknown key '{dotted}': keys are written table.key with table one of "
            f"{', '.join(SCHEMA)}" + _suggest(table, SCHEMA)
        )
    if name not in SCHEMA[table]:
        raise ConfigError(f"unknown key [{table}] {name}" + _suggest(name, SCHEMA[table]))
    return table, name


class RunConfig(Mapping):
    """Validated run parameters, addressed by dotted key (``cfg["model.bond_length"]``).

    Build one with :meth:`from_dict` or :func:`load_run_file`; it is immutable, and
    :meth:`replace` returns a validated copy with some keys changed. Iterating yields the
    dotted keys that are set.
    """

    def __init__(self, values: dict[str, dict[str, Any]], chains: list | None = None):
        self._values = values
        self._chains = chains

    # -- construction -------------------------------------------------------------------
    @classmethod
    def from_dict(cls, data: Mapping[str, Any] | None = None) -> RunConfig:
        """Validate a nested mapping (as parsed from TOML) and fill in defaults.

        Raises
        ------
        ConfigError
            For an unknown table or key, a wrong type, or a value out of range.
        """
        data = {} if data is None else data
        if not isinstance(data, Mapping):
            raise ConfigError(f"a run file must be a table of tables, got {type(data).__name__}")
        values: dict[str, dict[str, Any]] = {}
        chains = None
        if "chains" in data:
            chains = _check_chains(data["chains"])
            if "knot" in data:
                raise ConfigError(
                    "a run file gives either [knot] (one chain) or [[chains]] (several), not "
                    "both: move the [knot] keys into a [[chains]] entry"
                )
        for table in data:
            if table == "chains":
                continue
            if table not in SCHEMA:
                extra = " ([sweep] tables belong in sweep files)" if table == "sweep" else ""
                raise ConfigError(
                    f"unknown table [{table}]: expected {', '.join(SCHEMA)}"
                    + _suggest(table, SCHEMA)
                    + extra
                )
            if not isinstance(data[table], Mapping):
                raise ConfigError(f"[{table}] must be a table, got {data[table]!r}")
        for table, keys in SCHEMA.items():
            given = dict(data.get(table, {}))
            for name in given:
                if name not in keys:
                    raise ConfigError(f"unknown key [{table}] {name}" + _suggest(name, keys))
            values[table] = {}
            for name, key in keys.items():
                if name in given:
                    values[table][name] = _check_value(f"{table}.{name}", key, given[name])
                else:
                    values[table][name] = copy.deepcopy(key.default)
        if chains is None:
            limits.check_shape_sizes(values["knot"], "knot.")
        cfg = cls(values, chains)
        cfg._check_consistency()
        return cfg

    def _check_consistency(self) -> None:
        """Cross-key checks that a single key's range cannot express."""
        out = self._values["output"]
        run = self._values["run"]
        if run["min_timestep"] >= run["max_timestep"]:
            raise ConfigError(
                f"run.min_timestep = {run['min_timestep']!r} must be smaller than "
                f"run.max_timestep = {run['max_timestep']!r}"
            )
        if out["frame_interval"] > run["duration"]:
            raise ConfigError(
                f"output.frame_interval = {out['frame_interval']!r} is longer than "
                f"run.duration = {run['duration']!r}: lower the interval or run longer"
            )
        limits.check_frames(run["duration"], out["frame_interval"])
        name, step = registry.resolve(run["integrator"], run["peclet"], run["timestep"])
        limits.check_steps(run["duration"], *((run["max_timestep"], "run.max_timestep")
                           if registry.REGISTRY[name].adaptive else (step, "run.timestep")))
        if run["max_bond_length"] <= self._values["model"]["bond_length"]:
            raise ConfigError(
                f"run.max_bond_length = {run['max_bond_length']!r} must exceed "
                f"model.bond_length = {self._values['model']['bond_length']!r}"
            )

    # -- access -------------------------------------------------------------------------
    def __getitem__(self, dotted: str) -> Any:
        table, name = split_key(dotted)
        return self._values[table][name]

    def __iter__(self):
        for table, keys in self._values.items():
            for name, value in keys.items():
                if value is not None:
                    yield f"{table}.{name}"

    def __len__(self) -> int:
        return sum(1 for _ in self)

    @property
    def chains(self) -> list[dict[str, Any]] | None:
        """The ``[[chains]]`` entries (every key filled in), or ``None`` for a ``[knot]`` run."""
        return copy.deepcopy(self._chains)

    def chain_config(self, index: int) -> RunConfig:
        """The one-chain run configuration of ``[[chains]]`` entry ``index``: its keys as the
        ``[knot]`` table (without ``offset`` and ``rotation``), the other tables as here.

        Not validated again: the entry's keys are ``[knot]``'s, validated (sizes too) with
        the ``[[chains]]`` array, and the other tables with this configuration."""
        entry = self._chains[index]
        values = copy.deepcopy(self._values)
        values["knot"] = {
            name: copy.deepcopy(entry[name] if entry.get(name) is not None else key.default)
            for name, key in SCHEMA["knot"].items()
        }
        return RunConfig(values, None)

    def table(self, name: str) -> dict[str, Any]:
        """A copy of one table, ``{key: value}`` (unset optional keys are ``None``)."""
        if name not in self._values:
            raise ConfigError(f"unknown table [{name}]" + _suggest(name, SCHEMA))
        return dict(self._values[name])

    def replace(self, changes: Mapping[str, Any]) -> RunConfig:
        """Return a validated copy with ``{"table.key": value}`` changes applied
        (``"chains"``: a new ``[[chains]]`` array). Only the changed keys are validated (as
        :meth:`from_dict` would), then the cross-key checks; a change of shape (``chains`` on a
        ``[knot]`` run, ``knot.*`` on a ``[[chains]]`` run) goes through :meth:`from_dict`."""
        several = self._chains is not None
        if not any(d.startswith("knot.") if several else d == "chains" for d in changes):
            values = copy.deepcopy(self._values)
            chains = self._chains
            for dotted, value in changes.items():
                if dotted == "chains":
                    chains = _check_chains([{k: v for k, v in dict(e).items() if v is not None}
                                            for e in value])
                    continue
                table, name = split_key(dotted)
                values[table][name] = _check_value(dotted, SCHEMA[table][name], value)
            if chains is None and any(d.startswith("knot.") for d in changes):
                limits.check_shape_sizes(values["knot"], "knot.")
            cfg = RunConfig(values, copy.deepcopy(chains))
            cfg._check_consistency()
            return cfg
        data = self.to_dict(include_unset=False)
        for dotted, value in changes.items():
            if dotted == "chains":  # the whole [[chains]] array (a template's resolved keys)
                data["chains"] = [{k: v for k, v in dict(e).items() if v is not None}
                                  for e in value]
                continue
            table, name = split_key(dotted)
            data.setdefault(table, {})[name] = value
        return RunConfig.from_dict(data)

    # -- output -------------------------------------------------------------------------
    def to_dict(self, include_unset: bool = False) -> dict[str, dict[str, Any]]:
        """Nested ``{table: {key: value}}``; unset optional keys only if ``include_unset``.
        A ``[[chains]]`` run has ``"chains"``, a list of tables, in place of ``"knot"``."""
        out: dict[str, Any] = {
            table: {k: copy.deepcopy(v) for k, v in keys.items() if include_unset or v is not None}
            for table, keys in self._values.items()
        }
        if self._chains is not None:
            out.pop("knot")
            out["chains"] = [
                {k: copy.deepcopy(v) for k, v in entry.items() if include_unset or v is not None}
                for entry in self._chains
            ]
        return out

    def to_toml(self, header: str = "") -> str:
        """The run file text: every resolved key, usable again as a run file."""
        text = tomli_w.dumps(self.to_dict())
        return header + text

    def __repr__(self) -> str:
        return f"RunConfig({self.to_dict()!r})"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, RunConfig) and self.to_dict() == other.to_dict()

    __hash__ = None  # type: ignore[assignment]


def read_toml(path: str | Path, what: str = "run file") -> dict[str, Any]:
    """Read a TOML file; raise :class:`ConfigError` with one line on any problem."""
    path = Path(path)
    if not path.exists():
        raise ConfigError(f"{what} {str(path)!r} does not exist")
    if path.is_dir():
        raise ConfigError(f"{what} {str(path)!r} is a directory; give the .toml file")
    try:
        with path.open("rb") as fh:
            return tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{what} {str(path)!r} is not valid TOML: {exc}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{what} {str(path)!r} cannot be read: {exc}") from None


def load_run_file(path: str | Path) -> RunConfig:
    """Load and validate a run file.

    Extra top-level tables written by knotmm itself into ``run.toml`` (``[knotmm]``, with
    the version and resolved facts) are ignored, so a run's ``run.toml`` is a valid run file.
    """
    data = read_toml(path)
    data.pop("knotmm", None)
    try:
        return RunConfig.from_dict(data)
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from None


def parse_override(text: str) -> tuple[str, Any]:
    """Parse ``table.key=value`` (value in TOML syntax, bare words as strings)."""
    dotted, sep, raw = text.partition("=")
    if not sep:
        raise ConfigError(f"--set {text!r}: expected table.key=value, e.g. run.duration=50")
    dotted = dotted.strip()
    table, name = split_key(dotted)
    text = raw.strip()
    try:
        value = tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        value = text
    if SCHEMA[table][name].kind == "str" and not isinstance(value, str):
        value = text  # e.g. knot.name=6_1, which TOML would read as the integer 61
    return dotted, value
