"""One Simulation, two engines behind one interface (knotmm.engine.base.Engine).

The Simulation asks its engine and never which one it has; each engine owns its counters and
state, and neither writes into the other objects' state: the plugin engine leaves the Python
integrator it copies as it was.
"""

from __future__ import annotations

import ast
import inspect
import math
from pathlib import Path

import numpy as np
import pytest

import knotmm.engine.simulation as simulation_module
import knotmm.plugin
from knotmm.config import RunConfig
from knotmm.dynamics.deterministic import RK23, Heun
from knotmm.engine.base import Engine
from knotmm.engine.engines import make_engine
from knotmm.engine.plugin_engine import PluginEngine
from knotmm.engine.python_engine import PythonEngine
from knotmm.engine.schedule import landing_slack
from knotmm.engine.simulation import Simulation
from knotmm.errors import ConfigError

needs_plugin = pytest.mark.skipif(not knotmm.plugin.available(),
                                  reason=str(knotmm.plugin.load_error()))


def _abstract(cls) -> set[str]:
    """Names of ``cls``'s methods and properties that raise NotImplementedError."""
    out = set()
    for name, member in vars(cls).items():
        func = member.fget if isinstance(member, property) else member
        if callable(func) and "raise NotImplementedError" in inspect.getsource(func):
            out.add(name)
    return out


@pytest.mark.parametrize("cls", [PythonEngine, PluginEngine])
def test_each_engine_implements_the_whole_interface(cls):
    missing = {name for name in _abstract(Engine) if name not in vars(cls)}
    assert not missing
    assert cls.name in ("python", "plugin")


def test_the_simulation_does_not_ask_which_engine_it_has():
    """No engine names, no engine modules, no private state of another object in simulation.py."""
    source = Path(simulation_module.__file__).read_text()
    tree = ast.parse(source)
    names = {node.id for node in ast.walk(tree) if isinstance(node, ast.Name)}
    attributes = {node.attr for node in ast.walk(tree) if isinstance(node, ast.Attribute)}
    assert not {"PLUGIN", "PluginEngine", "PythonEngine"} & names
    assert not {"_plugin", "_f0", "mirror", "rpy"} & attributes
    strings = {node.value for node in ast.walk(tree)
               if isinstance(node, ast.Constant) and isinstance(node.value, str)}
    assert "plugin" not in strings


def test_make_engine_refuses_other_names():
    with pytest.raises(ConfigError, match="engine = 'numba'"):
        make_engine("numba", Heun(0.01))
    with pytest.raises(ConfigError, match="engine = 'auto'"):
        Simulation(np.zeros((4, 3)) + np.arange(4)[:, None] * [0.6, 0, 0], engine="auto")


def test_the_landing_rule():
    assert landing_slack(0.0) == landing_slack(0.5) == 1e-9
    assert landing_slack(-2000.0) == pytest.approx(2e-6, rel=1e-15)
    assert landing_slack(math.inf) == 0.0


def test_the_held_velocity_is_public_state_of_the_integrator(trefoil40):
    """What a checkpoint saves and sets back (no private attribute from outside)."""
    sim = Simulation(trefoil40, integrator=RK23(0.01), platform="Reference", engine="python")
    assert sim.integrator.held_velocity is None
    sim.step(2)
    held = sim.integrator.held_velocity
    assert held.shape == (40, 3)
    state = sim.integrator.get_state()
    sim.integrator.set_state(state)
    assert sim.integrator.held_velocity is None  # set_state forgets it
    sim.integrator.held_velocity = held
    assert sim.integrator.held_velocity is held
    euler = Heun(0.01)
    euler.held_velocity = held  # an integrator that reuses no velocity ignores it
    assert euler.held_velocity is None


def _cfg(**run):
    return RunConfig.from_dict({"knot": {"beads": 40},
                                "run": {"platform": "Reference", "topology_check_interval": 0.0,
                                        **run}})


@pytest.mark.parametrize("engine", ["python", pytest.param("plugin", marks=needs_plugin)])
def test_the_counters_are_the_engines(engine):
    sim = Simulation.from_config(_cfg(), engine=engine)
    assert sim.engine == engine
    sim.run(0.5)
    assert sim.currentStep > 0 and sim.n_evaluations > 3 * sim.currentStep - 1
    assert sim.n_rejected == 0 and sim.timestep != 0.01  # adaptive: the step moved on
    sim.currentStep = 0  # OpenMM's Simulation lets callers set it (knotmm.orbit does)
    assert sim.currentStep == 0


@needs_plugin
def test_the_plugin_engine_leaves_the_python_integrator_as_it_was():
    sim = Simulation.from_config(_cfg(), engine="plugin")
    before = sim.integrator.get_state()
    sim.run(0.5)
    assert sim.currentStep > 0
    assert sim.integrator.get_state() == before  # its counters and step are not written
    assert sim.integrator.n_accepted == 0 and sim.integrator.timestep == 0.01
