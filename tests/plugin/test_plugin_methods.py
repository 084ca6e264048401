"""Each deterministic method of the plugin against knotmm's Python engine, and its order.

Both engines run the T(2,3) chain of 40 beads on OpenMM's Reference platform (float64 forces)
from the same template; the Python engine is :class:`knotmm.engine.simulation.Simulation` with the
integrators of :mod:`knotmm.dynamics.deterministic` and the numba mobility of
:mod:`knotmm.dynamics.mobility`.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from plugin_helpers import plugin_context, positions_of

from knotmm.dynamics.deterministic import RK23, RKC2, Euler, Heun, Midpoint
from knotmm.engine.simulation import Simulation
from knotmm.model.system import chain_system as build_system
from knotmm.plugin import RPYIntegrator
from knotmm.shapes import torus_knot


@pytest.fixture(scope="module")
def chain():
    return torus_knot(2, 3, 40)


def python_run(x, integrator, times):
    sim = Simulation(x, integrator=integrator, platform="Reference")
    for t in times:
        sim.run(t - sim.time)
    return sim


def plugin_run(x, method, h, times, platform="Reference", **kwargs):
    integ = RPYIntegrator(h, method, **kwargs)
    ctx = plugin_context(build_system(x), x, integ, platform)
    for t in times:
        integ.stepTo(t)
    return integ, ctx


@pytest.mark.parametrize(("method", "cls"), [("euler", Euler), ("heun", Heun),
                                              ("midpoint", Midpoint)])
def test_fixed_step_matches_python_engine(chain, method, cls):
    # 0.013 does not divide 1: the last step is shortened to land on t = 1 tau_d
    sim = python_run(chain, cls(0.013), [1.0])
    integ, ctx = plugin_run(chain, method, 0.013, [1.0])
    state = ctx.getState()
    assert state.getStepCount() == sim.currentStep == 77
    assert state.getTime().value_in_unit(state.getTime().unit) == sim.time == 1.0
    assert integ.getNumForceEvaluations() == sim.n_evaluations
    np.testing.assert_allclose(positions_of(ctx), sim.positions, rtol=0, atol=1e-10)
    assert np.abs(sim.positions - chain).max() > 1.0  # it moved: the comparison means something


def test_rk23_matches_python_engine(chain):
    # four legs: each lands exactly, as frames of a run do
    times = [0.25, 0.5, 0.75, 1.0]
    sim = python_run(chain, RK23(0.01), times)
    integ, ctx = plugin_run(chain, "rk23", 0.01, times)
    assert integ.getNumAcceptedSteps() == sim.integrator.n_accepted == sim.currentStep
    assert integ.getNumRejectedSteps() == sim.integrator.n_rejected
    assert integ.getNumForceEvaluations() == sim.n_evaluations
    assert integ.getStepSize().value_in_unit(integ.getStepSize().unit) == pytest.approx(
        sim.integrator.timestep, rel=1e-12)
    np.testing.assert_allclose(positions_of(ctx), sim.positions, rtol=0, atol=1e-10)


def test_rk23_rejections_match(chain):
    """A too-large first step is rejected and shrunk the same way in both engines."""
    sim = python_run(chain, RK23(0.5, tolerance=1e-6), [1.0])
    integ, ctx = plugin_run(chain, "rk23", 0.5, [1.0], error_tolerance=1e-6)
    assert sim.integrator.n_rejected > 0
    assert integ.getNumRejectedSteps() == sim.integrator.n_rejected
    assert integ.getNumAcceptedSteps() == sim.integrator.n_accepted
    np.testing.assert_allclose(positions_of(ctx), sim.positions, rtol=0, atol=1e-10)


def test_rkc2_matches_python_engine(chain):
    # the power iteration starts from the same vector in both engines
    start = np.random.default_rng(3).standard_normal(chain.shape)
    py = RKC2(0.01)
    py.set_state({**py.get_state(), "eigenvector": start.tolist()})
    sim = python_run(chain, py, [0.5, 1.0])
    integ = RPYIntegrator(0.01, "rkc2")
    integ.setSpectralRadiusStartVector(start)
    ctx = plugin_context(build_system(chain), chain, integ)
    integ.stepTo(0.5)
    integ.stepTo(1.0)
    assert integ.getNumAcceptedSteps() == py.n_accepted
    assert integ.getNumRejectedSteps() == py.n_rejected
    assert integ.getNumForceEvaluations() == sim.n_evaluations
    assert integ.getLastStages() == py.last_stages
    assert integ.getSpectralRadius() == pytest.approx(py.rho, rel=1e-9)
    np.testing.assert_allclose(positions_of(ctx), sim.positions, rtol=0, atol=1e-10)


def scipy_reference(x, t_end):
    """A tight DOP853 solution driven by the Python engine's velocities (not the plugin's)."""
    from scipy.integrate import solve_ivp

    sim = Simulation(x, platform="Reference")
    sol = solve_ivp(lambda t, y: sim.velocity(y.reshape(-1, 3)).reshape(-1), (0.0, t_end),
                    x.reshape(-1), method="DOP853", rtol=1e-12, atol=1e-12)
    assert sol.success
    return sol.y[:, -1].reshape(-1, 3)


@pytest.fixture(scope="module")
def reference(chain):
    return scipy_reference(chain, 0.4)


@pytest.mark.parametrize(("method", "order"), [("heun", 2), ("midpoint", 2), ("euler", 1),
                                               ("rk23", 3)])
def test_convergence_order(chain, reference, method, order):
    errors = []
    steps = [0.02, 0.01, 0.005]
    for h in steps:
        if method == "rk23":
            # a huge tolerance and max_step = h make rk23 a fixed-step third-order method
            integ, ctx = plugin_run(chain, method, h, [0.4], error_tolerance=1e3, max_step=h)
            assert integ.getNumAcceptedSteps() == round(0.4 / h)
        else:
            integ, ctx = plugin_run(chain, method, h, [0.4])
        errors.append(np.abs(positions_of(ctx) - reference).max())
    rates = [math.log2(errors[i] / errors[i + 1]) for i in range(len(errors) - 1)]
    assert all(abs(r - order) < 0.25 for r in rates), (errors, rates)


def test_rk23_global_error_follows_tolerance(chain, reference):
    """rk23's global error (largest coordinate error) falls with its tolerance and stays
    within a small multiple of it (knotmm measured 0.3-0.6x on its test problem)."""
    errors = []
    for tol in (1e-5, 1e-7, 1e-9):
        integ, ctx = plugin_run(chain, "rk23", 0.01, [0.4], error_tolerance=tol)
        errors.append(np.abs(positions_of(ctx) - reference).max())
        assert errors[-1] < 3 * tol
    assert errors[0] > 10 * errors[1] > 100 * errors[2]


def test_virtual_sites_match_python_engine(chain):
    """segment_repulsion: bond midpoints are OpenMM virtual sites; only beads move."""
    from knotmm.model.layout import ChainLayout
    from knotmm.model.system import ChainModel, site_positions

    model, ring = ChainModel(segment_repulsion=True), ChainLayout.ring(40)
    sim = Simulation(chain, model=model, integrator=RK23(0.01), platform="Reference")
    sim.run(0.5)
    integ = RPYIntegrator(0.01, "rk23")
    ctx = plugin_context(build_system(chain, model), site_positions(chain, model, ring), integ)
    integ.stepTo(0.5)
    pos = positions_of(ctx)
    assert pos.shape == (80, 3)
    assert integ.getNumForceEvaluations() == sim.n_evaluations
    np.testing.assert_allclose(pos[:40], sim.positions, rtol=0, atol=1e-10)
    # the sites sit at the bond midpoints of the new positions
    np.testing.assert_allclose(pos[40:], site_positions(pos[:40], model, ring)[40:], atol=1e-12)


def test_from_python_integrator(chain):
    """The converted integrator takes the Python engine's steps (rk23 with its settings)."""
    from knotmm.dynamics.brownian import ItoHeun
    from knotmm.plugin import from_python_integrator

    py = RK23(0.02, tolerance=1e-5, max_timestep=0.04, min_timestep=1e-6)
    integ = from_python_integrator(py)
    assert (integ.getMethod(), integ.getErrorTolerance(), integ.getMaximumStepSize(),
            integ.getMinimumStepSize()) == ("rk23", 1e-5, 0.04, 1e-6)
    sim = python_run(chain, py, [0.5])
    ctx = plugin_context(build_system(chain), chain, integ)
    integ.stepTo(0.5)
    np.testing.assert_allclose(positions_of(ctx), sim.positions, rtol=0, atol=1e-10)

    brownian = from_python_integrator(ItoHeun(0.002, peclet=4.0, seed=3))
    assert brownian.getMethod() == "ito_heun"
    assert brownian.getThermalEnergy() == 0.25
    assert brownian.getRandomNumberSeed() == 4


def test_estimate_spectral_radius_changes_nothing_and_matches_the_python_power_iteration():
    """``RPYIntegrator.estimateSpectralRadius`` on an rk23 Context (the run's, as ``auto``
    asks it): the number a fresh rkc2 makes before its first try (one taken small enough to
    be accepted, so no rejection re-estimates it), within 10 % of knotmm's Python power
    iteration (its own start vector), and no trace: positions, counters and the next steps
    are those of a Context never asked."""
    from knotmm.model.system import ChainModel

    x = torus_knot(2, 3, 40)
    model = ChainModel(bending_stiffness=50.0)
    asked = RPYIntegrator(0.01, "rk23")
    ctx = plugin_context(build_system(x, model), x, asked)
    rho = asked.estimateSpectralRadius()
    assert np.array_equal(positions_of(ctx), x)
    assert asked.getNumForceEvaluations() == 0 and asked.getNumAcceptedSteps() == 0
    probe = RPYIntegrator(1e-6, "rkc2")
    probe_ctx = plugin_context(build_system(x, model), x, probe)
    probe.step(1)
    assert probe.getNumRejectedSteps() == 0
    assert rho == probe.getSpectralRadius()
    del probe_ctx
    python = Simulation(x, model=model, integrator=RK23(0.01), platform="Reference").stiffness()
    assert rho == pytest.approx(python, rel=0.1)
    asked.stepTo(1.0)
    plain = RPYIntegrator(0.01, "rk23")
    ctx2 = plugin_context(build_system(x, model), x, plain)
    plain.stepTo(1.0)
    np.testing.assert_array_equal(positions_of(ctx), positions_of(ctx2))
    assert asked.getNumForceEvaluations() == plain.getNumForceEvaluations()
