"""Simulation.saveCheckpoint / loadCheckpoint: a saved state goes on bit for bit."""

from __future__ import annotations

import json

import numpy as np
import pytest

from knotmm.config import RunConfig
from knotmm.engine.checkpoint import CheckpointReporter, read_checkpoint
from knotmm.engine.reporters import (
    DCDReporter,
    KnotTypeWatch,
    ObservablesReporter,
    ProgressReporter,
)
from knotmm.engine.schedule import TimeScheduled
from knotmm.engine.simulation import Simulation
from knotmm.errors import TrajectoryFileError

CONFIGS = {
    "rk23": {"knot": {"beads": 30}, "run": {"platform": "Reference"}},
    "ito_heun": {
        "knot": {"beads": 30},
        "run": {"platform": "Reference", "peclet": 5.0, "integrator": "ito_heun",
                "timestep": 0.002, "seed": 11},
    },
}


def _sim(name, positions=None):
    # the Python engine's own state (held velocity, Python noise stream); the plugin
    # engine's checkpoints: tests/engine/test_engine_choice.py
    return Simulation.from_config(RunConfig.from_dict(CONFIGS[name]), positions, engine="python")


@pytest.mark.parametrize("name", sorted(CONFIGS))
def test_a_loaded_checkpoint_goes_on_as_an_uninterrupted_run(tmp_path, name):
    """Independent check: one uninterrupted run of the same length (same bits, same counts)."""
    whole = _sim(name)
    whole.step(40)

    first = _sim(name)
    first.step(15)
    first.saveCheckpoint(tmp_path / "state.npz", {"frames": 3, "note": "kept"})
    # a new simulation, started elsewhere, with a used-up noise stream and step size
    other_start = first.positions + 0.01
    second = _sim(name, other_start)
    second.step(3)
    extra = second.loadCheckpoint(tmp_path / "state.npz")
    assert extra == {"frames": 3, "note": "kept"}
    second.step(25)

    np.testing.assert_array_equal(second.positions, whole.positions)
    assert second.time == whole.time
    assert second.currentStep == whole.currentStep == 40
    # no extra force evaluation after loading (issue 11, item 12)
    assert second.n_evaluations == whole.n_evaluations
    assert second.integrator.timestep == whole.integrator.timestep


def test_checkpoints_without_the_held_velocity_still_load(tmp_path):
    """Files written before the held velocity was stored: the same trajectory, one more
    evaluation (the velocity is computed again)."""
    whole = _sim("rk23")
    whole.step(20)
    first = _sim("rk23")
    first.step(10)
    first.saveCheckpoint(tmp_path / "new.npz")
    with np.load(tmp_path / "new.npz") as data:
        old = {k: data[k] for k in data.files if k != "velocity"}
    np.savez(tmp_path / "old.npz", **old)
    assert read_checkpoint(tmp_path / "old.npz")["velocity"] is None
    second = _sim("rk23")
    second.loadCheckpoint(tmp_path / "old.npz")
    second.step(10)
    np.testing.assert_array_equal(second.positions, whole.positions)
    assert second.n_evaluations == whole.n_evaluations + 1


def test_the_checkpoint_file_keeps_its_keys(tmp_path):
    """Existing run directories resume: the npz keys and their meaning stay the same."""
    sim = _sim("ito_heun")
    sim.step(5)
    sim.saveCheckpoint(tmp_path / "c.npz", {"frames": 1, "rows": 1})
    with np.load(tmp_path / "c.npz") as data:
        assert {"positions", "time", "step", "evaluations", "integrator", "integrator_state",
                "counters"} <= set(data.files)
        np.testing.assert_array_equal(data["positions"], sim.positions)
        assert float(data["time"]) == sim.time and int(data["step"]) == 5
        assert str(data["integrator"]) == "ito_heun"
        assert json.loads(str(data["counters"])) == {"frames": 1, "rows": 1}
        assert "rng_state" in json.loads(str(data["integrator_state"]))


def test_a_checkpoint_of_another_integrator_or_size_is_refused(tmp_path):
    a = _sim("ito_heun")
    a.saveCheckpoint(tmp_path / "c.npz")
    with pytest.raises(TrajectoryFileError, match="ito_heun.*rk23"):
        _sim("rk23").loadCheckpoint(tmp_path / "c.npz")
    small = Simulation.from_config(
        RunConfig.from_dict({**CONFIGS["ito_heun"], "knot": {"beads": 36}}), engine="python")
    with pytest.raises(TrajectoryFileError, match="30 beads"):
        small.loadCheckpoint(tmp_path / "c.npz")
    (tmp_path / "bad.npz").write_bytes(b"no")
    with pytest.raises(TrajectoryFileError, match="unreadable"):
        a.loadCheckpoint(tmp_path / "bad.npz")


def test_a_fault_does_not_store_the_velocity_of_the_bad_state(tmp_path):
    """After a refused step the integrator holds the velocity of the rejected positions;
    the checkpoint of the last good state must not carry it."""
    sim = _sim("rk23")
    sim.step(3)
    sim.max_bond_length = 0.0  # every next state is refused
    with pytest.raises(Exception, match="past run.max_bond_length"):
        sim.step(1)
    sim.saveCheckpoint(tmp_path / "c.npz")
    assert read_checkpoint(tmp_path / "c.npz")["velocity"] is None


def test_every_reporter_shares_the_one_scheduler():
    for cls in (DCDReporter, ObservablesReporter, ProgressReporter, KnotTypeWatch,
                CheckpointReporter):
        assert issubclass(cls, TimeScheduled), cls
        assert "next_report_time" not in vars(cls), cls  # nobody schedules on their own


def test_the_checkpoint_reporter_saves_on_its_schedule(tmp_path):
    sim = _sim("rk23")
    saved = []
    reporter = CheckpointReporter(tmp_path / "c.npz", 0.25,
                                  lambda k: saved.append(k) or {"next": k})
    sim.reporters.append(reporter)
    sim.run(1.0)
    assert saved == [1, 2, 3, 4, 5]  # t = 0, 0.25, ..., 1.0; the next index stored
    state = read_checkpoint(tmp_path / "c.npz")
    assert state["time"] == pytest.approx(1.0) and state["counters"] == {"next": 5}


def test_from_config_takes_model_integrator_and_template_from_the_config():
    from knotmm.shapes import torus_knot

    cfg = RunConfig.from_dict({"knot": {"beads": 40}, "model": {"bending_stiffness": 7.0},
                               "run": {"platform": "Reference", "max_bond_length": 2.5}})
    sim = Simulation.from_config(cfg)
    np.testing.assert_allclose(sim.positions, torus_knot(2, 3, 40), atol=1e-9)
    assert sim.model.bending_stiffness == 7.0
    assert sim.integrator.name == "rk23" and sim.platform_name == "Reference"
    assert sim.max_bond_length == 2.5
    given = torus_knot(2, 3, 40) + 1.0
    np.testing.assert_array_equal(Simulation.from_config(cfg, given).positions, given)
