"""One owner each: the method table, the integrators' defaults, the platforms (issue 31).

The owners: :mod:`knotmm.dynamics.registry` (``REGISTRY``, its ``DEFAULT_*`` constants,
``PLATFORMS``/``HOST_PLATFORMS``/``DEVICE_PLATFORMS``) and the compiled plugin's C++ method
table (``knotmm.plugin.METHODS``; ``tests/plugin/test_plugin_contract.py`` holds the two tables
together). Generated text (``run.integrator``'s help and choices, ``run.platform``'s) is
compared with what the registry writes; every prose copy (the plugin's docstring, its C++
header's comments, the README's run-file block and integrator table, ``plugin/README.md``) must
list exactly the owner's names: a copy that omits one or names one that does not exist fails.
Defaults: the run-file schema, every integrator class constructed without arguments, the
plugin's Python class and its C++ constructor all give the registry's values.
"""

from __future__ import annotations

import inspect
import math
import re
from pathlib import Path

import pytest

from knotmm.config import SCHEMA
from knotmm.dynamics import registry
from knotmm.dynamics.registry import (
    AUTO,
    DEFAULT_LANCZOS_TOLERANCE,
    DEFAULT_MAX_TIMESTEP,
    DEFAULT_MIN_TIMESTEP,
    DEFAULT_TIMESTEP,
    DEFAULT_TOLERANCE,
    DEVICE_PLATFORMS,
    HOST_PLATFORMS,
    NAMES,
    PLATFORMS,
    PLUGIN_ENGINE,
    REGISTRY,
)

ROOT = Path(__file__).resolve().parents[2]
#: The methods the plugin has, by the registry (the contract test holds the C++ table to it).
PLUGIN_NAMES = tuple(n for n, info in REGISTRY.items() if PLUGIN_ENGINE in info.engines)
_NAME = re.compile(r"[a-z][a-z0-9_]*\Z")


def _text(relative: str) -> str:
    return (ROOT / relative).read_text(encoding="utf-8")


def _between(text: str, start: str, end: str) -> str:
    i = text.index(start) + len(start)
    return text[i:text.index(end, i)]


def _same(listed, owner, where: str) -> None:
    """``listed`` names each of ``owner`` once and nothing else."""
    listed = list(listed)
    missing = sorted(set(owner) - set(listed))
    unknown = sorted(set(listed) - set(owner))
    twice = sorted({n for n in listed if listed.count(n) > 1})
    assert not (missing or unknown or twice), (
        f"{where}: omits {missing}, names {unknown} that do not exist, lists {twice} twice")


def _listed_code(text: str) -> list[str]:
    """The `name`s of a sentence that lists code names: those outside parentheses, up to the
    sentence's end (a ". " outside parentheses and code)."""
    names, depth = [], 0
    for k, part in enumerate(text.split("`")):
        if k % 2:
            if depth == 0 and _NAME.match(part):
                names.append(part)
            continue
        for j, char in enumerate(part):
            depth += {"(": 1, ")": -1}.get(char, 0)
            if depth == 0 and part[j:j + 2] in (". ", ".\n"):
                return names
    return names


def _plugin():
    kp = pytest.importorskip("knotmm.plugin")
    if not kp.available():
        pytest.skip(f"plugin not available: {kp.load_error()}")
    return kp


# -- the method table: generated copies --------------------------------------------------------
def test_run_integrator_help_and_choices_are_written_from_the_registry():
    key = SCHEMA["run"]["integrator"]
    assert key.choices == (AUTO, *NAMES)
    assert key.doc == registry.integrator_help()
    for info in REGISTRY.values():
        assert f"{info.name} ({info.description}" in key.doc
    assert SCHEMA["run"]["timestep"].doc == registry.timestep_help()
    assert SCHEMA["run"]["tolerance"].doc == registry.tolerance_help()


def test_the_generated_help_names_each_default():
    text = registry.timestep_help()
    assert f"default {DEFAULT_TIMESTEP:g} (" in text
    listed = re.findall(r"([\d.]+) for ([\w, ]+?)(?=, \d|\))", text)
    steps = {name: float(h) for h, names in listed
             for name in re.findall(r"\w+", names.replace(" and ", ", "))}
    assert steps == {n: i.default_timestep for n, i in REGISTRY.items() if i.brownian}
    text = registry.tolerance_help()
    assert f"default {DEFAULT_TOLERANCE:g} (" in text
    assert f"{registry.AUTO_BROWNIAN}: {REGISTRY[registry.AUTO_BROWNIAN].default_tolerance:g}" \
        in text


# -- the method table: prose copies ------------------------------------------------------------
def test_the_plugin_docstring_table_lists_every_plugin_method():
    import knotmm.plugin as kp  # the docstring is there with or without the compiled plugin

    borders = [m.start() for m in re.finditer(r"^=+ ", kp.__doc__, re.M)]
    table = kp.__doc__[borders[1]:borders[2]]  # the rows, between the 2nd and 3rd border
    rows = re.findall(r"^``([a-z0-9_]+)``\s+(\d)\S*\s+(yes|no)\s", table, re.M)
    _same([name for name, _, _ in rows], PLUGIN_NAMES, "knotmm.plugin's docstring table")
    for name, order, adaptive in rows:
        assert (int(order), adaptive == "yes") == (REGISTRY[name].order, REGISTRY[name].adaptive)
    if kp.available():
        _same([name for name, _, _ in rows], kp.METHODS, "knotmm.plugin's docstring table")


def test_the_cpp_headers_comments_list_every_method():
    header = _text("plugin/openmmapi/include/knotmm/RPYIntegrator.h")
    _same(re.findall(r'"(\w+)"', _between(header, "@param method", "@param errorTolerance")),
          PLUGIN_NAMES, "RPYIntegrator.h, @param method")
    for flag, attr in (("adaptive", "adaptive"), ("stochastic", "brownian")):
        comment = re.search(r"\(([\w,\s]+);\s*\*?\s*RPYMethodInfo::" + flag, header)
        _same(re.findall(r"\w+", comment.group(1)),
              [n for n in PLUGIN_NAMES if getattr(REGISTRY[n], attr)],
              f"RPYIntegrator.h, RPYMethodInfo::{flag}")


def test_the_readme_lists_every_integrator():
    readme = _text("README.md")
    block = _between(readme, '\nintegrator = "auto"', "\ntimestep =")
    choices = " ".join(line.split("#", 1)[1] for line in block.splitlines()).split("(")[0]
    _same([c.strip() for c in choices.split("|")], (AUTO, *NAMES), "README, integrator =")
    section = readme[readme.index("### Integrators\n"):]
    rows = re.findall(r"^\| (`[^|]+) \|", _between(section, "|---|", "\n\n"), re.M)
    _same([n for row in rows for n in re.findall(r"`(\w+)`", row)], NAMES,
          "README, the Integrators table")


def test_plugin_readme_lists_every_plugin_method():
    text = _text("plugin/README.md")
    _same(_listed_code(_between(text, "Methods: ", "\n\n")), PLUGIN_NAMES,
          "plugin/README.md, Methods:")
    fixed = re.search(r"`FixedSteps`: ([\w, ]+);", text).group(1)
    _same([n.strip() for n in fixed.split(",")],
          [n for n in PLUGIN_NAMES if not REGISTRY[n].adaptive], "plugin/README.md, FixedSteps")
    adaptive = re.search(r"with an adaptive\s+method \(([\w, ]+)\)", text).group(1)
    _same([n.strip() for n in adaptive.split(",")],
          [n for n in PLUGIN_NAMES if REGISTRY[n].adaptive], "plugin/README.md, adaptive")


def test_the_helpers_of_this_file_catch_a_stale_copy():
    """An omission and a name that does not exist are both caught."""
    with pytest.raises(AssertionError, match="omits"):
        _same(NAMES[:-1], NAMES, "copy")
    with pytest.raises(AssertionError, match="ito_heun_adapt"):
        _same((*NAMES, "ito_heun_adapt"), NAMES, "copy")
    assert _listed_code("Methods: `a`, `b` (as `c`; `d`), `e`. Not `f`.") == ["a", "b", "e"]


# -- the defaults ------------------------------------------------------------------------------
def test_the_schema_defaults_are_the_registrys():
    run = SCHEMA["run"]
    assert run["max_timestep"].default == DEFAULT_MAX_TIMESTEP
    assert run["min_timestep"].default == DEFAULT_MIN_TIMESTEP
    assert run["lanczos_tolerance"].default == DEFAULT_LANCZOS_TOLERANCE
    # unset: resolved by the registry (resolve, resolve_tolerance) from the same constants
    assert run["timestep"].default is None and run["tolerance"].default is None
    assert registry.resolve(AUTO, math.inf, None) == (registry.AUTO_DETERMINISTIC,
                                                      DEFAULT_TIMESTEP)
    make = inspect.signature(registry.make).parameters
    assert make["max_timestep"].default == DEFAULT_MAX_TIMESTEP
    assert make["min_timestep"].default == DEFAULT_MIN_TIMESTEP
    assert make["lanczos_tolerance"].default == DEFAULT_LANCZOS_TOLERANCE


@pytest.mark.parametrize("name", NAMES)
def test_every_class_built_without_arguments_has_the_registrys_defaults(name):
    info = REGISTRY[name]
    params = inspect.signature(info.load().__init__).parameters
    for param, value in (("tolerance", info.default_tolerance),
                         ("max_timestep", DEFAULT_MAX_TIMESTEP),
                         ("min_timestep", DEFAULT_MIN_TIMESTEP),
                         ("lanczos_tolerance", DEFAULT_LANCZOS_TOLERANCE)):
        if param in params:  # a run passes each (registry.make): the class holds the same
            assert params[param].default == value, param
    integ = info.load()()
    assert integ.timestep == info.default_timestep
    if info.adaptive:
        assert integ.tolerance == info.default_tolerance
        assert integ.max_timestep == DEFAULT_MAX_TIMESTEP
        assert integ.min_timestep == DEFAULT_MIN_TIMESTEP
    if info.brownian:
        assert integ.noise.tolerance == DEFAULT_LANCZOS_TOLERANCE
    # what a run resolves for it from an unset run.timestep and run.tolerance
    assert registry.resolve(name, 2.0, None) == (name, info.default_timestep)
    if info.adaptive:
        assert registry.resolve_tolerance(name, None, 10.0) == info.default_tolerance


def test_the_noise_defaults_are_the_registrys():
    from knotmm.dynamics import noise

    assert noise.NoiseGenerator().tolerance == DEFAULT_LANCZOS_TOLERANCE
    for fn in (noise.lanczos_sqrt, noise.lanczos_noise):
        assert inspect.signature(fn).parameters["tolerance"].default == DEFAULT_LANCZOS_TOLERANCE


def test_the_plugins_defaults_are_the_registrys():
    """The Python class reads them; the C++ constructor's own are held to them here."""
    kp = _plugin()
    for integ in (kp.RPYIntegrator(0.01), kp.rpyplugin.RPYIntegrator(0.01)):
        assert integ.getErrorTolerance() == DEFAULT_TOLERANCE
        assert integ.getMinimumStepSize() == DEFAULT_MIN_TIMESTEP
        assert integ.getMaximumStepSize() == DEFAULT_MAX_TIMESTEP
        assert integ.getLanczosTolerance() == DEFAULT_LANCZOS_TOLERANCE


def test_the_plugin_readmes_signature_shows_the_defaults():
    kp = pytest.importorskip("knotmm.plugin")
    shown = _between(_text("plugin/README.md"), "\nRPYIntegrator(step_size, ", ")\n")
    defaults = dict(re.findall(r"(\w+)=([^,\s]+)", shown))
    params = inspect.signature(kp.RPYIntegrator.__init__).parameters if kp.available() else {}
    expected = {"error_tolerance": DEFAULT_TOLERANCE, "min_step": DEFAULT_MIN_TIMESTEP,
                "max_step": DEFAULT_MAX_TIMESTEP, "lanczos_tolerance": DEFAULT_LANCZOS_TOLERANCE}
    for name, value in expected.items():
        assert float(defaults[name]) == value, name
        if params:
            assert params[name].default == value, name


# -- the platforms -----------------------------------------------------------------------------
def test_run_platform_choices_and_help_are_the_registrys():
    key = SCHEMA["run"]["platform"]
    assert key.choices == ("auto", *PLATFORMS)
    _same(re.findall(r"\w+", key.doc.split(":", 1)[1]), key.choices, "run.platform's help")
    assert set(HOST_PLATFORMS) | set(DEVICE_PLATFORMS) == set(PLATFORMS)
    assert SCHEMA["run"]["precision"].choices == registry.PRECISIONS


def test_the_engine_module_takes_the_registrys_platforms():
    from knotmm.engine import engines

    assert engines.DEVICE_PLATFORMS is DEVICE_PLATFORMS
    assert not hasattr(engines, "PLUGIN_PLATFORMS")  # asked of OpenMM: plugin_platforms()


def test_the_readmes_list_the_platforms():
    readme = _text("README.md")
    line = _between(readme, '\nplatform = "auto"', "\n")
    choices = line.split("#", 1)[1].split("(")[0]
    _same([c.strip() for c in choices.split("|")], ("auto", *PLATFORMS), "README, platform =")
    line = _between(readme, '\nprecision = "auto"', "\n")
    choices = line.split("#", 1)[1].split("(")[0]
    _same([c.strip() for c in choices.split("|")], registry.PRECISIONS, "README, precision =")

