"""run.engine: its resolution; the plugin engine held to the Python engine (Reference)."""

from __future__ import annotations

import logging
import math

import numpy as np
import pytest

import knotmm.plugin
from knotmm.config import RunConfig
from knotmm.engine.engines import resolve_engine
from knotmm.engine.simulation import Simulation
from knotmm.errors import SimulationFault, TrajectoryFileError

needs_plugin = pytest.mark.skipif(not knotmm.plugin.available(),
                                  reason=str(knotmm.plugin.load_error()))


def _cfg(**run) -> RunConfig:
    return RunConfig.from_dict({"knot": {"beads": 40},
                                "run": {"platform": "Reference", "topology_check_interval": 0.0,
                                        **run}})


# -- resolution -------------------------------------------------------------------------------
def test_python_is_python_whatever_is_built(caplog):
    with caplog.at_level(logging.WARNING):
        assert resolve_engine("python", "rk23") == "python"
        assert resolve_engine("python", "ito_heun", 2.0) == "python"
    assert not caplog.records


def test_missing_plugin_asked_for_warns_once_and_falls_back(monkeypatch, caplog):
    monkeypatch.setattr(knotmm.plugin, "available", lambda: False)
    monkeypatch.setattr(knotmm.plugin, "load_error", lambda: "no plugin in this test")
    with caplog.at_level(logging.WARNING):
        assert resolve_engine("plugin", "rk23") == "python"
    assert [r.getMessage().count("no plugin in this test") for r in caplog.records] == [1]
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        assert resolve_engine("auto", "rk23") == "python"  # silently
    assert not caplog.records


@needs_plugin
def test_auto_takes_the_plugin_except_on_gpus(caplog):
    with caplog.at_level(logging.WARNING):
        assert resolve_engine("auto", "rk23") == "plugin"
        assert resolve_engine("auto", "heun", math.inf, "Reference") == "plugin"
        # an ito_heun without noise (Pe = inf) is Heun: cheaper in C++
        assert resolve_engine("auto", "ito_heun", math.inf) == "plugin"
        # Brownian steps: the plugin (LAPACK Cholesky, no Python round trips) is cheaper
        assert resolve_engine("auto", "ito_heun", 2.0) == "plugin"
        assert resolve_engine("auto", "leimkuhler_matthews", 2.0) == "plugin"
        assert resolve_engine("auto", "euler_maruyama", 50.0) == "plugin"
        # ... with Lanczos noise too, which the plugin draws as the Python engine does
        assert resolve_engine("auto", "ito_heun", 2.0, "CPU", "lanczos") == "plugin"
        assert resolve_engine("auto", "heun", math.inf, "CPU", "lanczos") == "plugin"
        assert resolve_engine("auto", "rk23", math.inf, "CUDA") == "python"
        assert resolve_engine("plugin", "ito_heun", 2.0) == "plugin"  # asked for: granted
    assert not caplog.records
    with caplog.at_level(logging.WARNING):
        assert resolve_engine("plugin", "rk23", math.inf, "CUDA") == "python"
    assert len(caplog.records) == 1 and "CUDA" in caplog.records[0].getMessage()
    caplog.clear()
    with caplog.at_level(logging.WARNING):  # asked for with Lanczos noise: granted, silently
        assert resolve_engine("plugin", "ito_heun", 2.0, "CPU", "lanczos") == "plugin"
    assert not caplog.records


@needs_plugin
@pytest.mark.parametrize(("noise", "beads", "method"), [
    ("cholesky", 40, "cholesky"), ("lanczos", 40, "lanczos"), ("auto", 40, "cholesky"),
    ("auto", 301, "lanczos")])
def test_a_runs_noise_method_reaches_the_plugin(noise, beads, method):
    """``run.noise`` (``"auto"``: Cholesky up to 300 beads) and ``run.lanczos_tolerance``
    reach the plugin integrator, which takes the run whichever the method."""
    cfg = RunConfig.from_dict({"knot": {"beads": beads},
                               "run": {"peclet": 2.0, "noise": noise,
                                       "lanczos_tolerance": 1e-7}})
    sim = Simulation.from_config(cfg)
    assert sim.engine == "plugin" and sim.integrator.name == "ito_heun_adaptive"
    sim.step(1)
    rpy = sim.openmm_integrator
    assert rpy.getNoiseMethod() == method and rpy.getLanczosTolerance() == 1e-7


# -- plugin against Python --------------------------------------------------------------------
@needs_plugin
@pytest.mark.parametrize("integrator", ["rk23", "heun"])
def test_plugin_takes_the_python_engines_steps(integrator):
    """1 tau_d from the template: positions within 1e-10 d, equal step, evaluation and
    rejection counts (the C++ and Python integrators are written independently)."""
    cfg = _cfg(integrator=integrator)
    sims = {e: Simulation.from_config(cfg, engine=e) for e in ("python", "plugin")}
    for sim in sims.values():
        sim.run(1.0)
    py, pl = sims["python"], sims["plugin"]
    assert pl.engine == "plugin" and py.engine == "python"
    assert pl.time == py.time == 1.0
    np.testing.assert_allclose(pl.positions, py.positions, rtol=0, atol=1e-10)
    assert pl.currentStep == py.currentStep > 0
    assert pl.n_evaluations == py.n_evaluations
    assert pl.n_rejected == py.n_rejected
    if integrator == "rk23":
        assert pl.timestep == pytest.approx(py.timestep, rel=1e-8)


@needs_plugin
def test_plugin_steps_one_at_a_time_like_python():
    """``step(n)`` (OpenMM's meaning: n accepted steps) goes through single plugin steps."""
    sims = {e: Simulation.from_config(_cfg(), engine=e) for e in ("python", "plugin")}
    for sim in sims.values():
        sim.step(7)
    py, pl = sims["python"], sims["plugin"]
    assert pl.currentStep == py.currentStep == 7
    assert pl.time == pytest.approx(py.time, rel=1e-12)
    np.testing.assert_allclose(pl.positions, py.positions, rtol=0, atol=1e-10)


@needs_plugin
def test_from_config_resolves_run_engine():
    assert Simulation.from_config(_cfg(engine="plugin")).engine == "plugin"
    assert Simulation.from_config(_cfg(engine="python")).engine == "python"
    assert Simulation.from_config(_cfg(engine="auto", peclet=2.0)).engine == "plugin"


# -- faults ----------------------------------------------------------------------------------
@needs_plugin
@pytest.mark.parametrize(("settings", "expect"), [
    ({"max_bond_length": 0.6005}, "past run.max_bond_length = 0.6005"),
    ({"tolerance": 1e-12, "min_timestep": 1e-3}, "below run.min_timestep"),
])
def test_plugin_faults_are_the_python_engines(settings, expect):
    """The fault of a stretch is found at the step where the Python engine finds it: the
    same message (time, step, bead, value), and the last good state is kept."""
    cfg = _cfg(**settings)
    messages, kept = {}, {}
    for engine in ("python", "plugin"):
        sim = Simulation.from_config(cfg, engine=engine)
        with pytest.raises(SimulationFault) as info:
            sim.run(1.0)
        messages[engine] = str(info.value)
        kept[engine] = (sim.positions.copy(), sim.time, sim.currentStep)
    assert expect in messages["plugin"]
    assert messages["plugin"] == messages["python"]
    assert kept["plugin"][1:] == kept["python"][1:]
    np.testing.assert_allclose(kept["plugin"][0], kept["python"][0], rtol=0, atol=1e-10)


# -- checkpoints -----------------------------------------------------------------------------
@needs_plugin
@pytest.mark.parametrize("settings", [{}, {"peclet": 2.0, "seed": 7}])
def test_plugin_checkpoint_continues_bit_for_bit(tmp_path, settings):
    """Deterministic and Brownian (the plugin's noise stream is in the Context checkpoint)."""
    cfg = _cfg(engine="plugin", **settings)
    first = Simulation.from_config(cfg)
    assert first.engine == "plugin"
    first.run(0.5)
    first.saveCheckpoint(tmp_path / "c.npz", {"frames": 3})
    first.run(0.5)
    second = Simulation.from_config(cfg, engine="plugin")
    assert second.loadCheckpoint(tmp_path / "c.npz") == {"frames": 3}
    assert second.time == 0.5
    second.run(0.5)
    assert np.array_equal(second.positions, first.positions)
    assert (second.time, second.currentStep, second.n_evaluations) == (
        first.time, first.currentStep, first.n_evaluations)
    # the other engine cannot continue it
    with pytest.raises(TrajectoryFileError, match="plugin engine"):
        Simulation.from_config(cfg, engine="python").loadCheckpoint(tmp_path / "c.npz")
