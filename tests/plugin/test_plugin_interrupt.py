"""The plugin's long computations give control back between steps (issue 30, BUG-13).

A stretch between two reports used to be one ``RPYIntegrator.stepTo`` call holding the GIL:
a blown-up state or a step far below the stretch kept it in C++ for minutes, deaf to
SIGINT/SIGTERM. ``stepToWithin(time, seconds)`` returns at a step boundary once its time
budget is spent, and :class:`knotmm.engine.plugin_engine.PluginEngine` calls it in a loop
with the state checks and the stop request between calls. These tests hold that:

* with a zero budget ``stepToWithin`` takes exactly one step per call and the steps are those
  of one ``stepTo`` call, bit for bit (adaptive, fixed-step and Brownian methods);
* a stop asked for while a long stretch runs ends the run within about a second;
* a run stopped inside a stretch, saved and resumed, goes on bit for bit as one that was
  never stopped.
"""

from __future__ import annotations

import math
import subprocess
import sys
import textwrap
import threading
import time

import numpy as np
import openmm
import pytest
from plugin_helpers import plugin_context, positions_of

import knotmm.engine.plugin_engine as plugin_engine
from knotmm.config import RunConfig
from knotmm.engine.interrupt import StopRequested, raise_if_requested, request_stop
from knotmm.engine.simulation import Simulation
from knotmm.model.system import chain_system as build_system
from knotmm.plugin import RPYIntegrator
from knotmm.shapes import torus_knot


@pytest.mark.parametrize(("method", "step", "kwargs"), [
    ("rk23", 0.01, {}),
    ("heun", 0.005, {}),
    ("ito_heun_adaptive", 0.002, {"kT": 0.5, "seed": 5, "error_tolerance": 0.02}),
    ("leimkuhler_matthews", 0.005, {"kT": 0.5, "seed": 6}),
])
def test_step_to_within_a_zero_budget_takes_one_step_a_call_as_step_to_would(method, step,
                                                                            kwargs):
    x = torus_knot(2, 3, 30)
    system = build_system(x)
    whole = RPYIntegrator(step, method, **kwargs)
    ctx_whole = plugin_context(system, x, whole)
    whole.stepTo(0.1)

    parts = RPYIntegrator(step, method, **kwargs)
    ctx_parts = plugin_context(system, x, parts)
    calls = 0
    while True:
        before = parts.getNumAcceptedSteps()
        reached = parts.stepToWithin(0.1, 0.0)
        calls += 1
        assert parts.getNumAcceptedSteps() == before + 1  # one step, then back to Python
        if reached:
            break
        assert ctx_parts.getState().getTime().value_in_unit(openmm.unit.picosecond) < 0.1
    assert calls == whole.getNumAcceptedSteps() > 5
    assert ctx_parts.getState().getTime() == ctx_whole.getState().getTime()
    np.testing.assert_array_equal(positions_of(ctx_parts), positions_of(ctx_whole))
    assert parts.getNumRejectedSteps() == whole.getNumRejectedSteps()
    assert parts.stepToWithin(0.1, 0.0)  # reached already: no step
    assert parts.getNumAcceptedSteps() == calls


@pytest.mark.parametrize("budget", [-1.0, math.nan])
def test_step_to_within_refuses_a_bad_budget(budget):
    x = torus_knot(2, 3, 30)
    integ = RPYIntegrator(0.01, "rk23")
    ctx = plugin_context(build_system(x), x, integ)
    with pytest.raises(openmm.OpenMMException, match="maxSeconds"):
        integ.stepToWithin(0.1, budget)
    assert integ.getNumAcceptedSteps() == 0
    assert ctx.getState().getTime().value_in_unit(openmm.unit.picosecond) == 0.0


def test_a_plugin_built_without_step_to_within_is_named_for_a_rebuild():
    """The engine needs ``stepToWithin``: a build from older sources is not used (the Python
    engine runs) and :func:`knotmm.plugin.rebuild_needed` says so, with the command."""
    code = textwrap.dedent("""
        import importlib
        import knotmm.plugin.rpyplugin as built
        del built.RPYIntegrator.stepToWithin  # as a build from before issue 30
        import knotmm.plugin as plugin
        importlib.reload(plugin)
        print(plugin.available(), plugin.rebuild_needed())
        print(plugin.load_error())
        """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    first, error = out.stdout.splitlines()[:2]
    assert first == "False True"
    assert "stepToWithin" in error and "rebuild it" in error


def _config(**run) -> RunConfig:
    return RunConfig.from_dict({"knot": {"beads": 30},
                                "run": {"engine": "plugin", "seed": 3, **run}})


def test_a_stop_asked_for_inside_a_long_stretch_is_taken_within_a_second():
    """One stretch of 2e4 steps (several seconds in C++); the stop comes 0.3 s into it."""
    sim = Simulation.from_config(_config(max_timestep=1e-5, peclet=math.inf))
    assert sim.engine == "plugin"
    timer = threading.Timer(0.3, request_stop)
    start = time.monotonic()
    timer.start()
    try:
        with pytest.raises(StopRequested):
            sim.run(0.2)
        elapsed = time.monotonic() - start
    finally:
        timer.cancel()
        try:  # never leave a request behind for the next test
            raise_if_requested()
        except StopRequested:
            pass
    assert elapsed < 2.0, f"the stop took {elapsed:.2f} s"
    assert 0.0 < sim.time < 0.2
    # the state is a whole step boundary: the Context holds it, and it passes the checks
    sim.check_state(sim.positions, initial=True)


class _Frames:
    """A time-scheduled reporter keeping each frame's time, step and positions."""

    def __init__(self, interval):
        self.interval = interval
        self.times, self.steps, self.frames = [], [], []

    def next_report_time(self, simulation):
        return len(self.times) * self.interval

    def report(self, simulation, state):
        self.times.append(simulation.time)
        self.steps.append(simulation.currentStep)
        self.frames.append(simulation.positions.copy())


def test_a_run_stopped_inside_a_stretch_resumes_bit_for_bit(tmp_path, monkeypatch):
    """Brownian (ito_heun_adaptive, Pe = 10): stopped between two C++ calls half way through a
    stretch, checkpointed, resumed in a new Simulation: the same frames as one run."""
    cfg = _config(peclet=10.0)
    reference = Simulation.from_config(cfg)
    ref_frames = _Frames(0.05)
    reference.reporters.append(ref_frames)
    reference.run(0.25)

    monkeypatch.setattr(plugin_engine.PluginEngine, "chunk_seconds", 0.0)  # one step a call
    calls = []

    def stop_at_the_8th_call():
        calls.append(1)
        if len(calls) == 8:
            raise StopRequested("SIGTERM")

    monkeypatch.setattr(plugin_engine, "raise_if_requested", stop_at_the_8th_call)
    sim = Simulation.from_config(cfg)
    frames = _Frames(0.05)
    sim.reporters.append(frames)
    with pytest.raises(StopRequested):
        sim.run(0.25)
    stopped_at = sim.time
    assert 0.0 < stopped_at < 0.25
    assert not any(abs(stopped_at - k * 0.05) < 1e-12 for k in range(6))  # inside a stretch
    sim.saveCheckpoint(tmp_path / "checkpoint.npz")

    monkeypatch.undo()
    resumed = Simulation.from_config(cfg)
    resumed.loadCheckpoint(tmp_path / "checkpoint.npz")
    resumed.reporters.append(frames)
    resumed.run(0.25 - stopped_at, write_at_start=False)
    n = 5  # the frames before the end (t = 0, ..., 0.2): their targets are the same floats
    assert frames.times[:n] == ref_frames.times[:n]
    assert frames.steps[:n] == ref_frames.steps[:n]
    np.testing.assert_array_equal(np.array(frames.frames[:n]), np.array(ref_frames.frames[:n]))
