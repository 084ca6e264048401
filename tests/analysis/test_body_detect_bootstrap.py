"""Body frame, torus-shape criterion, swirl detector and block bootstrap against closed forms."""

from __future__ import annotations

import numpy as np
import pytest
from synthetic_regimes import noisy_swirl, rigid_ring, rotate_x, tilted_torus

from knotmm.analysis.body import body_frame, torus_shape
from knotmm.analysis.bootstrap import (
    autocorrelation_time,
    block_bootstrap_mean,
    bootstrap_uncertainties,
)
from knotmm.analysis.detect import FALSE_ALARM, detect_swirl, float32_spacing, line_amplitudes


def test_body_frame_of_a_tilted_ring_is_its_own_cylinder():
    t = np.arange(50) * 0.5
    x = rigid_ring(t, n_beads=40, radius=3.0, tilt_deg=35.0)
    b = body_frame(x, t)
    a = np.radians(35.0)
    np.testing.assert_allclose(b.normal, np.tile([0.0, -np.sin(a), np.cos(a)], (50, 1)), atol=1e-9)
    np.testing.assert_allclose(b.rho, 3.0, atol=1e-9)
    np.testing.assert_allclose(b.z, 0.0, atol=1e-9)
    np.testing.assert_allclose(b.inclination, 35.0, atol=1e-6)
    # spinning with period 50 about its own axis: phi advances 2 pi t / 50
    np.testing.assert_allclose(b.phi[-1] - b.phi[0], 2 * np.pi * t[-1] / 50.0, atol=1e-9)
    # a 40-gon: planar winding N sin(2 pi / N) / (2 pi)
    np.testing.assert_allclose(b.winding, 40 * np.sin(2 * np.pi / 40) / (2 * np.pi), rtol=1e-9)
    assert b.toroidal.all()


def test_normal_followed_through_a_full_turn():
    t = np.arange(361) * 1.0
    x = tilted_torus(t, t.copy(), velocity=0.0, swirl_amplitude=0.3)  # one degree per frame
    b = body_frame(x, t)
    # the followed normal turns with the body: its angle from +z is the rotation angle
    expected = np.where(t <= 180, t, 360 - t)
    np.testing.assert_allclose(b.tilt, expected, atol=0.05)
    assert b.flips.count == 2
    assert b.max_turn_deg == pytest.approx(1.0, abs=0.01)


def test_torus_shape_criterion():
    moments = np.array([[0.1, 9.0, 9.5], [3.0, 9.0, 9.5], [0.1, 2.0, 9.5], [0.1, 9.0, 9.5]])
    winding = np.array([2.0, 2.0, 2.0, 0.2])
    hole = np.zeros(4)
    assert torus_shape(moments, winding, hole).tolist() == [True, False, False, False]
    assert not torus_shape(moments[:1], winding[:1], np.array([0.2]))[0]
    # a random coil is not a flat torus
    rng = np.random.default_rng(3)
    coil = np.cumsum(rng.normal(size=(1, 200, 3)), axis=1)
    assert not body_frame(coil).toroidal[0]


def test_line_amplitudes_closed_form():
    t = np.arange(300) * 0.3
    values = np.stack([0.7 * np.sin(2 * np.pi * t / 9.0 + 0.3), 0.2 * np.cos(2 * np.pi * t / 9.0)])
    np.testing.assert_allclose(line_amplitudes(t, values.T + 5.0, 1 / 9.0), [0.7, 0.2], rtol=2e-3)


def test_detector_false_alarm_rate_on_white_noise():
    # 200 noise-only windows: the test promises at most 1 % false alarms
    rng = np.random.default_rng(11)
    t = np.arange(256) * 0.5
    hits = sum(
        detect_swirl(t, rng.normal(size=(256, 12)), rng.normal(size=(256, 12))).detected
        for _ in range(200)
    )
    assert hits <= 200 * FALSE_ALARM * 3


def test_detector_finds_a_weak_line_and_the_precision_floor():
    rng = np.random.default_rng(5)
    t = np.arange(400) * 0.5
    phase = 2 * np.pi * t[:, None] / 13.0 + np.linspace(0, 2 * np.pi, 20, endpoint=False)
    rho = 0.2 * np.sin(phase) + rng.normal(scale=0.5, size=phase.shape)
    z = 0.2 * np.cos(phase) + rng.normal(scale=0.5, size=phase.shape)
    det = detect_swirl(t, rho, z)
    assert det.detected and 1 / abs(det.frequency) == pytest.approx(13.0, rel=0.01)
    # the same line, 1e-5 d, in a run stored near 1000 d: below the float32 floor
    tiny = detect_swirl(t, 1e-5 * np.sin(phase), 1e-5 * np.cos(phase), max_coordinate=1000.0)
    assert not tiny.detected and "float32" in tiny.reason
    assert tiny.amplitude_floor == pytest.approx(10 * 2.0**-10 / 10)  # 10^4 A: spacing 2^-10 A
    assert float32_spacing(1000.0) == pytest.approx(2.0**-10 / 10)


def _ar1(phi, m, seed):
    rng = np.random.default_rng(seed)
    e = rng.normal(size=m)
    x = np.empty(m)
    x[0] = e[0] / np.sqrt(1 - phi**2)
    for i in range(1, m):
        x[i] = phi * x[i - 1] + e[i]
    return x


def test_block_bootstrap_on_ar1_matches_the_closed_form():
    phi, m = 0.8, 20000
    ratios = []
    for seed in range(3):
        x = _ar1(phi, m, seed)
        assert autocorrelation_time(x) == pytest.approx((1 + phi) / (2 * (1 - phi)), rel=0.15)
        _, se, block, _ = block_bootstrap_mean(x)
        assert block >= 30
        sd = np.sqrt(1 / (1 - phi**2))
        ratios.append(se / (sd * np.sqrt((1 + phi) / (1 - phi) / m)))
    assert np.mean(ratios) == pytest.approx(1.0, abs=0.15)


def test_noisy_periodic_signal_period_and_scatter():
    # swirl phase diffusing with D = 0.02 rad^2/tau_d over T = 200 tau_d: the mean frequency
    # has standard error sqrt(2 D / T) / (2 pi); the bootstrap must report about that and
    # the estimates must scatter about that around the true period 10 tau_d
    t = np.arange(801) * 0.25
    d_phase, span = 0.02, t[-1] - t[0]
    theory = np.sqrt(2 * d_phase / span) / (2 * np.pi)
    values, errors = [], []
    for seed in range(12):
        x = noisy_swirl(t, d_phase, noise=0.01, seed=seed, n_beads=30)
        u = bootstrap_uncertainties(body_frame(x, t), slice(None))
        values.append(u["swirl_frequency"]["value"])
        errors.append(u["swirl_frequency"]["std_error"])
    assert np.mean(errors) == pytest.approx(theory, rel=0.25)
    assert np.std(values, ddof=1) == pytest.approx(theory, rel=0.5)
    assert np.mean(values) == pytest.approx(0.1, abs=3 * theory / np.sqrt(12))
    assert u["tau_swirl_body"]["value"] == pytest.approx(10.0, rel=0.1)
    assert u["sedimentation_velocity"]["value"] == pytest.approx(7.0, rel=1e-3)


def test_rotate_x_is_a_rotation():
    x = np.random.default_rng(0).normal(size=(3, 5, 3))
    y = rotate_x(x, [10.0, 90.0, 250.0])
    np.testing.assert_allclose(np.linalg.norm(y, axis=-1), np.linalg.norm(x, axis=-1))
    np.testing.assert_allclose(y[1, :, 2], x[1, :, 1], atol=1e-12)
