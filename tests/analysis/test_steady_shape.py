"""A steady shape is not a slow swirl (knotmm.analysis.detect, item 2 of its docstring).

A red spectrum (the swirl band's strongest bin at its low edge, the power rising towards zero
frequency) comes from a relaxation towards a steady shape and from a swirl slower than half
the window alike. Only the first is ``steady``: its body-frame speed dies out, a swirl's does
not. The signals are closed forms: ``e(t) c_i`` with ``e = exp(-t/T)`` (every bead's
displacement between frames is ``|c_i| e_k (1 - exp(-dt/T))``, so the speed ratio of the last
quarter to the first is ``exp(-shift dt / T)`` exactly) and a swirl ``A exp(i (w t + phi_i))``
(constant speed: ratio 1).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from synthetic import vortex_knot_positions, write_run_directory

from knotmm.analysis import analyze, load_run
from knotmm.analysis.detect import RELAXED, detect_swirl, motion_decay
from knotmm.analysis.regimes import UNDRIVEN

DT = 0.25
T = np.arange(200) * DT  # a window of 49.75 tau_d
PHASES = np.linspace(0, 2 * np.pi, 24, endpoint=False)


def _relaxing(tau):
    e = np.exp(-T / tau)[:, None]
    return 4.0 + 0.8 * e * (1 + 0.3 * np.cos(PHASES)), 0.5 * e * np.sin(PHASES)


def _swirl(period, amplitude=0.3):
    theta = 2 * np.pi * T[:, None] / period + PHASES
    return 4.0 + amplitude * np.sin(theta), amplitude * np.cos(theta)


@pytest.mark.parametrize("tau", [5.0, 40.0])
def test_motion_decay_of_a_relaxation_is_the_closed_form(tau):
    rho, z = _relaxing(tau)
    steps = len(T) - 1
    shift = steps - steps // 4  # first index of the last quarter of the frame differences
    assert motion_decay(rho, z) == pytest.approx(math.exp(-shift * DT / tau), rel=1e-9)


def test_motion_decay_of_a_swirl_is_one_and_undefined_for_few_frames():
    assert motion_decay(*_swirl(75.0)) == pytest.approx(1.0, rel=1e-9)
    assert motion_decay(*_swirl(10.0)) == pytest.approx(1.0, rel=1e-9)
    rho, z = _swirl(10.0)
    assert math.isnan(motion_decay(rho[:4], z[:4]))


def test_a_fast_relaxation_is_a_steady_shape():
    det = detect_swirl(T, *_relaxing(5.0))
    assert not det.detected and det.steady
    assert det.motion_decay < RELAXED
    assert "relaxation towards a steady shape" in det.reason
    assert det.to_dict()["steady_shape"] is True


def test_a_slow_relaxation_and_a_slow_swirl_are_not_called_steady():
    # both give a red spectrum in a 50 tau_d window; neither shows the shape at rest
    for rho, z in (_relaxing(40.0), _swirl(75.0)):
        det = detect_swirl(T, rho, z)
        assert not det.detected and not det.steady, det.reason
        assert "no spectral line" in det.reason and "slower than half the window" in det.reason
        assert det.to_dict()["steady_shape"] is False


def test_a_swirl_in_the_band_is_detected_and_not_steady():
    det = detect_swirl(T, *_swirl(10.0))
    assert det.detected and not det.steady
    assert 1 / abs(det.frequency) == pytest.approx(10.0, rel=1e-3)
    assert det.motion_decay == pytest.approx(1.0, rel=1e-9)


def test_an_undriven_run_is_steady_whatever_its_frames_show(tmp_path):
    # a swirling vortex knot whose run.toml says model.gravity = 0: with no external force
    # the energy only falls (dU/dt = -F.M F <= 0), so the motion cannot be a lasting swirl
    times = np.arange(401) * 0.5
    config = {"knot": {"kind": "torus", "p": 2, "q": 3}, "model": {"bond_length": 0.6}}
    x = vortex_knot_positions(times)
    driven = analyze(load_run(write_run_directory(tmp_path / "g1", x, 0.5, config)),
                     knot_samples=0, fit=False)
    assert driven.swirl_detected
    assert driven.extra["swirl_detection"]["steady_shape"] is False
    config["model"]["gravity"] = 0.0
    undriven = analyze(load_run(write_run_directory(tmp_path / "g0", x, 0.5, config)),
                       knot_samples=0, fit=False)
    found = undriven.extra["swirl_detection"]
    assert not undriven.swirl_detected and found["steady_shape"] is True
    assert found["reason"] == UNDRIVEN
