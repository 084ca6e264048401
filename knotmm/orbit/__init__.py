"""Periodic orbits of sedimenting knots and their stability (``knotmm orbit``).

The swirling state of a torus knot is a *relative periodic orbit*: after one period ``T`` the
shape repeats up to a fall along gravity and a rotation by ``theta`` about the vertical axis.
This package finds it and says how stable it is:

* :mod:`~knotmm.orbit.flow`: the flow map ``phi_T`` (knotmm's engine, fixed Heun step,
  double precision) and the symmetry operations;
* :mod:`~knotmm.orbit.shooting`: Newton-Krylov shooting for ``(x, T, theta)``;
* :mod:`~knotmm.orbit.floquet`: Floquet multipliers by Arnoldi, the neutral ones apart;
* :mod:`~knotmm.orbit.modes`: what the leading mode looks like (tilt, breathing, ...);
* :mod:`~knotmm.orbit.continuation`: following the orbit along a parameter, bifurcations;
* :mod:`~knotmm.orbit.start`, :mod:`~knotmm.orbit.driver`, :mod:`~knotmm.orbit.output`: from
  a run directory to ``orbit.json``, ``orbit.dcd``, ``mode_1.dcd`` and plots.

Typical use::

    from knotmm.orbit import orbit_of_run
    report = orbit_of_run("runs/trefoil")        # writes runs/trefoil/orbit/
    report.summary["period"], report.summary["leading_exponent"]

``docs/architecture.md`` ("Orbits") gives the equations and the design choices.
"""

from __future__ import annotations

import importlib

# (``floquet`` the function stays in its module: the name is also the submodule's)
__all__ = ["orbit_of_run", "continuation_of_run", "solve_orbit", "make_flow",
           "describe_mode", "Orbit", "FloquetResult"]

_OWNERS = {
    "orbit_of_run": "knotmm.orbit.driver",
    "continuation_of_run": "knotmm.orbit.driver",
    "solve_orbit": "knotmm.orbit.shooting",
    "Orbit": "knotmm.orbit.shooting",
    "FloquetResult": "knotmm.orbit.floquet",
    "make_flow": "knotmm.orbit.flow",
    "describe_mode": "knotmm.orbit.modes",
}


def __getattr__(name: str):
    if name in _OWNERS:
        return getattr(importlib.import_module(_OWNERS[name]), name)
    raise AttributeError(f"module 'knotmm.orbit' has no attribute {name!r}")


def __dir__():
    """The module's names with those imported on first use."""
    return sorted(set(globals()) | set(_OWNERS))
