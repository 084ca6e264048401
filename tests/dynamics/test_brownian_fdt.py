"""Fluctuation-dissipation balance of the Brownian integrators with the RPY mobility.

Each check compares a measured fluctuation with its exact value, with a tolerance of a few
standard errors computed from the number of independent samples (or a Kolmogorov-Smirnov
critical value at level 1e-6), and a fixed seed: the tests cannot be flaky. The slow
versions (``-m slow``) repeat them with more samples and tighter error bars.

Model units: d = 1, mu0 = 1, kT = 1 / Pe.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from knotmm.config import RunConfig
from knotmm.dynamics.brownian import EulerMaruyama, ItoHeun
from knotmm.dynamics.mobility import pair_coefficients, rpy_matrix, rpy_velocities
from knotmm.dynamics.registry import make
from knotmm.engine.simulation import Simulation
from knotmm.model.system import ChainModel

INTEGRATORS = ["euler_maruyama", "ito_heun"]


def ks_critical(n, alpha=1e-6):
    return math.sqrt(-math.log(alpha / 2.0) / 2.0) / math.sqrt(n)


def zero_rhs(y):
    return np.zeros_like(y)


# -- a free bead ------------------------------------------------------------------------------
def free_bead_msd(name, steps, h, peclet, lags, seed):
    integ = make(name, h, peclet=peclet, seed=seed, noise="cholesky")
    y = np.zeros((1, 3))
    path = np.empty((steps + 1, 3))
    path[0] = y[0]
    for k in range(steps):
        y, _ = integ.step(zero_rhs, y)
        path[k + 1] = y[0]
    out = []
    for lag in lags:
        # non-overlapping windows: independent displacements
        d = path[lag::lag] - path[:-lag:lag]
        sq = np.sum(d * d, axis=1)
        expected = 6.0 * integ.kT * lag * h  # 6 kT mu0 t
        se = expected * math.sqrt(2.0 / 3.0 / len(sq))  # |d|^2 ~ (2 kT t) chi2(3)
        out.append((sq.mean(), expected, se, len(sq)))
    return out


@pytest.mark.parametrize("name", INTEGRATORS)
def test_free_bead_msd(name):
    """<|r(t) - r(0)|^2> = 6 kT mu0 t at lags of 1, 10 and 100 steps."""
    for msd, expected, se, n in free_bead_msd(name, 20_000, 0.01, 2.0, (1, 10, 100), 3):
        assert abs(msd - expected) < 5 * se, (msd, expected, se, n)


@pytest.mark.slow
@pytest.mark.parametrize("name", INTEGRATORS)
def test_free_bead_msd_slow(name):
    for msd, expected, se, _ in free_bead_msd(name, 400_000, 0.01, 0.5, (1, 30, 1000), 4):
        assert abs(msd - expected) < 5 * se


# -- two beads at fixed separation ------------------------------------------------------------
def pair_expectations(r):
    """Parallel and perpendicular pair mobility mu_12 at distance r (in mu0)."""
    a, b = pair_coefficients(r)
    return a + b * r * r, a


def two_bead_displacements(name, r, repeats, steps, h, peclet, seed):
    integ = make(name, h, peclet=peclet, seed=seed, noise="cholesky")
    start = np.array([[0.0, 0.0, 0.0], [r, 0.0, 0.0]])
    disp = np.empty((repeats, 2, 3))
    for k in range(repeats):
        y = start
        for _ in range(steps):
            y, _ = integ.step(zero_rhs, y)
        disp[k] = y - start
    return disp, integ.kT * steps * h


def check_two_bead(disp, kt_t, r, z=5.0):
    """COM and relative displacement variances vs 2 kT t times the RPY combinations."""
    par, perp = pair_expectations(r)
    com = 0.5 * (disp[:, 0] + disp[:, 1])
    rel = disp[:, 1] - disp[:, 0]
    checks = {
        # var of the COM: (mu_11 + 2 mu_12 + mu_22) / 4 = (1 + mu_12) / 2
        "com_par": (com[:, 0], (1 + par) / 2),
        "com_perp": (com[:, 1:].ravel(), (1 + perp) / 2),
        # var of the relative coordinate: mu_11 - 2 mu_12 + mu_22 = 2 (1 - mu_12)
        "rel_par": (rel[:, 0], 2 * (1 - par)),
        "rel_perp": (rel[:, 1:].ravel(), 2 * (1 - perp)),
        # cross-correlation of the two beads: mu_12
        "cross_par": (disp[:, 0, 0] * disp[:, 1, 0], par),
    }
    results = {}
    for key, (values, mobility) in checks.items():
        expected = 2.0 * kt_t * mobility
        if key.startswith("cross"):
            measured = values.mean()
            v1 = v2 = 2.0 * kt_t
            se = math.sqrt((v1 * v2 + expected**2) / len(values))
        else:
            measured = np.mean(values**2)  # the mean is zero: no force
            se = expected * math.sqrt(2.0 / len(values))
        results[key] = (measured / (2 * kt_t), mobility, se / (2 * kt_t))
        assert abs(measured - expected) < z * se, (key, r, measured, expected, se)
    return results


@pytest.mark.parametrize("r", [0.7, 1.5])
def test_two_bead_relative_and_com_diffusion(r):
    """Short-time diffusion of two free beads matches the RPY pair mobility.

    4 steps of 2.5e-4 tau_d at kT = 1 move each bead ~0.045 d, so the separation (and the
    mobility) hardly changes; 3000 repeats give 2.6% standard errors. Without
    hydrodynamic interactions rel_par would be 2 and com_par 0.5 (here 1.3 / 0.66 at r = 0.7
    and 1.07 / 0.73 at r = 1.5).
    """
    disp, kt_t = two_bead_displacements("euler_maruyama", r, 3000, 4, 2.5e-4, 1.0, seed=8)
    check_two_bead(disp, kt_t, r)


@pytest.mark.slow
@pytest.mark.parametrize("name", INTEGRATORS)
@pytest.mark.parametrize("r", [0.5, 0.99, 1.01, 2.0, 4.0])
def test_two_bead_diffusion_slow(name, r):
    disp, kt_t = two_bead_displacements(name, r, 20_000, 4, 2.5e-4, 1.0, seed=9)
    check_two_bead(disp, kt_t, r)


# -- harmonic dimer: Boltzmann's bond-length distribution with HI ------------------------------
K_SPRING, R0, KT = 4.0, 1.0, 1.0


def boltzmann_cdf():
    """CDF of the bond length, p(r) ~ r^2 exp(-k (r - r0)^2 / (2 kT)), on a fine grid."""
    grid = np.linspace(0.0, R0 + 12.0 * math.sqrt(KT / K_SPRING), 40_001)
    pdf = grid**2 * np.exp(-K_SPRING * (grid - R0) ** 2 / (2 * KT))
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (pdf[1:] + pdf[:-1]) * np.diff(grid))])
    mean = np.sum(0.5 * (grid[1:] * pdf[1:] + grid[:-1] * pdf[:-1]) * np.diff(grid)) / cdf[-1]
    second = (
        np.sum(0.5 * (grid[1:] ** 2 * pdf[1:] + grid[:-1] ** 2 * pdf[:-1]) * np.diff(grid))
        / cdf[-1]
    )
    return grid, cdf / cdf[-1], mean, second - mean**2


def _pair_ab(r):
    """Vectorised RPY pair tensor mu_12 = a I + c rhat rhat, written from docs/model.md."""
    far = r >= 1.0
    rs = np.where(far, r, 1.0)
    a = np.where(far, 3 / (8 * rs) * (1 + 1 / (6 * rs**2)), 1 - 9 * r / 16)
    c = np.where(far, 3 / (8 * rs) * (1 - 1 / (2 * rs**2)), 3 * r / 16)
    return a, c


class DimerEnsemble:
    """M independent harmonic dimers stored as one (2M, 3) array (beads 2k and 2k+1).

    ``rhs`` is mu F per dimer; ``noise`` is B xi with B B^T = [[I, mu_12], [mu_12, I]]
    per dimer, from the centre-of-mass / relative decomposition (B = Q diag(S+, S-),
    S+-^2 = I +- mu_12). The dimers do not interact: each sees only its own mobility.
    """

    @staticmethod
    def _geometry(y):
        d = y[1::2] - y[0::2]
        r = np.linalg.norm(d, axis=1)
        return d / r[:, None], r

    def rhs(self, y):
        u, r = self._geometry(y)
        f2 = -K_SPRING * (r - R0)[:, None] * u
        a, c = _pair_ab(r)
        mu12_f1 = a[:, None] * (-f2) + (c * np.sum(u * -f2, axis=1))[:, None] * u
        mu12_f2 = a[:, None] * f2 + (c * np.sum(u * f2, axis=1))[:, None] * u
        v = np.empty_like(y)
        v[0::2] = -f2 + mu12_f2
        v[1::2] = f2 + mu12_f1
        return v

    def noise(self, y, rng):
        u, r = self._geometry(y)
        a, c = _pair_ab(r)
        xi = rng.standard_normal(y.shape)

        def root(sign, v):  # (I + sign mu_12)^(1/2) v
            s_perp = np.sqrt(1 + sign * a)
            s_par = np.sqrt(1 + sign * (a + c))
            return s_perp[:, None] * v + ((s_par - s_perp) * np.sum(u * v, axis=1))[:, None] * u

        p, m = root(1.0, xi[0::2]), root(-1.0, xi[1::2])
        out = np.empty_like(y)
        out[0::2] = (p + m) / math.sqrt(2)
        out[1::2] = (p - m) / math.sqrt(2)
        return out


def test_dimer_ensemble_helpers_match_the_engine():
    """The vectorised dimer mobility, velocity and noise covariance equal knotmm's."""
    rng = np.random.default_rng(1)
    ens = DimerEnsemble()
    for r in (0.4, 0.99, 1.0, 1.7):
        direction = rng.standard_normal(3)
        y = np.array([[0.1, -0.2, 0.3], [0.1, -0.2, 0.3]])
        y[1] += r * direction / np.linalg.norm(direction)
        u, _ = ens._geometry(y)
        f2 = -K_SPRING * (r - R0) * u[0]
        np.testing.assert_allclose(ens.rhs(y), rpy_velocities(y, np.array([-f2, f2])), atol=1e-12)
        # B B^T: apply B to the 6 unit vectors through xi
        cols = []
        for k in range(6):
            e = np.zeros((2, 3))
            e.flat[k] = 1.0

            class Unit:
                def standard_normal(self, shape, e=e):
                    return e

            cols.append(ens.noise(y, Unit()).reshape(-1))
        b = np.array(cols).T
        np.testing.assert_allclose(b @ b.T, rpy_matrix(y), atol=1e-12)


def dimer_ensemble_run(cls, n_dimers, h, duration, seed):
    """Start every dimer at r = r0 (out of equilibrium), run, return the bond lengths."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((n_dimers, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    y = np.empty((2 * n_dimers, 3))
    y[0::2] = -0.5 * R0 * u
    y[1::2] = 0.5 * R0 * u
    ens = DimerEnsemble()
    integ = cls(h, peclet=1.0 / KT, seed=seed, noise=ens.noise)
    for _ in range(int(round(duration / h))):
        y, _ = integ.step(ens.rhs, y)
    return ens._geometry(y)[1]


def check_boltzmann(r, n_independent, variance_bias=0.0):
    grid, cdf, mean, var = boltzmann_cdf()
    ks = stats.kstest(r, lambda s: np.interp(s, grid, cdf)).statistic
    assert ks < ks_critical(n_independent), ks
    se_mean = math.sqrt(var / n_independent)
    assert abs(r.mean() - mean) < 5 * se_mean, (r.mean(), mean, se_mean)
    se_var = var * math.sqrt(2.0 / n_independent)  # near-Gaussian bond length
    assert abs(r.var() - var) < 5 * se_var + variance_bias * var, (r.var(), var)
    return ks, r.mean(), mean, se_mean, r.var(), var, se_var


@pytest.mark.parametrize("cls", [EulerMaruyama, ItoHeun])
def test_dimer_bond_length_is_boltzmann_with_hi(cls):
    """4000 dimers relax from r = r0 to p(r) ~ r^2 exp(-U/kT) under RPY dynamics.

    k = 4 F0/d, r0 = 1 d, kT = 1: bond lengths span both RPY branches (r < d and r > d).
    The relaxation rate k mu_rel(r) lies between ~1 and 5 / tau_d; 3 tau_d relax the
    distribution and h = 0.01 biases the variance by at most h lambda / 2 ~ 2.5% (EM).
    """
    r = dimer_ensemble_run(cls, 4000, 0.01, 3.0, seed=2)
    check_boltzmann(r, len(r), variance_bias=0.03)


@pytest.mark.slow
@pytest.mark.parametrize("cls", [EulerMaruyama, ItoHeun])
def test_dimer_bond_length_is_boltzmann_with_hi_slow(cls):
    r = dimer_ensemble_run(cls, 20_000, 0.004, 4.0, seed=3)
    check_boltzmann(r, len(r), variance_bias=0.012)


def dimer_time_series(name, noise, samples, spacing, h, seed):
    """One dimer through knotmm's own noise generator: bond length every ``spacing`` steps."""
    integ = make(name, h, peclet=1.0 / KT, seed=seed, noise=noise)

    def rhs(y):
        d = y[1] - y[0]
        r = np.linalg.norm(d)
        f2 = -K_SPRING * (r - R0) * d / r
        return rpy_velocities(y, np.array([-f2, f2]))

    y = np.array([[0.0, 0.0, 0.0], [R0, 0.0, 0.0]])
    for _ in range(3 * spacing):  # relax
        y, _ = integ.step(rhs, y)
    out = np.empty(samples)
    for k in range(samples):
        for _ in range(spacing):
            y, _ = integ.step(rhs, y)
        out[k] = np.linalg.norm(y[1] - y[0])
    return out


def test_dimer_time_average_is_boltzmann():
    """The same through knotmm's Cholesky noise, time-averaged on one dimer.

    Samples 2 tau_d apart (several relaxation times at the typical bond length) count as
    independent; 250 samples give a loose but honest check (the slow test takes 2000, and
    also runs the Lanczos noise).
    """
    r = dimer_time_series("ito_heun", "cholesky", 250, 200, 0.01, seed=4)
    check_boltzmann(r, len(r), variance_bias=0.02)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("name", "noise"),
    [("euler_maruyama", "cholesky"), ("ito_heun", "cholesky"), ("ito_heun", "lanczos")],
)
def test_dimer_time_average_is_boltzmann_slow(name, noise):
    if noise == "cholesky":
        r = dimer_time_series(name, noise, 2000, 400, 0.005, seed=5)
    else:  # ~1 ms per Lanczos sample even for 6 dimensions: fewer samples
        r = dimer_time_series(name, noise, 300, 200, 0.01, seed=5)
    check_boltzmann(r, len(r), variance_bias=0.02)


# -- through the real Simulation --------------------------------------------------------------
def regular_ring(n_beads, bond=0.6):
    radius = bond / (2 * math.sin(math.pi / n_beads))
    t = 2 * math.pi * np.arange(n_beads) / n_beads
    return np.stack([radius * np.cos(t), radius * np.sin(t), np.zeros(n_beads)], axis=1)


def ring_com_msd(repeats, steps, h, peclet, seed, n_beads=12, integrator="euler_maruyama"):
    cfg = RunConfig.from_dict(
        {
            "model": {"gravity": 0.0},
            "run": {
                "peclet": peclet,
                "integrator": integrator,
                "timestep": h,
                "seed": seed,
                "noise": "cholesky",
            },
        }
    )
    from knotmm.dynamics.registry import integrator_from_config

    model = ChainModel.from_config(cfg)
    assert model.gravity == 0.0
    start = regular_ring(n_beads)
    sim = Simulation(start, model, integrator_from_config(cfg), platform="Reference")
    # no gravity: internal forces only, which sum to zero
    assert np.abs(sim.forces(start).sum(axis=0)).max() < 1e-9
    disp = np.empty((repeats, 3))
    t = steps * h
    for k in range(repeats):
        sim.set_positions(start)
        t0 = sim.time
        if integrator == "euler_maruyama":
            sim.step(steps)
        else:  # an adaptive method takes its own steps and lands on t
            sim.run(t)
        assert sim.time - t0 == pytest.approx(t)
        disp[k] = sim.positions.mean(axis=0) - start.mean(axis=0)
    kt = 1.0 / peclet
    m = rpy_matrix(start)
    # Kirkwood short-time COM diffusion: D_com = kT/N^2 sum_ij mu_ij (per component)
    d_com = np.array([m[k::3, k::3].sum() for k in range(3)]) / n_beads**2
    return disp, kt, t, d_com


@pytest.mark.parametrize("integrator", [
    "euler_maruyama", pytest.param("ito_heun_adaptive", marks=pytest.mark.slow)])
def test_ring_com_diffusion_through_simulation(integrator):
    """A 12-bead ring (gravity 0 from [model] gravity = 0.0): COM short-time diffusion.

    The ring is symmetric, so its internal forces move the centre of mass only at second
    order; over t = 0.002 tau_d the COM displacement variance per component is
    2 kT t D_com with D_com = sum_ij mu_ij / N^2 (0.444 in-plane and 0.370 along z here,
    against 1/12 = 0.083 without hydrodynamic interactions). The 2% allowance covers the
    coupling of the internal forces to the noise during t (O(lambda t)); the slow version
    (1.3% standard errors) sees none.
    """
    repeats = 1500
    disp, kt, t, d_com = ring_com_msd(repeats, 4, 5e-4, 4.0, seed=6, integrator=integrator)
    for k in range(3):
        expected = 2 * kt * t * d_com[k]
        se = expected * math.sqrt(2.0 / repeats)
        assert abs(np.mean(disp[:, k] ** 2) - expected) < 5 * se + 0.02 * expected, k
    assert np.all(np.abs(disp.mean(axis=0)) < 5 * np.sqrt(2 * kt * t * d_com / repeats))


@pytest.mark.slow
def test_ring_com_diffusion_through_simulation_slow():
    repeats = 12_000
    disp, kt, t, d_com = ring_com_msd(repeats, 4, 5e-4, 4.0, seed=7)
    for k in range(3):
        expected = 2 * kt * t * d_com[k]
        se = expected * math.sqrt(2.0 / repeats)
        assert abs(np.mean(disp[:, k] ** 2) - expected) < 5 * se + 0.02 * expected, k
