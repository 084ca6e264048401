"""Which engine integrates a run, and making it: the compiled plugin or the Python integrators.

``run.engine`` (``docs/architecture.md``, "The engine in one loop"):

* ``"python"``: the integrators of :mod:`knotmm.dynamics`, stepped from Python
  (:class:`knotmm.engine.python_engine.PythonEngine`: the readable reference);
* ``"plugin"``: :class:`knotmm.plugin.RPYIntegrator`, which takes every step in C++ up to the
  next report time (:class:`knotmm.engine.plugin_engine.PluginEngine`); if the plugin is not
  built, cannot load or is switched off (``KNOTMM_NO_PLUGIN=1``), one warning names
  :func:`knotmm.plugin.load_error` and the run uses the Python engine;
* ``"auto"`` (the default): the plugin when it is available, the Python engine otherwise, and
  for GPU platforms, where the plugin has no kernel. Brownian runs take the
  plugin too (its Cholesky is LAPACK's, as the Python engine's, and its step has no Python
  round trips: T(2,3), N = 90, Pe = 2, CPU time per step 1.12 against 1.68 ms with ito_heun
  at dt = 0.002 and 0.96 against 1.69 ms with leimkuhler_matthews at 0.01,
  ``benchmarks/bench_brownian_step.py``), whether the noise is Cholesky's or Lanczos's
  (``run.noise``; ``"auto"`` is Lanczos above 300 beads): the plugin has both.

A plugin that was built but cannot be used as it is (compiled against another OpenMM than the
one imported, or from older sources: :func:`knotmm.plugin.rebuild_needed`) is worth a warning
whatever ``run.engine`` says: :func:`resolve_engine` logs one line with the command that
rebuilds it (``knotmm run`` prints it). A plugin that was never built, or was switched off,
is silent unless ``run.engine = "plugin"`` asked for it.

Which methods each engine has is :mod:`knotmm.dynamics.registry`'s
(:attr:`~knotmm.dynamics.registry.IntegratorInfo.engines`), checked against the loaded
plugin's own table (:data:`knotmm.plugin.METHODS`).

Both engines take the same steps for deterministic methods (positions equal to 1e-10 d over
1 tau_d on the Reference platform); the Brownian methods use different noise streams with
the same statistics.
"""

from __future__ import annotations

import importlib
import logging
import math

from knotmm.dynamics import registry
from knotmm.errors import ConfigError

__all__ = ["ENGINES", "PLUGIN", "PYTHON", "PLUGIN_PLATFORMS", "make_engine", "resolve_engine"]

log = logging.getLogger(__name__)

PLUGIN = registry.PLUGIN_ENGINE
PYTHON = registry.PYTHON_ENGINE
#: The ``run.engine`` values.
ENGINES = ("auto", PLUGIN, PYTHON)
#: OpenMM platforms the plugin has a kernel for (CPU shares the Reference kernel).
PLUGIN_PLATFORMS = ("Reference", "CPU")
#: Engine name -> (module, class) of its :class:`knotmm.engine.base.Engine`.
_ENGINE_CLASSES = {
    PYTHON: ("knotmm.engine.python_engine", "PythonEngine"),
    PLUGIN: ("knotmm.engine.plugin_engine", "PluginEngine"),
}


def make_engine(name: str, integrator, threads: int = 1, n_beads: int | None = None):
    """The engine called ``name`` for ``integrator`` (a :class:`knotmm.engine.base.Engine`).

    Parameters
    ----------
    name : {"python", "plugin"}
        A resolved engine (:func:`resolve_engine`), not ``"auto"``.
    integrator : knotmm.dynamics.deterministic.Integrator
        The run's integrator.
    threads : int
        Threads of the plugin's RPY pair loop (the Python engine's are the Simulation's).
    n_beads : int, optional
        The chain's size (the plugin resolves ``run.noise = "auto"`` with it).

    Raises
    ------
    ConfigError
        For another ``name``.
    """
    if name not in _ENGINE_CLASSES:
        raise ConfigError(f"engine = {name!r}: expected {PYTHON!r} or {PLUGIN!r}")
    module, cls = _ENGINE_CLASSES[name]
    return getattr(importlib.import_module(module), cls)(integrator, threads=threads,
                                                         n_beads=n_beads)


def resolve_engine(requested: str, integrator: str, peclet: float = math.inf,
                   platform: str = "CPU", noise_method: str = "cholesky") -> str:
    """The engine a run uses: ``"plugin"`` or ``"python"``.

    Parameters
    ----------
    requested : {"auto", "plugin", "python"}
        ``run.engine``.
    integrator : str
        The resolved ``run.integrator`` (a registry name, not ``"auto"``).
    peclet : float
        ``run.peclet``. The plugin runs Brownian and deterministic runs alike, so it does
        not change the choice; kept so callers can pass it.
    platform : str
        The OpenMM platform's name (resolved, not ``"auto"``).
    noise_method : {"cholesky", "lanczos"}
        How a Brownian run's noise is drawn (``run.noise`` resolved for the chain's size,
        :meth:`knotmm.dynamics.noise.NoiseGenerator.method_for`). Both engines draw either
        kind, so it does not change the choice; kept so callers can pass it.

    Returns
    -------
    str
        ``"plugin"`` or ``"python"``. When ``"plugin"`` was asked for and cannot be used, or
        the plugin needs a rebuild (:func:`knotmm.plugin.rebuild_needed`; whatever was
        asked for), one warning (logged, so ``knotmm run`` prints it) says why.
    """
    if requested not in ENGINES:
        raise ConfigError(f"run.engine = {requested!r}: expected one of {', '.join(ENGINES)}")
    import knotmm.plugin as plugin

    if not plugin.available():
        if requested == PLUGIN:
            log.warning("run.engine = \"plugin\": %s; using the Python engine",
                        plugin.load_error())
        elif plugin.rebuild_needed():  # built, but not usable: say so whatever was asked
            log.warning("%s; using the Python engine", plugin.load_error())
        return PYTHON
    if requested == PYTHON:
        return PYTHON
    has_method = _plugin_has(plugin, integrator)
    if requested == PLUGIN:
        if not has_method:
            log.warning("run.engine = \"plugin\": run.integrator = %r has no plugin "
                        "counterpart; using the Python engine", integrator)
            return PYTHON
        if platform not in PLUGIN_PLATFORMS:
            log.warning("run.engine = \"plugin\": the plugin has no kernel for the %s platform "
                        "(only %s); using the Python engine", platform,
                        " and ".join(PLUGIN_PLATFORMS))
            return PYTHON
        return PLUGIN
    if not has_method or platform not in PLUGIN_PLATFORMS:
        return PYTHON
    return PLUGIN


def _plugin_has(plugin, integrator: str) -> bool:
    """The registry gives ``integrator`` a plugin counterpart, and the loaded plugin has it."""
    info = registry.REGISTRY.get(integrator)
    return info is not None and PLUGIN in info.engines and integrator in plugin.METHODS
