"""Which engine integrates a run: the compiled plugin or the Python integrators.

``run.engine`` (``docs/architecture.md``, "The engine in one loop"):

* ``"python"``: the integrators of :mod:`knotmm.dynamics`, stepped from Python (the
  readable reference);
* ``"plugin"``: :class:`knotmm.plugin.RPYIntegrator`, which takes every step in C++ up to the
  next report time; if the plugin is not built (or cannot load), one warning names
  :func:`knotmm.plugin.load_error` and the run uses the Python engine;
* ``"auto"`` (the default): the plugin when it is available, silently the Python engine
  otherwise, and for GPU platforms, where the plugin has no kernel. Brownian runs take the
  plugin too (its Cholesky is LAPACK's, as the Python engine's, and its step has no Python
  round trips: T(2,3), N = 90, Pe = 2, CPU time per step 1.12 against 1.68 ms with ito_heun
  at dt = 0.002 and 0.96 against 1.69 ms with leimkuhler_matthews at 0.01,
  ``benchmarks/bench_brownian_step.py``), whether the noise is Cholesky's or Lanczos's
  (``run.noise``; ``"auto"`` is Lanczos above 300 beads): the plugin has both.

Both engines take the same steps for deterministic methods (positions equal to 1e-10 d over
1 tau_d on the Reference platform); the Brownian methods use different noise streams with
the same statistics.
"""

from __future__ import annotations

import logging
import math

from knotmm.errors import ConfigError

__all__ = ["ENGINES", "PLUGIN", "PYTHON", "PLUGIN_PLATFORMS", "resolve_engine"]

log = logging.getLogger(__name__)

PLUGIN = "plugin"
PYTHON = "python"
#: The ``run.engine`` values.
ENGINES = ("auto", PLUGIN, PYTHON)
#: OpenMM platforms the plugin has a kernel for (CPU shares the Reference kernel).
PLUGIN_PLATFORMS = ("Reference", "CPU")


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
        ``"plugin"`` or ``"python"``. When ``"plugin"`` was asked for and cannot be used, one
        warning (logged, so ``knotmm run`` prints it) says why.
    """
    if requested not in ENGINES:
        raise ConfigError(f"run.engine = {requested!r}: expected one of {', '.join(ENGINES)}")
    if requested == PYTHON:
        return PYTHON
    import knotmm.plugin as plugin

    if requested == PLUGIN:
        if not plugin.available():
            log.warning("run.engine = \"plugin\": %s; using the Python engine",
                        plugin.load_error())
            return PYTHON
        if integrator not in plugin.METHODS:
            log.warning("run.engine = \"plugin\": run.integrator = %r has no plugin "
                        "counterpart; using the Python engine", integrator)
            return PYTHON
        if platform not in PLUGIN_PLATFORMS:
            log.warning("run.engine = \"plugin\": the plugin has no kernel for the %s platform "
                        "(only %s); using the Python engine", platform,
                        " and ".join(PLUGIN_PLATFORMS))
            return PYTHON
        return PLUGIN
    if (not plugin.available() or integrator not in plugin.METHODS
            or platform not in PLUGIN_PLATFORMS):
        return PYTHON
    return PLUGIN
