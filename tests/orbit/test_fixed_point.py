"""A fixed point is no periodic orbit (knotmm.orbit.start: STEADY, shape_speed).

A chain that converges to a steady shape is "periodic" with any period, so ``knotmm orbit``
refuses it in one line (exit 2): when its analysis says the shape is steady (a run with
``model.gravity = 0``), and when the shape barely moves under the flow over the period
guess. ``shape_speed`` is checked against rigid motions (0), against a naive least-squares
removal of the rigid motions from a field, and on a swirling state against a finite-time
step of the flow map and the swirl's measured amplitudes.
"""

from __future__ import annotations

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from knotmm.cli.main import main
from knotmm.errors import ConfigError
from knotmm.orbit.flow import rms
from knotmm.orbit.start import FIXED_POINT_MOTION, STEADY, shape_speed


class _Field:
    """A flow whose velocity is a given function of the positions."""

    def __init__(self, velocity):
        self.velocity = velocity


def _shape(n=40, seed=3):
    """A knotted-looking ring of beads, not centred, in d."""
    s = np.linspace(0, 2 * np.pi, n, endpoint=False)
    x = np.stack([(4 + np.cos(3 * s)) * np.cos(2 * s), (4 + np.cos(3 * s)) * np.sin(2 * s),
                  np.sin(3 * s)], axis=1)
    return x + np.random.default_rng(seed).normal(scale=0.1, size=x.shape) + [3.0, -2.0, 50.0]


def _rigid(x, translation, omega, about):
    """``U + omega e_z x (x - about)``: a translation and a turn about a vertical axis."""
    r = x - about
    return translation + omega * np.stack([-r[:, 1], r[:, 0], np.zeros(len(x))], axis=1)


def _naive_shape_part(x, v):
    """``v`` less its least-squares fit by the 3 translations and the turn about z."""
    xc = x - x.mean(axis=0)
    basis = [np.tile(e, (len(x), 1)) for e in np.eye(3)]
    basis.append(np.stack([-xc[:, 1], xc[:, 0], np.zeros(len(x))], axis=1))
    b = np.stack([u.ravel() for u in basis], axis=1)
    coef, *_ = np.linalg.lstsq(b, v.ravel(), rcond=None)
    return (v.ravel() - b @ coef).reshape(v.shape)


def test_a_rigid_motion_has_no_shape_speed():
    x = _shape()
    # falling at 7 d/tau_d, drifting sideways, turning about an axis off the centroid
    flow = _Field(lambda y: _rigid(y, np.array([0.3, -0.2, -7.0]), 0.8, np.array([1.0, 2.0, 0.0])))
    assert rms(flow.velocity(x)) > 7
    assert shape_speed(flow, x) < 1e-12 * 7


def test_shape_speed_is_what_the_rigid_motions_leave():
    x = _shape()
    w = np.random.default_rng(8).normal(size=x.shape)
    flow = _Field(lambda y: w + _rigid(y, np.array([0.0, 0.0, -7.0]), -0.3, np.zeros(3)))
    expected = rms(_naive_shape_part(x, flow.velocity(x)))
    assert expected == pytest.approx(rms(_naive_shape_part(x, w)), rel=1e-12)
    assert shape_speed(flow, x) == pytest.approx(expected, rel=1e-10)


def test_a_swirling_state_moves_its_shape(run40, orbit40):
    from knotmm.analysis import analyze, load_run

    flow, _, start = orbit40
    speed = shape_speed(flow, start.positions)
    assert speed * start.tau_swirl > 10 * FIXED_POINT_MOTION
    # the flow map over a short step, its rigid part removed by least squares
    h = 0.01
    v = (flow(start.positions, h) - start.positions) / h
    assert speed == pytest.approx(rms(_naive_shape_part(start.positions, v)), rel=2e-3)
    # the swirl moves each bead on an ellipse: rho and z by the measured half-amplitudes,
    # along the ring by C p / q (the vortex-knot formula, p/q = 2/3); beads spread over the
    # phase, so the rms speed is omega times the rms of the half-amplitudes over sqrt(2)
    found = analyze(load_run(run40), knot_samples=0, fit=False)
    a = found.extra["swirl_detection"]
    half = math.sqrt(a["amplitude_rho"] ** 2 + a["amplitude_z"] ** 2
                     + (2 / 3 * a["amplitude_rho"]) ** 2)
    assert speed == pytest.approx(2 * math.pi / start.tau_swirl * half / math.sqrt(2), rel=0.1)


def test_the_shooting_refuses_a_state_whose_shape_is_at_rest():
    from knotmm.orbit.driver import _shoot

    x = _shape()
    start = SimpleNamespace(positions=x, tau_swirl=5.0, time=30.0, window=(10.0, 60.0))
    resting = _Field(lambda y: _rigid(y, np.array([0.0, 0.0, -7.0]), 0.1, np.zeros(3)))
    with pytest.raises(ConfigError, match=STEADY) as info:
        _shoot("RUN", start, resting, 1e-8)
    assert "a fixed point" in str(info.value) and "t = 30 tau_d" in str(info.value)


def test_the_shooting_refuses_a_period_that_newton_shrank(monkeypatch):
    import knotmm.orbit.driver as driver

    x = _shape()
    w = np.random.default_rng(2).normal(size=x.shape)
    start = SimpleNamespace(positions=x, tau_swirl=5.0, time=30.0, window=(10.0, 60.0))
    moving = _Field(lambda y: w)
    monkeypatch.setattr(driver, "refine_guess", lambda flow, x, tau: (5.2, 0.1, 0.01))
    for period, refused in ((2.5, True), (2.7, False)):
        monkeypatch.setattr(driver, "solve_orbit",
                            lambda *a, period=period, **k: SimpleNamespace(period=period))
        if refused:
            with pytest.raises(ConfigError, match=STEADY) as info:
                driver._shoot("RUN", start, moving, 1e-8)
            assert "from 5.2 to 2.5 tau_d" in str(info.value)
        else:
            assert driver._shoot("RUN", start, moving, 1e-8)[0].period == 2.7


def test_orbit_of_an_undriven_run_is_refused_in_one_line(run_maker, tmp_path, capsys):
    run = run_maker(tmp_path / "g0", **{"model.gravity": 0.0})
    assert main(["analyze", str(run), "--knot-samples", "0", "--no-plots", "-q"]) == 0
    found = json.loads((run / "analysis.json").read_text())
    assert found["swirl_detected"] is False
    assert found["swirl_detection"]["steady_shape"] is True
    capsys.readouterr()
    assert main(["orbit", str(run), "--modes", "0", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("knotmm: error: "), err
    assert STEADY in err[0] and "model.gravity = 0" in err[0], err
    assert not (tmp_path / "o").exists()
