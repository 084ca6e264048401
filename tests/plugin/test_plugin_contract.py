"""The Python side holds to the compiled plugin's own tables: methods, landing rule, faults.

One owner each: the registry (:mod:`knotmm.dynamics.registry`) is the Python table of methods
and says which have a plugin counterpart; the plugin's ``methodTable()`` is the C++ one, and
:data:`knotmm.plugin.METHODS` is built from it. The landing rule is
:func:`knotmm.engine.schedule.landing_slack` in Python and ``landingSlack`` in C++. A failed
plugin step is a :class:`knotmm.plugin.StepFault`, which the plugin engine reads by its fields,
not by its text.
"""

from __future__ import annotations

import math

import openmm
import pytest

import knotmm.plugin as kp
from knotmm.config import RunConfig
from knotmm.dynamics.registry import PLUGIN_ENGINE, REGISTRY
from knotmm.engine.schedule import landing_slack
from knotmm.engine.simulation import Simulation
from knotmm.errors import SimulationFault


def test_the_registry_and_the_cpp_method_table_agree():
    """Names, order of accuracy, adaptive and stochastic flags; every registry entry that
    lists the plugin engine is in the C++ table and no other."""
    table = kp.rpyplugin.methodTable()
    cpp = {name: (order, adaptive, stochastic) for name, order, adaptive, stochastic in table}
    assert len(cpp) == len(table)  # no name twice
    python = {name: (info.order, info.adaptive, info.brownian)
              for name, info in REGISTRY.items() if PLUGIN_ENGINE in info.engines}
    assert cpp == python


def test_methods_is_built_from_the_cpp_table_in_its_order():
    table = kp.rpyplugin.methodTable()
    assert list(kp.METHODS.items()) == [(name, (order, adaptive, stochastic))
                                        for name, order, adaptive, stochastic in table]


@pytest.mark.parametrize("t", [0.0, 1e-12, 0.5, 1.0, -3.0, 7.25, 1e3, 123456.789, 1e9])
def test_the_python_landing_rule_is_the_plugins(t):
    assert landing_slack(t) == kp.rpyplugin.landingSlack(t)


def test_step_fault_is_the_plugins_exception_type():
    assert kp.StepFault is kp.rpyplugin.StepFault
    assert issubclass(kp.StepFault, openmm.OpenMMException)


# -- the plugin engine reads faults by their type and fields -----------------------------------
def _sim(**run):
    cfg = RunConfig.from_dict({"knot": {"beads": 30},
                               "run": {"platform": "Reference", "engine": "plugin", **run}})
    sim = Simulation.from_config(cfg)
    assert sim.engine == "plugin"
    return sim


def _failing_step(sim, monkeypatch, exc):
    """Every plugin step raises ``exc`` (and keeps the state, as the plugin does)."""
    def fail(*args):
        raise exc

    monkeypatch.setattr(sim.openmm_integrator, "step", fail)
    monkeypatch.setattr(sim.openmm_integrator, "stepTo", fail)
    monkeypatch.setattr(sim.openmm_integrator, "stepToWithin", fail)


def test_a_non_finite_fault_names_its_bead_whatever_its_text(monkeypatch):
    sim = _sim(integrator="heun")
    fault = kp.StepFault("some other wording", "non_finite", "heun", 0.0, 7, math.nan)
    _failing_step(sim, monkeypatch, fault)
    with pytest.raises(SimulationFault, match="non-finite at t = 0.01 tau_d.*first bad bead 7"):
        sim.run(0.1)
    assert sim.currentStep == 0 and sim.time == 0.0


def test_an_underflow_fault_gives_the_python_engines_message(monkeypatch):
    sim = _sim(integrator="rk23")
    fault = kp.StepFault("reworded", "step_underflow", "rk23", 0.0, -1, 12.3456)
    _failing_step(sim, monkeypatch, fault)
    with pytest.raises(SimulationFault,
                       match=r"below run.min_timestep.*rk23 error estimate 12.3 x tolerance"):
        sim.run(0.1)


def test_other_openmm_exceptions_are_not_read_as_faults(monkeypatch):
    """Text that looks like a fault is not one: the plain message, with its hint."""
    sim = _sim(integrator="rk23")
    text = "error estimate 5 x tolerance; non-finite at t = 0 ps (bead 3)"
    _failing_step(sim, monkeypatch, openmm.OpenMMException(text))
    with pytest.raises(SimulationFault) as info:
        sim.run(0.1)
    message = str(info.value)
    assert message.startswith("the plugin's step failed at t = 0 tau_d")
    assert text in message and "run.engine = \"python\"" in message
    assert sim.currentStep == 0 and sim.time == 0.0  # the start is kept
