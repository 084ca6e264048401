"""Bad arguments and failed steps: clear errors, and the last good state is kept."""

from __future__ import annotations

import numpy as np
import openmm
import pytest
from openmm import unit
from plugin_helpers import plugin_context, positions_of

from knotmm.model.system import chain_system as build_system
from knotmm.plugin import RPYIntegrator
from knotmm.shapes import torus_knot


@pytest.fixture(scope="module")
def chain():
    return torus_knot(2, 3, 40)


def test_step_below_minimum_raises_and_keeps_state(chain):
    integ = RPYIntegrator(0.5, "rk23", error_tolerance=1e-9, min_step=0.1)
    ctx = plugin_context(build_system(chain), chain, integ)
    with pytest.raises(openmm.OpenMMException, match="below minimumStepSize"):
        integ.step(1)
    np.testing.assert_array_equal(positions_of(ctx), chain)
    assert ctx.getState().getStepCount() == 0
    assert integ.getNumRejectedSteps() == 2


@pytest.mark.parametrize(("args", "kwargs", "match"), [
    ((0.01, "verlet"), {}, "method='verlet'"),
    ((-0.01,), {}, "step"),
    ((0.01, "rk23", 0.0), {}, "errorTolerance"),
    ((0.01, "heun"), {"kT": 1.0}, "deterministic"),
    ((0.01,), {"bead_diameter": -1.0}, "beadDiameter"),
])
def test_bad_arguments(args, kwargs, match):
    with pytest.raises((ValueError, openmm.OpenMMException), match=match):
        RPYIntegrator(*args, **kwargs)


def test_settings_fixed_once_bound(chain):
    integ = RPYIntegrator(0.01)
    plugin_context(build_system(chain), chain, integ)
    for setter, value in ((integ.setBeadDiameter, 2.0), (integ.setMobility, 2.0),
                          (integ.setRandomNumberSeed, 3)):
        with pytest.raises(openmm.OpenMMException, match="before the Context"):
            setter(value)


def test_quantities_are_accepted(chain):
    integ = RPYIntegrator(0.01 * unit.picosecond, "rk23", 1e-4 * unit.nanometer)
    ctx = plugin_context(build_system(chain), chain, integ)
    integ.stepTo(0.25 * unit.picosecond)
    assert ctx.getState().getTime() == 0.25 * unit.picosecond
    assert integ.getErrorTolerance() == 1e-4


def test_periodic_system_is_refused(chain):
    system = build_system(chain)
    system.setDefaultPeriodicBoxVectors(*(np.eye(3) * 50.0))
    steric = next(f for f in system.getForces() if isinstance(f, openmm.NonbondedForce))
    steric.setNonbondedMethod(openmm.NonbondedForce.CutoffPeriodic)
    with pytest.raises(openmm.OpenMMException, match="periodic"):
        plugin_context(system, chain, RPYIntegrator(0.01))
