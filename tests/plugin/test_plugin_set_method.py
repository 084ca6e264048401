"""``RPYIntegrator.setMethod`` in a Context (issue 31): a switched integrator steps exactly as
one built with that method.

Two Contexts of the same T(2,3) chain (40 beads, bending stiffness 50: rkc2 takes many
stages) on the Reference platform: one made with the method, one made with another method,
stepped or asked for its stiffness, then switched. Their positions, times and counters must
be equal bit for bit after the same stretch.
"""

from __future__ import annotations

import numpy as np
import openmm
import pytest
from plugin_helpers import plugin_context, positions_of

from knotmm.model.parameters import ChainModel
from knotmm.model.system import chain_system
from knotmm.plugin import RPYIntegrator
from knotmm.shapes import torus_knot


@pytest.fixture(scope="module")
def chain():
    x = torus_knot(2, 3, 40)
    return x, chain_system(x, ChainModel(bending_stiffness=50.0))


def _counts(integ):
    return (integ.getNumAcceptedSteps(), integ.getNumRejectedSteps(),
            integ.getNumForceEvaluations())


@pytest.mark.parametrize("before", ["nothing", "probe", "steps"])
def test_a_switched_integrator_steps_as_one_built_with_the_method(chain, before):
    x, system = chain
    built = RPYIntegrator(0.01, "rkc2", 1e-4)
    ctx_built = plugin_context(system, x, built)
    switched = RPYIntegrator(0.01, "rk23", 1e-4)
    ctx_switched = plugin_context(system, x, switched)
    if before == "probe":
        switched.estimateSpectralRadius()
    elif before == "steps":  # steps taken: the switch starts the stepper afresh from here
        switched.step(3)
        ctx_switched.setTime(0.0)
        switched.setStepSize(0.01)  # the step rk23 adapted stays, as any setting: reset it
        ctx_built.setPositions(positions_of(ctx_switched))
    switched.setMethod("rkc2")
    assert switched.getMethod() == "rkc2" and switched.isAdaptive()
    assert _counts(switched) == (0, 0, 0)
    built.stepTo(0.5)
    switched.stepTo(0.5)
    assert _counts(switched) == _counts(built)
    assert switched.getNumAcceptedSteps() > 3 and built.getLastStages() > 2  # rkc2 worked
    assert switched.getLastStages() == built.getLastStages()
    assert switched.getSpectralRadius() == built.getSpectralRadius()
    np.testing.assert_array_equal(positions_of(ctx_switched), positions_of(ctx_built))
    assert np.abs(positions_of(ctx_built) - x).max() > 1e-3  # it moved


def test_the_first_step_is_clipped_as_when_a_context_is_made(chain):
    """An adaptive method never starts above its largest step (as ``initialize`` does)."""
    x, system = chain
    integ = RPYIntegrator(0.5, "heun")
    integ.setMaximumStepSize(0.02)
    ctx = plugin_context(system, x, integ)  # noqa: F841 - kept alive: the integrator lives in it
    assert integ.getStepSize().value_in_unit(openmm.unit.picosecond) == 0.5  # fixed: kept
    integ.setMethod("rk23")
    assert integ.getStepSize().value_in_unit(openmm.unit.picosecond) == 0.02


def test_bad_switches_are_refused_and_change_nothing(chain):
    x, system = chain
    integ = RPYIntegrator(0.001, "ito_heun", kT=0.5, seed=3)
    ctx = plugin_context(system, x, integ)  # noqa: F841 - kept alive: the integrator lives in it
    with pytest.raises(openmm.OpenMMException, match="rk5"):
        integ.setMethod("rk5")
    with pytest.raises(openmm.OpenMMException, match="deterministic"):
        integ.setMethod("rk23")
    assert integ.getMethod() == "ito_heun"
    integ.step(2)
    assert integ.getNumAcceptedSteps() == 2


def test_a_brownian_switch_draws_the_noise_of_a_fresh_integrator(chain):
    """The noise stream is seeded again: the same seed gives the same steps."""
    x, system = chain
    built = RPYIntegrator(0.001, "ito_heun_adaptive", 0.02, kT=0.5, seed=7)
    ctx_built = plugin_context(system, x, built)
    switched = RPYIntegrator(0.001, "ito_heun", 0.02, kT=0.5, seed=7)
    ctx_switched = plugin_context(system, x, switched)
    switched.step(2)
    ctx_switched.setPositions(x)
    ctx_switched.setTime(0.0)
    switched.setStepSize(0.001)
    switched.setMethod("ito_heun_adaptive")
    built.stepTo(0.05)
    switched.stepTo(0.05)
    assert _counts(switched) == _counts(built)
    np.testing.assert_array_equal(positions_of(ctx_switched), positions_of(ctx_built))
