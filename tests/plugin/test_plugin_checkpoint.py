"""Checkpoints restore a plugin run exactly: positions, adaptive step, counters, noise."""

from __future__ import annotations

import numpy as np
import pytest
from plugin_helpers import plugin_context, positions_of

from knotmm.model.system import chain_system as build_system
from knotmm.plugin import RPYIntegrator
from knotmm.shapes import torus_knot


def counters(integ):
    step = integ.getStepSize()
    return (integ.getNumForceEvaluations(), integ.getNumAcceptedSteps(),
            integ.getNumRejectedSteps(), step.value_in_unit(step.unit))


@pytest.mark.parametrize(("method", "kwargs"), [
    ("rk23", {}),
    ("rkc2", {}),
    ("heun", {}),
    ("ito_heun", {"kT": 0.5, "seed": 11}),
    ("euler_maruyama", {"kT": 0.5, "seed": 12}),
    ("leimkuhler_matthews", {"kT": 0.5, "seed": 13}),
])
@pytest.mark.parametrize("platform", ["Reference", "CPU"])
def test_checkpoint_round_trip_is_bit_identical(method, kwargs, platform):
    x = torus_knot(2, 3, 40)
    step = 0.002 if method in ("ito_heun", "euler_maruyama") else 0.01  # LM: 0.01 as its default
    integ = RPYIntegrator(step, method, **kwargs)
    ctx = plugin_context(build_system(x), x, integ, platform)
    integ.stepTo(0.2)
    saved = ctx.createCheckpoint()
    saved_counters = counters(integ)
    integ.stepTo(0.4)
    first = positions_of(ctx)
    first_counters = counters(integ)
    assert np.abs(first - x).max() > 0.5

    ctx.loadCheckpoint(saved)
    assert counters(integ) == saved_counters
    integ.stepTo(0.4)
    np.testing.assert_array_equal(positions_of(ctx), first)
    assert counters(integ) == first_counters


def test_checkpoint_into_a_fresh_context():
    """A checkpoint loads into a new Context with a new integrator (a restarted program)."""
    x = torus_knot(2, 3, 40)
    system = build_system(x)
    a = RPYIntegrator(0.01, "rk23")
    ctx_a = plugin_context(system, x, a)
    a.stepTo(0.3)
    saved = ctx_a.createCheckpoint()
    a.stepTo(0.6)

    b = RPYIntegrator(0.01, "rk23")
    ctx_b = plugin_context(system, x, b)
    ctx_b.loadCheckpoint(saved)
    b.stepTo(0.6)
    np.testing.assert_array_equal(positions_of(ctx_b), positions_of(ctx_a))
    assert counters(b) == counters(a)


def test_noise_depends_on_seed_only():
    x = torus_knot(2, 3, 40)
    runs = []
    for seed in (5, 5, 6):
        integ = RPYIntegrator(0.002, "euler_maruyama", kT=1.0, seed=seed)
        ctx = plugin_context(build_system(x), x, integ)
        integ.step(20)
        runs.append(positions_of(ctx))
    np.testing.assert_array_equal(runs[0], runs[1])
    assert np.abs(runs[0] - runs[2]).max() > 1e-3


def test_positions_set_from_outside_are_used():
    """setPositions between steps drops the cached velocity (FSAL) of rk23."""
    x = torus_knot(2, 3, 40)
    system = build_system(x)
    a = RPYIntegrator(0.01, "rk23")
    ctx = plugin_context(system, x, a)
    a.step(5)
    ctx.setPositions(x)  # back to the start: the cached velocity belongs to step 5's end
    evaluations = a.getNumForceEvaluations()
    h = a.getStepSize()
    a.step(1)
    assert a.getNumForceEvaluations() == evaluations + 4  # k1 recomputed, then k2, k3, k4
    b = RPYIntegrator(h, "rk23")  # a fresh run from x with the same step
    ctx_b = plugin_context(system, x, b)
    b.step(1)
    np.testing.assert_allclose(positions_of(ctx), positions_of(ctx_b), rtol=0, atol=1e-13)
