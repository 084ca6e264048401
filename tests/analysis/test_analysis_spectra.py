"""Spectral periods: sub-bin accuracy, signs, uncertainties; the vortex-knot fit."""

from __future__ import annotations

import numpy as np
import pytest
from synthetic import vortex_knot_positions

from knotmm.analysis import (
    analyze,
    cylindrical,
    fit_vortex_knot,
    rotation_spectrum,
    scaled_coordinates,
    swirl_spectrum,
    winding_numbers,
)
from knotmm.analysis.spectra import line_spectrum
from knotmm.io.run_data import RunData


@pytest.mark.parametrize("frequency", [0.0437, -0.0712, 0.00291])
def test_single_line_between_bins(frequency):
    """A line that falls between Fourier bins is found to far better than a bin."""
    times = np.arange(300) * 0.5  # bin width 1/150
    rng = np.random.default_rng(0)
    phases = rng.uniform(0, 2 * np.pi, 20)
    signal = np.exp(1j * (2 * np.pi * frequency * times[:, None] + phases))
    signal += 0.05 * (rng.normal(size=signal.shape) + 1j * rng.normal(size=signal.shape))
    peak = line_spectrum(signal, times).peak
    assert abs(peak.frequency - frequency) < 0.01 * peak.resolution
    assert peak.frequency_uncertainty > 0
    # the uncertainty is of the right size: the error is within a few standard errors
    assert abs(peak.frequency - frequency) < 5 * peak.frequency_uncertainty + 1e-6


def test_swirl_and_rotation_spectra_naive_check():
    """Spectrum on the FFT grid agrees with a direct Fourier sum."""
    times = np.arange(64) * 0.5
    x = vortex_knot_positions(
        times, n_beads=30, rho0=1.5, swirl_amplitude=0.3, tau_swirl=7.0, tau_rot=-50.0
    )
    c = cylindrical(x)
    spec = swirl_spectrum(times, c.rho, c.z)
    signal = (c.z - c.z.mean(0)) + 1j * (c.rho - c.rho.mean(0))
    taper = np.hanning(len(times) + 2)[1:-1]
    k = len(spec.frequencies) // 2 + 37
    f = spec.frequencies[k]
    direct = sum(
        abs(np.sum(taper * signal[:, b] * np.exp(-2j * np.pi * f * (times - times[0])))) ** 2
        for b in range(signal.shape[1])
    )
    full = (np.abs(np.fft.fft(signal * taper[:, None], n=len(spec.frequencies), axis=0)) ** 2).sum(
        1
    )
    assert direct / full.max() == pytest.approx(spec.power[k], rel=1e-9)
    assert spec.peak.period == pytest.approx(7.0, rel=0.01)
    rot = rotation_spectrum(times, c.alpha)
    assert rot.peak.frequency < 0  # clockwise
    assert rot.peak.period == pytest.approx(50.0, rel=0.01)


@pytest.mark.parametrize("p, q", [(2, 3), (2, 5), (3, 2), (3, 4)])
def test_winding_numbers(p, q):
    x = vortex_knot_positions(
        np.array([0.0, 3.0]), n_beads=120, p=p, q=q, rho0=6.0, swirl_amplitude=0.5
    )
    axis, core = winding_numbers(x)
    np.testing.assert_allclose(np.abs(axis), p)
    np.testing.assert_allclose(np.abs(core), q)


@pytest.mark.parametrize("mirror, tau_rot", [(False, 300.0), (True, 300.0), (False, -300.0)])
def test_fit_and_collapse(mirror, tau_rot):
    times = np.arange(201) * 0.5
    truth = dict(rho0=4.3, swirl_amplitude=0.5, tau_swirl=20.0, velocity=7.0)
    x = vortex_knot_positions(times, tau_rot=tau_rot, mirror=mirror, noise=0.01, **truth)
    c = cylindrical(x)
    # starting guesses 3% off: the fit must move to the truth
    fit = fit_vortex_knot(times, c.rho, c.alpha, x[..., 2], 2, 3, 20.6, 0.97 * tau_rot)
    assert fit.converged
    assert fit.rho0 == pytest.approx(4.3, rel=1e-3)
    assert fit.swirl_amplitude == pytest.approx(0.5, rel=1e-2)
    assert fit.tau_swirl == pytest.approx(20.0, rel=1e-3)
    expected_rot = -tau_rot if mirror else tau_rot
    assert fit.tau_rot == pytest.approx(expected_rot, rel=1e-2)
    assert fit.velocity == pytest.approx(7.0, rel=1e-4)
    assert fit.r2["total"] > 0.99
    assert fit.rms["total"] == pytest.approx(0.01, rel=0.2)
    sc = scaled_coordinates(fit, times, c.rho, c.alpha, x[..., 2])
    angle = 2 * np.pi * sc.cycle
    for values, curve in (
        (sc.rho, np.sin(angle)),
        (sc.alpha, np.cos(angle)),
        (sc.z, np.cos(angle)),
    ):
        assert np.sqrt(np.mean((values - curve) ** 2)) < 0.1


def _wobbling_torus(wobble_period: float, tilt: float) -> dict:
    """A T(2,3) vortex knot (swirl 7 tau_d, 0.1 d) whose axis wobbles about x by ``tilt`` rad
    with ``wobble_period`` (tau_d), frames 0.25 tau_d apart, analysed over 0-50 tau_d."""
    dt = 0.25
    times = np.arange(201) * dt
    x = vortex_knot_positions(times, rho0=4.0, swirl_amplitude=0.1, tau_swirl=7.0,
                              tau_rot=400.0, z_com=-7.0 * times, noise=0.005)
    angle = tilt * np.sin(2 * np.pi * times / wobble_period)[:, None]
    com = x.mean(axis=1, keepdims=True)
    r = x - com
    y = np.cos(angle) * r[..., 1] - np.sin(angle) * r[..., 2]
    z = np.sin(angle) * r[..., 1] + np.cos(angle) * r[..., 2]
    x = com + np.stack([r[..., 0], y, z], axis=-1)
    return analyze(RunData.from_arrays(x, dt, {"knot": {"p": 2, "q": 3}}), knot_samples=0,
                   t_from=0, t_to=50).to_dict()


def test_a_slow_tilt_wobble_is_not_the_swirl_period():
    """A torus whose axis wobbles slowly (period 40 tau_d, 0.12 rad; what a torus does at
    finite temperature) in a 50 tau_d window: the lab-frame swirl signal's strongest line is
    the wobble, slower than half the window; tau_swirl is the swirl's 7 tau_d (the period
    the body frame sees), searched in the band the swirl is detected in (two periods)."""
    d = _wobbling_torus(40.0, 0.12)
    assert d["swirl_detected"]
    assert d["tau_swirl"] == pytest.approx(7.0, rel=0.01)


def test_a_line_at_the_slow_edge_of_the_band_is_not_measured():
    """A faster wobble (period 30 tau_d, band edge 25 tau_d in a 50 tau_d window) whose
    foot is the lab-frame spectrum's strongest point in the band: tau_swirl is not measured
    (NaN, with a note naming the body frame's 7 tau_d), the swirl still detected."""
    d = _wobbling_torus(30.0, 0.2)
    assert d["swirl_detected"]
    assert d["tau_swirl"] is None or np.isnan(d["tau_swirl"])
    assert any("tau_swirl not measured" in n for n in d["notes"])
