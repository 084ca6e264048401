"""Which engine integrates a run: the compiled plugin or the Python integrators.

``run.engine`` (``docs/architecture.md``, "The engine in one loop"):

* ``"python"``: the integrators of :mod:`knotmm.dynamics`, stepped from Python (the
  readable reference);
* ``"plugin"``: :class:`knotmm.plugin.RPYIntegrator`, which takes every step in C++ up to the
  next report time; if the plugin is not built (or cannot load), one warning names
  :func:`knotmm.plugin.load_error` and the run uses the Python engine;
* ``"auto"`` (the default): the plugin when it is available, silently the Python engine
  otherwise, and the Python engine for Brownian runs (a Brownian integrator at finite
  ``run.peclet``): there a plugin step costs more than a Python one (dense Cholesky noise in
  both; ito_heun at N = 90, dt = 0.002, medians of 5 x 400 steps: 1.94 against 1.21, 2.12
  against 1.64 and 2.17 against 1.62 ms a step on the shared 2-core development machine),
  and for GPU platforms, where the plugin has no kernel.

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
                   platform: str = "CPU") -> str:
    """The engine a run uses: ``"plugin"`` or ``"python"``.

    Parameters
    ----------
    requested : {"auto", "plugin", "python"}
        ``run.engine``.
    integrator : str
        The resolved ``run.integrator`` (a registry name, not ``"auto"``).
    peclet : float
        ``run.peclet``; a Brownian integrator at a finite value makes a Brownian run.
    platform : str
        The OpenMM platform's name (resolved, not ``"auto"``).

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
    brownian = integrator in plugin.METHODS and plugin.METHODS[integrator][2]
    if (not plugin.available() or integrator not in plugin.METHODS
            or platform not in PLUGIN_PLATFORMS or (brownian and math.isfinite(peclet))):
        return PYTHON
    return PLUGIN
