"""The core pin (knotmm.engine.affinity) changes where threads run, nothing else."""

from __future__ import annotations

import os

import numpy as np
import pytest

import knotmm.plugin as kp
from knotmm.dynamics.deterministic import RK23
from knotmm.engine.affinity import CorePin
from knotmm.engine.simulation import Simulation
from knotmm.shapes.geometry import torus_knot

pytestmark = pytest.mark.skipif(not kp.available(), reason="needs the compiled plugin")


def _run(monkeypatch, pin: bool):
    monkeypatch.setenv("KNOTMM_NO_PIN", "0" if pin else "1")
    sim = Simulation(torus_knot(2, 3, 40), integrator=RK23(0.01), platform="CPU",
                     engine="plugin")
    assert sim.core_pin.enabled == (pin and hasattr(os, "sched_setaffinity"))
    sim.run(2.0)
    return sim.positions.copy(), sim.n_evaluations


def test_pinned_and_unpinned_runs_are_the_same_bit_for_bit(monkeypatch):
    before = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else None
    pinned = _run(monkeypatch, True)
    if before is not None:  # the caller's affinity is given back after each stretch
        assert os.sched_getaffinity(0) == before
    plain = _run(monkeypatch, False)
    np.testing.assert_array_equal(pinned[0], plain[0])
    assert pinned[1] == plain[1]


def test_disabled_pin_does_nothing():
    pin = CorePin(enabled=False)
    with pin.creating():
        pass
    assert not pin.pool
    with pin.stepping():
        pass
