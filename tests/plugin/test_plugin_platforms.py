"""The plugin on every device platform it has a kernel on (OpenCL here on pocl, CUDA where a GPU
is lent), against independent references.

Each test runs once per device platform where :func:`knotmm.engine.engines.plugin_platforms`
finds the plugin's kernel, and is skipped with the reason where there is none. The references
are the naive model of ``tests/reference_model.py`` (forces and the RPY tensor as double loops)
and knotmm's Python engine on the double-precision Reference platform (the numba mobility and
the integrators of :mod:`knotmm.dynamics`): never the device backend itself. OpenMM compiles
device kernels with fast-math flags, so agreement is to a tolerance, not bit for bit. OpenMM's
device platforms also store force-field parameters as float32 even in double precision (the
bond length 0.6 d is 0.6000000238 there: a bond force 1.8e-7 F0 off), so "double" agrees with
the Reference platform to about 1e-6 d over a few tau_d, not to rounding
(``plugin/tests/TestRPYDevice.cpp`` compares with float-rounded parameters: 1e-9 d).
"""

from __future__ import annotations

import numpy as np
import openmm
import pytest
import reference_model as rm
from plugin_helpers import positions_of

from knotmm.dynamics.brownian import EulerMaruyama
from knotmm.dynamics.deterministic import RK23, Euler
from knotmm.engine.engines import DEVICE_PLATFORMS, plugin_platforms
from knotmm.engine.simulation import Simulation
from knotmm.model.layout import ChainLayout
from knotmm.model.system import ChainModel, chain_system
from knotmm.plugin import RPYIntegrator
from knotmm.shapes import torus_knot

DEVICES = [name for name in plugin_platforms() if name in DEVICE_PLATFORMS]
NO_DEVICE = ("no device platform has the plugin's kernel here (OpenCL: install pocl-opencl-icd, "
             "opencl-headers and ocl-icd-opencl-dev, then reinstall knotmm; knotmm --version "
             "says why a platform's library did not load)")
device = pytest.mark.parametrize(
    "platform", [pytest.param(n, id=n) for n in DEVICES]
    or [pytest.param(None, marks=pytest.mark.skip(reason=NO_DEVICE), id="none")])

CHAINS = [(12, True), (10, True), (8, False)]
LAYOUT = ChainLayout(tuple(n for n, _ in CHAINS), tuple(c for _, c in CHAINS))


def three_chains(seed=7) -> np.ndarray:
    """Two rings and an open rod within the steric range of each other, beads 0.6 d apart (so
    every bond is inside the RPY overlap branch r < d)."""
    rng = np.random.default_rng(seed)
    a = rm.circle(12)
    b = rm.circle(10) + [2.1, 0.0, 0.35]
    rod = np.c_[np.zeros(8), 0.6 * np.arange(8) - 2.1, np.full(8, -0.45)]
    return np.vstack([a, b, rod]) + rng.normal(scale=0.03, size=(30, 3))


def reference_run(x, integrator, times, layout=None, model=None):
    """The Python engine on the Reference platform, landing on each of ``times``."""
    sim = Simulation(x, model=model, integrator=integrator, platform="Reference",
                     engine="python", layout=layout)
    for t in times:
        sim.run(t - sim.time)
    return sim


def device_run(x, integrator, times, platform, precision, layout=None, model=None):
    sim = Simulation(x, model=model, integrator=integrator, platform=platform,
                     engine="plugin", layout=layout, precision=precision)
    assert sim.engine == "plugin" and sim.platform_name == platform
    for t in times:
        sim.run(t - sim.time)
    return sim


@device
@pytest.mark.parametrize(("precision", "tol"), [("double", 1e-6), ("mixed", 1e-4)])
def test_velocity_is_the_naive_rpy_times_the_naive_forces(platform, precision, tol):
    """One Euler step of 1e-6 tau_d: displacement / h is mu(x) F(x) of the naive model (three
    chains, bonds and contacts inside the overlap branch)."""
    x = three_chains()
    want = rm.rpy_velocities(x, rm.forces(x, CHAINS)["total"])
    h = 1e-6
    sim = device_run(x, Euler(h), [h], platform, precision, layout=LAYOUT)
    got = (sim.positions - x) / h
    scale = np.abs(want).max()
    np.testing.assert_allclose(got, want, rtol=0, atol=tol * scale)


@device
@pytest.mark.parametrize(("system", "precision", "tolerance", "atol"), [
    ("trefoil90", "double", 1e-4, 5e-6),
    ("three_chains", "double", 1e-4, 5e-6),
    ("trefoil90", "mixed", 1e-6, 1e-5),
])
def test_rk23_follows_the_python_engine_over_four_tau_d(platform, system, precision,
                                                         tolerance, atol):
    if system == "trefoil90":
        x, layout = torus_knot(2, 3, 90), None
    else:
        x, layout = three_chains(), LAYOUT
    times = [1.0, 2.0, 3.0, 4.0]
    want = reference_run(x, RK23(0.01, tolerance=tolerance), times, layout)
    got = device_run(x, RK23(0.01, tolerance=tolerance), times, platform, precision, layout)
    assert got.time == 4.0  # landed exactly on the last frame time
    state_time = got.context.getState().getTime().value_in_unit(openmm.unit.picosecond)
    assert state_time == 4.0
    np.testing.assert_allclose(got.positions, want.positions, rtol=0, atol=atol)
    assert np.abs(want.positions - x).max() > 1.0  # it fell: the comparison means something


@device
@pytest.mark.parametrize("precision", ["mixed", "double"])
def test_a_chain_far_from_the_origin_moves_as_one_at_the_origin(platform, precision):
    """The state is held in double: 1e4 d away, the chain's motion is that at the origin (to
    the tolerance of the comparison of the Python engine on Reference, run at the origin)."""
    x = torus_knot(2, 3, 40)
    offset = np.array([1e4, -1e4, 1e4])
    times = [0.5, 1.0]
    want = reference_run(x, RK23(0.01), times)
    got = device_run(x + offset, RK23(0.01), times, platform, precision)
    np.testing.assert_allclose(got.positions - offset, want.positions, rtol=0, atol=1e-5)


@device
def test_segment_midpoint_sites_follow_the_python_engine(platform):
    """``segment_repulsion``: virtual sites at bond midpoints, placed by OpenMM on the device."""
    x = three_chains()
    model = ChainModel(segment_repulsion=True)
    times = [0.5, 1.0]
    want = reference_run(x, RK23(0.01), times, LAYOUT, model)
    got = device_run(x, RK23(0.01), times, platform, "double", LAYOUT, model)
    np.testing.assert_allclose(got.positions, want.positions, rtol=0, atol=5e-6)
    # the Context's sites sit at the midpoints of the layout's bonds
    everything = positions_of(got.context)
    sites = everything[x.shape[0]:]
    beads = everything[: x.shape[0]]
    bonds = LAYOUT.bonds()
    np.testing.assert_allclose(sites, 0.5 * (beads[bonds[:, 0]] + beads[bonds[:, 1]]),
                               rtol=0, atol=1e-6)


def _brownian(platform, properties, x, steps, seed=11):
    integrator = RPYIntegrator(0.001, "euler_maruyama", kT=1.0, seed=seed)
    context = openmm.Context(chain_system(x, ChainModel()), integrator,
                             openmm.Platform.getPlatformByName(platform), properties)
    context.setPositions(x)
    integrator.step(steps)
    return positions_of(context)


@device
def test_brownian_steps_agree_with_the_reference_platform_to_rounding(platform):
    """Euler-Maruyama, seed 11, 100 steps at kT = 1 F0 d: the noise is drawn from the same
    stream on every platform, so the paths agree but for the float32 parameters (1e-7 d)."""
    x = torus_knot(2, 3, 40)
    want = _brownian("Reference", {}, x, 100)
    got = _brownian(platform, {"Precision": "double"}, x, 100)
    assert np.abs(want - x).max() > 0.05  # the noise moved the beads
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-7)


@device
def test_brownian_run_through_the_simulation_lands_on_its_frames(platform):
    x = torus_knot(2, 3, 40)
    sim = device_run(x, EulerMaruyama(0.003, peclet=1.0, seed=3), [0.1, 0.2], platform, "mixed")
    assert sim.time == 0.2
    assert np.isfinite(sim.positions).all()
    bonds = np.linalg.norm(np.diff(np.vstack([sim.positions, sim.positions[:1]]), axis=0),
                           axis=1)
    assert 0.3 < bonds.min() and bonds.max() < 1.5  # 1.016 on Reference too, for this seed
