"""Brownian methods of the plugin: fluctuation-dissipation checks against closed forms.

Each tolerance comes from the sample count: the standard error of a mean over correlated
samples is taken from batch means (independent batches by construction: each is many
relaxation times long), and a check passes within 4.5 standard errors plus the known
discretisation bias of the method at the chosen step.
"""

from __future__ import annotations

import numpy as np
import openmm
import pytest
from plugin_helpers import dimer_system, plugin_context, positions_of
from scipy.integrate import quad

from knotmm.plugin import RPYIntegrator


def batch_mean_and_error(samples, batches=40):
    """Mean of the samples and its standard error from ``batches`` batch means."""
    samples = np.asarray(samples)
    means = samples[: len(samples) // batches * batches].reshape(batches, -1).mean(axis=1)
    return samples.mean(), means.std(ddof=1) / np.sqrt(batches)


@pytest.mark.parametrize("method", ["euler_maruyama", "ito_heun"])
@pytest.mark.parametrize(("kT", "mu0"), [(0.5, 1.0), (2.0, 0.3)])
def test_free_bead_msd(method, kT, mu0):
    """A lone bead: each coordinate's displacement over t has variance 2 kT mu0 t."""
    system = openmm.System()
    system.addParticle(1.0)
    h, window, windows = 0.01, 10, 2000
    integ = RPYIntegrator(h, method, kT=kT, mobility=mu0, seed=2024)
    ctx = plugin_context(system, np.zeros((1, 3)), integ)
    x = [positions_of(ctx)[0]]
    for _ in range(windows):
        integ.step(window)
        x.append(positions_of(ctx)[0])
    d = np.diff(np.array(x), axis=0).reshape(-1)  # independent N(0, 2 kT mu0 t) samples
    t = h * window
    expected = 2 * kT * mu0 * t
    # variance of a sample variance of n normals: 2 sigma^4 / n
    se = expected * np.sqrt(2.0 / d.size)
    assert abs(np.mean(d**2) - expected) < 4.5 * se
    assert abs(np.mean(d)) < 4.5 * np.sqrt(expected / d.size)


def boltzmann_moments(k, l0, kT):
    """<r> and <r^2> of P(r) ~ r^2 exp(-k (r - l0)^2 / (2 kT)) on r > 0."""
    def w(r):
        return r * r * np.exp(-k * (r - l0) ** 2 / (2 * kT))

    hi = l0 + 12 * np.sqrt(kT / k)
    z = quad(w, 0, hi)[0]
    return quad(lambda r: r * w(r), 0, hi)[0] / z, quad(lambda r: r * r * w(r), 0, hi)[0] / z


@pytest.mark.parametrize("method", ["ito_heun", "euler_maruyama"])
def test_dimer_bond_length_is_boltzmann(method):
    """A bonded pair with hydrodynamic coupling (both RPY branches: r spans 0.4..1.6 d).

    The stationary bond-length distribution must be Boltzmann's whatever the mobility: it
    checks that the noise covariance is the RPY tensor (and that no drift term is missing).
    Bond relaxation rate about 2 k (mu_ii - mu_ij) ~ 5 / tau_d; samples every 0.2 tau_d.
    """
    k, l0, kT = 10.0, 1.0, 1.0
    h = 0.004 if method == "euler_maruyama" else 0.01
    every = round(0.2 / h)
    n_samples = 20000
    integ = RPYIntegrator(h, method, kT=kT, seed=7)
    x0 = np.array([[0.0, 0.0, 0.0], [l0, 0.0, 0.0]])
    ctx = plugin_context(dimer_system(k, l0), x0, integ)
    integ.step(10 * every)  # equilibrate
    r = np.empty(n_samples)
    for i in range(n_samples):
        integ.step(every)
        x = positions_of(ctx)
        r[i] = np.linalg.norm(x[1] - x[0])
    m1, m2 = boltzmann_moments(k, l0, kT)
    mean, se1 = batch_mean_and_error(r)
    msq, se2 = batch_mean_and_error(r**2)
    assert r.min() < 0.6 and r.max() > 1.4  # both the overlap and the far branch were sampled
    # Discretisation bias at these steps (stiffest rate ~ 2 k mu ~ 20/tau_d, h lambda <= 0.1):
    # below 0.5 % of the variance of r, a few 1e-4 in <r^2>.
    assert abs(mean - m1) < 4.5 * se1 + 1e-3, (mean, m1, se1)
    assert abs(msq - m2) < 4.5 * se2 + 2e-3, (msq, m2, se2)


def test_kT_can_change_between_steps():
    """setThermalEnergy on a bound integrator acts from the next step (e.g. annealing)."""
    system = openmm.System()
    system.addParticle(1.0)
    integ = RPYIntegrator(0.01, "euler_maruyama", kT=1.0, seed=3)
    ctx = plugin_context(system, np.zeros((1, 3)), integ)
    integ.step(5)
    assert np.abs(positions_of(ctx)).max() > 0
    integ.setThermalEnergy(0.0)  # no noise and no force: the bead stays
    before = positions_of(ctx)
    integ.step(5)
    np.testing.assert_array_equal(positions_of(ctx), before)
