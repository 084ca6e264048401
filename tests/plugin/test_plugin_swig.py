"""The plugin's Python face: casts, step faults as data, stepTo's arguments, the method table."""

from __future__ import annotations

import math
import pickle

import numpy as np
import openmm
import openmm.app as app
import pytest
from plugin_helpers import plugin_context

import knotmm.plugin as kp
from knotmm.model.system import ChainModel, chain_system
from knotmm.model.topology import bead_topology
from knotmm.shapes.geometry import torus_knot

SETTINGS = dict(error_tolerance=3e-5, kT=0.25, seed=11, min_step=2e-6, max_step=0.3, threads=2,
                noise="lanczos", lanczos_tolerance=1e-5, noise_precision="single")


def _configured():
    integ = kp.RPYIntegrator(0.004, "leimkuhler_matthews", SETTINGS["error_tolerance"],
                             kT=SETTINGS["kT"], seed=SETTINGS["seed"])
    integ.setMinimumStepSize(SETTINGS["min_step"])
    integ.setMaximumStepSize(SETTINGS["max_step"])
    integ.setNumThreads(SETTINGS["threads"])
    integ.setNoiseMethod(SETTINGS["noise"])
    integ.setLanczosTolerance(SETTINGS["lanczos_tolerance"])
    integ.setNoisePrecision(SETTINGS["noise_precision"])
    integ.setBeadDiameter(1.5)
    integ.setMobility(0.5)
    return integ


def _settings(integ):
    return (integ.getMethod(), integ.getStepSize().value_in_unit(openmm.unit.picosecond),
            integ.getErrorTolerance(), integ.getThermalEnergy(), integ.getRandomNumberSeed(),
            integ.getMinimumStepSize(), integ.getMaximumStepSize(), integ.getNumThreads(),
            integ.getNoiseMethod(), integ.getLanczosTolerance(), integ.getNoisePrecision(),
            integ.getBeadDiameter(), integ.getMobility())


@pytest.mark.parametrize("how", ["deserialize", "clone"])
def test_xml_round_trip_gives_back_the_class_and_every_setting(how):
    original = _configured()
    if how == "deserialize":
        copy = openmm.XmlSerializer.deserialize(openmm.XmlSerializer.serialize(original))
    else:
        copy = openmm.XmlSerializer.clone(original)
    assert type(copy) is kp.RPYIntegrator
    assert _settings(copy) == _settings(original)
    del original  # the copy owns its own C++ object
    x = torus_knot(2, 3, 30)
    ctx = plugin_context(chain_system(x, ChainModel()), x, copy)
    assert type(ctx.getIntegrator()) is kp.RPYIntegrator
    copy.stepTo(0.02)
    assert copy.getNumAcceptedSteps() == 5


def test_app_simulation_reads_the_integrator_from_xml(tmp_path):
    path = tmp_path / "integrator.xml"
    path.write_text(openmm.XmlSerializer.serialize(kp.RPYIntegrator(0.01, "rk23", 1e-5)))
    x = torus_knot(2, 3, 30)
    sim = app.Simulation(bead_topology(30), chain_system(x, ChainModel()), str(path),
                         openmm.Platform.getPlatformByName("Reference"))
    assert type(sim.integrator) is kp.RPYIntegrator
    assert type(sim.context.getIntegrator()) is kp.RPYIntegrator
    sim.context.setPositions(x)
    sim.integrator.stepTo(0.5)
    assert sim.context.getState().getTime().value_in_unit(openmm.unit.picosecond) == 0.5


def test_cast_and_isinstance_on_base_class_references():
    integ = kp.RPYIntegrator(0.01, "heun")
    assert kp.RPYIntegrator.isinstance(integ)
    assert not kp.RPYIntegrator.isinstance(openmm.VerletIntegrator(0.01))
    with pytest.raises(openmm.OpenMMException):
        kp.RPYIntegrator.cast(openmm.VerletIntegrator(0.01))


def test_step_underflow_is_a_step_fault_with_its_fields():
    x = torus_knot(2, 3, 30)
    integ = kp.RPYIntegrator(0.5, "rk23", 1e-12)
    integ.setMinimumStepSize(0.1)
    ctx = plugin_context(chain_system(x, ChainModel()), x, integ)
    with pytest.raises(kp.StepFault) as info:
        integ.step(5)
    fault = info.value
    assert isinstance(fault, openmm.OpenMMException)
    assert (fault.kind, fault.method, fault.time, fault.bead) == ("step_underflow", "rk23", 0.0, -1)
    assert fault.error_estimate > 1.0
    assert f"error estimate {fault.error_estimate:.6g} x tolerance" in str(fault)
    # the last good state is kept: the start
    got = ctx.getState(getPositions=True).getPositions(asNumpy=True)._value
    np.testing.assert_array_equal(got, x)


def test_non_finite_positions_are_a_step_fault_naming_the_bead():
    x = torus_knot(2, 3, 30)
    integ = kp.RPYIntegrator(50.0, "euler")
    ctx = plugin_context(chain_system(x, ChainModel()), x, integ)
    with pytest.raises(kp.StepFault) as info:
        integ.step(100)
    fault = info.value
    assert fault.kind == "non_finite" and fault.method == "euler"
    assert f"(bead {fault.bead})" in str(fault)
    last_good = ctx.getState().getTime().value_in_unit(openmm.unit.picosecond)
    assert fault.time == last_good and math.isnan(fault.error_estimate)
    again = pickle.loads(pickle.dumps(fault))  # crosses process pools (sweeps)
    assert (type(again), again.kind, again.bead, str(again)) == (
        kp.StepFault, fault.kind, fault.bead, str(fault))


@pytest.mark.parametrize("target", [math.nan, math.inf, -1.0])
def test_step_to_refuses_a_time_it_cannot_reach(target):
    x = torus_knot(2, 3, 30)
    integ = kp.RPYIntegrator(0.01, "rk23")
    ctx = plugin_context(chain_system(x, ChainModel()), x, integ)  # noqa: F841 - keeps it bound
    integ.stepTo(0.1)
    with pytest.raises(openmm.OpenMMException, match="stepTo: time="):
        integ.stepTo(target)
    integ.stepTo(0.1)  # the time it is at: nothing to do, no error
    integ.stepTo(0.1 - 1e-12)  # within the landing slack


def test_landing_slack_is_relative_1e9():
    assert kp.rpyplugin.landingSlack(0.5) == 1e-9
    assert kp.rpyplugin.landingSlack(-2000.0) == pytest.approx(2e-6, rel=1e-15)


def test_method_table_shape():
    table = kp.rpyplugin.methodTable()
    assert [row[0] for row in table] == ["euler", "heun", "midpoint", "rk23", "rkc2",
                                         "euler_maruyama", "ito_heun", "leimkuhler_matthews",
                                         "ito_heun_adaptive"]
    for name, order, adaptive, stochastic in table:
        integ = kp.RPYIntegrator(0.01, name)
        assert (integ.isAdaptive(), integ.isStochastic()) == (adaptive, stochastic)
        assert order in (1, 2, 3)
    with pytest.raises(openmm.OpenMMException, match="expected one of euler, heun"):
        kp.rpyplugin.RPYIntegrator(0.01, "rk45")  # the C++ check, under knotmm's own


@pytest.mark.parametrize("call", ["step", "stepTo", "stepToWithin"])
def test_steps_leave_the_interpreter_to_other_threads(call):
    """step, stepTo and stepToWithin run without Python's global interpreter lock, so a
    Python thread beside them goes on counting while they step. Held, the lock stops the
    counter for the whole call (a C call does not hand it over): it then counts only while
    the caller waits to take the lock back, a few milliseconds' worth (measured: 0.5-1 % of
    its free rate over a 0.6 s call, against 80-100 % with the lock released)."""
    import threading
    import time

    x = torus_knot(2, 3, 60)
    integ = kp.RPYIntegrator(1e-4, "euler")
    ctx = plugin_context(chain_system(x, ChainModel()), x, integ)
    count, done = [0], threading.Event()

    def counting():
        while not done.is_set():
            count[0] += 1

    thread = threading.Thread(target=counting, daemon=True)
    thread.start()
    try:
        time.sleep(0.05)  # the counter thread is running
        before, start = count[0], time.perf_counter()
        time.sleep(0.1)
        free_rate = (count[0] - before) / (time.perf_counter() - start)
        steps = 4000
        before, start = count[0], time.perf_counter()
        {"step": lambda: integ.step(steps),
         "stepTo": lambda: integ.stepTo(steps * 1e-4),
         "stepToWithin": lambda: integ.stepToWithin(steps * 1e-4, 60.0)}[call]()
        took = time.perf_counter() - start
        during = count[0] - before
    finally:
        done.set()
        thread.join()
    assert ctx.getState().getTime().value_in_unit(openmm.unit.picosecond) == pytest.approx(0.4)
    assert took > 0.1, "the call must be long against the interpreter's 5 ms switch interval"
    assert during > 0.1 * free_rate * took, (took, during, free_rate)
