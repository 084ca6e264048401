"""Where an engine test runs: the Python engine on the Reference platform, and the compiled
plugin on every OpenMM platform it has a kernel on (Reference, CPU, OpenCL here on pocl, CUDA
where a GPU is), asked of OpenMM (``knotmm.engine.engines.plugin_platforms``), never listed.

``@pytest.mark.parametrize(("engine", "platform"), ENGINE_PLATFORMS)`` runs a test once per
such place; a machine without the plugin skips the plugin's with the reason.
"""

from __future__ import annotations

import pytest

import knotmm.plugin as kp
from knotmm.engine.engines import DEVICE_PLATFORMS, plugin_platforms

_PLUGIN = plugin_platforms() if kp.available() else ()
ENGINE_PLATFORMS = [pytest.param("python", "Reference", id="python-Reference")] + (
    [pytest.param("plugin", name, id=f"plugin-{name}") for name in _PLUGIN]
    or [pytest.param("plugin", None, id="plugin",
                     marks=pytest.mark.skip(reason=f"no plugin: {kp.load_error()}"))])


def placement(platform: str) -> dict:
    """Keyword arguments of ``Simulation`` for ``platform``: a device platform in double
    precision (its default, mixed, keeps single-precision forces)."""
    return {"platform": platform, **({"precision": "double"} if platform in DEVICE_PLATFORMS
                                     else {})}


def trajectory_tolerance(platform: str) -> float:
    """How far (d) a few tau_d on ``platform`` may lie from a double-precision reference:
    1e-7 on the Reference platform; the CPU platform computes its forces in single
    precision, and OpenMM's device platforms keep force-field parameters in float32 even in
    double precision (the bond length 0.6 d is 0.6000000238 there), so 5e-6 on those (measured
    over 4 tau_d of three chains: CPU 6.9e-7 d, OpenCL 1.6e-6 d)."""
    return 1e-7 if platform == "Reference" else 5e-6


def engine_velocity(x, engine: str, platform: str, **simulation_kwargs):
    """The velocity (d/tau_d, shape (n, 3)) at ``x`` of a ``Simulation`` on ``engine`` and
    ``platform``, and the relative tolerance it has against a double-precision reference.

    The Python engine gives it directly (1e-9); the plugin takes one Euler step of 1e-7 tau_d:
    displacement / h, the forces changing by O(h) over it, and single-precision forces on the
    CPU platform and float32 parameters on the device platforms (1e-4).
    """
    from knotmm.dynamics.deterministic import Euler
    from knotmm.engine.simulation import Simulation

    h = 1e-7
    sim = Simulation(x, engine=engine, integrator=Euler(h), **placement(platform),
                     **simulation_kwargs)
    if engine == "python":
        return sim.velocity(x), 1e-9
    sim.step(1)
    return (sim.positions - x) / h, 1e-4
