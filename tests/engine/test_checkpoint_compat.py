"""Checkpoint files written before the engine interface (issue 19) still load and go on.

``data/checkpoint_pre19_{engine}_{method}.npz`` were written by ``Simulation.saveCheckpoint``
of knotmm before issue 19 (commit 42fad00: ``Simulation`` branching on its engine, the plugin
engine writing its counters into the Python integrator), for a 30-bead T(2,3) ring on the
Reference platform after 12 steps: rk23 (deterministic, with the held FSAL velocity) and
leimkuhler_matthews at Pe = 5, seed 11 (the held half kick; the plugin's noise stream inside
the Context checkpoint), each on the Python and the plugin engine. ``..._after8.npz`` holds
what that code reached 8 steps later: positions, time, step, evaluations, step size and
rejections. Made with::

    sim = Simulation.from_config(RunConfig.from_dict(CONFIGS[method]), engine=engine)
    sim.step(12); sim.saveCheckpoint(path, {"frames": 2, "rows": 2}); sim.step(8)

A plugin checkpoint holds OpenMM's own Context state, which only the OpenMM version that
wrote it reads: those cases are skipped under another version. The RPY pair loop has
per-CPU code paths (numba's and the plugin's), so positions are held to 1e-10 d, not bits.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import openmm.version
import pytest

import knotmm.plugin
from knotmm.config import RunConfig
from knotmm.engine.checkpoint import read_checkpoint
from knotmm.engine.simulation import Simulation

DATA = Path(__file__).parent / "data"
CONFIGS = {
    "rk23": {"knot": {"beads": 30}, "run": {"platform": "Reference"}},
    "leimkuhler_matthews": {
        "knot": {"beads": 30},
        "run": {"platform": "Reference", "peclet": 5.0, "integrator": "leimkuhler_matthews",
                "seed": 11},
    },
}
#: The keys of a checkpoint file before issue 19, by engine.
OLD_KEYS = {
    "python": {"positions", "time", "step", "evaluations", "integrator", "integrator_state",
               "counters"},
    "plugin": {"positions", "time", "step", "evaluations", "integrator", "integrator_state",
               "counters", "engine", "openmm_checkpoint"},
}


def _case(engine, method):
    stem = DATA / f"checkpoint_pre19_{engine}_{method}"
    return stem.with_suffix(".npz"), dict(np.load(f"{stem}_after8.npz"))


@pytest.mark.parametrize("method", sorted(CONFIGS))
@pytest.mark.parametrize("engine", ["python", "plugin"])
def test_a_checkpoint_written_before_the_engine_interface_goes_on(engine, method):
    path, expect = _case(engine, method)
    if engine == "plugin":
        if not knotmm.plugin.available():
            pytest.skip(str(knotmm.plugin.load_error()))
        if str(expect["openmm_version"]) != openmm.version.version:
            pytest.skip(f"written by OpenMM {expect['openmm_version']}")
    with np.load(path) as data:  # the file is what the old code wrote
        assert OLD_KEYS[engine] <= set(data.files) <= OLD_KEYS[engine] | {"velocity"}
    sim = Simulation.from_config(RunConfig.from_dict(CONFIGS[method]), engine=engine)
    assert sim.loadCheckpoint(path) == {"frames": 2, "rows": 2}
    assert (sim.currentStep, sim.time) == (12, read_checkpoint(path)["time"])
    sim.step(8)
    np.testing.assert_allclose(sim.positions, expect["positions"], rtol=0, atol=1e-10)
    assert sim.time == pytest.approx(float(expect["time"]), rel=1e-13)
    assert sim.currentStep == int(expect["step"]) == 20
    assert sim.n_evaluations == int(expect["evaluations"])
    assert sim.n_rejected == int(expect["rejected"])
    assert sim.timestep == pytest.approx(float(expect["timestep"]), rel=1e-9)


@pytest.mark.parametrize("method", sorted(CONFIGS))
def test_a_new_checkpoint_has_the_old_keys(tmp_path, method):
    """The file format did not change: the same keys (and so the same meaning) as before."""
    sim = Simulation.from_config(RunConfig.from_dict(CONFIGS[method]), engine="python")
    sim.step(3)
    sim.saveCheckpoint(tmp_path / "c.npz")
    old, _ = _case("python", method)
    with np.load(tmp_path / "c.npz") as new, np.load(old) as before:
        assert set(new.files) == set(before.files)
        assert (set(read_checkpoint(tmp_path / "c.npz")["integrator_state"])
                == set(read_checkpoint(old)["integrator_state"]))
