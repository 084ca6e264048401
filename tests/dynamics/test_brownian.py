"""Brownian dynamics: noise generators, stochastic integrators, configuration, restart.

The statistical checks of the fluctuation-dissipation balance are in
``test_brownian_fdt.py``; the tilt and flip analysis in ``test_brownian_tilt.py``. Every
random test uses a fixed seed, and every statistical tolerance is set from the number of
samples (a few standard errors, or a Kolmogorov-Smirnov critical value at a tiny level), so
nothing here is flaky.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import scipy.linalg
import tomli_w
from scipy import stats

from knotmm.config import RunConfig
from knotmm.dynamics.brownian import EulerMaruyama, ItoHeun, thermal_energy
from knotmm.dynamics.deterministic import RK23, Euler, Heun
from knotmm.dynamics.mobility import rpy_matrix, rpy_velocities
from knotmm.dynamics.noise import (
    CHOLESKY_MAX_BEADS,
    LanczosConvergenceError,
    NoiseError,
    NoiseGenerator,
    cholesky_noise,
    lanczos_noise,
    lanczos_sqrt,
    mobility_cholesky,
    noise_rng,
)
from knotmm.dynamics.registry import BROWNIAN_NAMES, integrator_from_config, make
from knotmm.errors import ConfigError, SimulationFault

if __import__("sys").version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

#: Five beads with pairs in both branches of the RPY tensor (r < d and r >= d).
FIVE = np.array(
    [[0.0, 0.0, 0.0], [0.7, 0.0, 0.0], [0.7, 1.3, 0.2], [-0.5, 0.4, 1.1], [2.5, -1.0, 0.3]]
)


def random_chain(n, seed=3, bond=0.6):
    """A random walk of n beads with bonds of 0.6 d (overlapping neighbours, r < d)."""
    rng = np.random.default_rng(seed)
    steps = rng.standard_normal((n, 3))
    steps *= bond / np.linalg.norm(steps, axis=1, keepdims=True)
    return np.cumsum(steps, axis=0)


def ks_critical(n, m=None, alpha=1e-6):
    """Asymptotic Kolmogorov-Smirnov critical distance at level ``alpha``."""
    c = math.sqrt(-math.log(alpha / 2.0) / 2.0)
    return c * (math.sqrt((n + m) / (n * m)) if m else 1.0 / math.sqrt(n))


def bonferroni_z(n_tests, alpha=1e-4):
    """Two-sided normal quantile that keeps the family-wise false-alarm rate at ``alpha``."""
    return float(stats.norm.isf(alpha / (2.0 * n_tests)))


# -- the physics the "no drift" rests on ------------------------------------------------------
def numerical_divergence(matrix, x, eps=1e-6):
    """``sum_j d/dr_j . M_ij`` for every bead i, shape (3 n_beads,), by central differences."""
    n = x.shape[0]
    div = np.zeros(3 * n)
    for j in range(n):
        for b in range(3):
            xp, xm = x.copy(), x.copy()
            xp[j, b] += eps
            xm[j, b] -= eps
            div += (matrix(xp) - matrix(xm))[:, 3 * j + b] / (2 * eps)
    return div


def isotropic_part(x):
    """RPY with every pair block replaced by its isotropic part (trace/3) I: not div-free."""
    m = rpy_matrix(x)
    n = x.shape[0]
    for i in range(n):
        for j in range(n):
            if i != j:
                block = m[3 * i : 3 * i + 3, 3 * j : 3 * j + 3]
                m[3 * i : 3 * i + 3, 3 * j : 3 * j + 3] = np.trace(block) / 3 * np.eye(3)
    return m


def test_rpy_divergence_is_zero():
    """sum_j d/dr_j . mu_ij = 0 in both branches: Ito dynamics needs no drift term."""
    div = numerical_divergence(rpy_matrix, FIVE)
    # each derivative is O(1); rounding of the difference quotients is ~1e-10
    assert np.max(np.abs(div)) < 1e-7
    # the same finite differences do see a divergence where there is one
    assert np.max(np.abs(numerical_divergence(isotropic_part, FIVE))) > 1e-2


def test_thermal_energy():
    assert thermal_energy(math.inf) == 0.0
    assert thermal_energy(2.0) == 0.5
    with pytest.raises(ConfigError, match="run.peclet"):
        thermal_energy(0.0)


# -- noise generators -------------------------------------------------------------------------
def test_cholesky_noise_is_L_xi_bead_major(rng):
    xi = rng.standard_normal(15)
    m = rpy_matrix(FIVE)
    L = mobility_cholesky(FIVE)
    np.testing.assert_allclose(L @ L.T, m, atol=1e-12)
    assert np.allclose(np.triu(L, 1), 0.0)
    out = cholesky_noise(FIVE, xi=xi)
    assert out.shape == (5, 3)
    np.testing.assert_allclose(out.reshape(-1), np.linalg.cholesky(m) @ xi, atol=1e-12)
    # bead-major: bead 0's block is driven only by the first three numbers
    e = np.zeros(15)
    e[:3] = [1.0, 2.0, 3.0]
    np.testing.assert_allclose(cholesky_noise(FIVE, xi=e)[0], L[:3, :3] @ e[:3])


def test_cholesky_noise_covariance_is_mobility():
    """Sample covariance of 4000 draws vs rpy_matrix, each entry within its error bars."""
    s = 4000
    gen = np.random.default_rng(11)
    samples = np.array([cholesky_noise(FIVE, gen).reshape(-1) for _ in range(s)])
    m = rpy_matrix(FIVE)
    cov = samples.T @ samples / s  # the mean is known to be zero
    # Isserlis: var(x_i x_j) = M_ii M_jj + M_ij^2
    se = np.sqrt((np.outer(np.diag(m), np.diag(m)) + m**2) / s)
    z = (cov - m) / se
    iu = np.triu_indices(15)
    assert np.max(np.abs(z[iu])) < bonferroni_z(len(iu[0]))
    # whole-distribution check: x^T M^-1 x is chi-square with 15 degrees of freedom
    q = np.einsum("si,ij,sj->s", samples, np.linalg.inv(m), samples)
    assert abs(q.mean() - 15) < 5 * math.sqrt(2 * 15 / s)
    assert stats.kstest(q, stats.chi2(15).cdf).statistic < ks_critical(s)


def test_cholesky_noise_singular_mobility_raises():
    x = np.array([[0.0, 0, 0], [0.0, 0, 0], [1.0, 0, 0]])
    with pytest.raises(NoiseError, match="run.noise"):
        cholesky_noise(x, np.random.default_rng(0))
    assert issubclass(NoiseError, SimulationFault)


@pytest.mark.parametrize("n_beads", [5, 40])
def test_lanczos_converges_to_symmetric_square_root(n_beads, rng):
    """Same xi: the Lanczos iterate approaches sqrtm(M) xi as the tolerance shrinks."""
    x = FIVE if n_beads == 5 else random_chain(n_beads)
    m = rpy_matrix(x)
    exact = scipy.linalg.sqrtm(m).real
    xi = rng.standard_normal(3 * n_beads)
    target = exact @ xi
    errors = []
    for tol in (1e-2, 1e-4, 1e-6, 1e-9):
        y = lanczos_noise(x, tolerance=tol, xi=xi).reshape(-1)
        err = np.linalg.norm(y - target) / np.linalg.norm(target)
        errors.append(err)
        assert err < 10 * tol + 1e-11, (tol, err)
    assert errors[-1] < 1e-8
    # the complete Krylov space gives the exact root (to rounding)
    y_full, iters = lanczos_sqrt(lambda v: m @ v, xi, tolerance=1e-300, max_iter=3 * n_beads)
    assert iters <= 3 * n_beads
    np.testing.assert_allclose(y_full, target, rtol=0, atol=1e-9 * np.linalg.norm(target))


def test_lanczos_is_matrix_free_and_reports_non_convergence(rng):
    x = random_chain(30)
    xi = rng.standard_normal(90)
    calls = []

    def matvec(v):
        calls.append(v.shape)
        return rpy_velocities(x, v.reshape(30, 3)).reshape(-1)

    y, iters = lanczos_sqrt(matvec, xi, tolerance=1e-6)
    assert len(calls) == iters and all(c == (90,) for c in calls)
    assert 5 < iters < 90
    with pytest.raises(LanczosConvergenceError, match="run.lanczos_tolerance"):
        lanczos_sqrt(matvec, xi, tolerance=1e-12, max_iter=4)
    assert np.all(lanczos_sqrt(matvec, np.zeros(90))[0] == 0.0)


def test_cholesky_and_lanczos_agree_in_distribution():
    """Both have covariance mu: chi-square of the Mahalanobis norm and two-sample KS tests."""
    x = random_chain(20, seed=5)
    m = rpy_matrix(x)
    m_inv = np.linalg.inv(m)
    s = 1500
    gen = NoiseGenerator("lanczos", tolerance=1e-3)  # loose: a real Krylov approximation
    g1, g2 = np.random.default_rng(21), np.random.default_rng(22)
    chol = np.array([cholesky_noise(x, g1).reshape(-1) for _ in range(s)])
    lanc = np.array([gen(x, g2).reshape(-1) for _ in range(s)])
    assert 3 < gen.last_iterations < 60
    dof = 60
    for samples in (chol, lanc):
        q = np.einsum("si,ij,sj->s", samples, m_inv, samples)
        assert abs(q.mean() - dof) < 5 * math.sqrt(2 * dof / s)
        assert stats.kstest(q, stats.chi2(dof).cdf).statistic < ks_critical(s)
    # projections on fixed directions, normalised by their exact standard deviation
    dirs = np.random.default_rng(7).standard_normal((6, 3 * 20))
    sd = np.sqrt(np.einsum("ki,ij,kj->k", dirs, m, dirs))
    for k in range(len(dirs)):
        a, b = chol @ dirs[k] / sd[k], lanc @ dirs[k] / sd[k]
        assert stats.ks_2samp(a, b).statistic < ks_critical(s, s)
        assert stats.kstest(b, "norm").statistic < ks_critical(s)


def test_noise_generator_selection():
    gen = NoiseGenerator("auto")
    assert gen.method_for(CHOLESKY_MAX_BEADS) == "cholesky"
    assert gen.method_for(CHOLESKY_MAX_BEADS + 1) == "lanczos"
    assert NoiseGenerator("lanczos").method_for(10) == "lanczos"
    assert NoiseGenerator("cholesky").method_for(10_000) == "cholesky"
    with pytest.raises(ConfigError, match="run.noise"):
        NoiseGenerator("svd")
    with pytest.raises(ConfigError, match="run.lanczos_tolerance"):
        NoiseGenerator("lanczos", tolerance=0.0)


def test_both_methods_advance_the_stream_alike():
    """A run may switch method on restart without shifting the noise sequence."""
    x = random_chain(12)
    r1, r2 = noise_rng(4), noise_rng(4)
    NoiseGenerator("cholesky")(x, r1)
    NoiseGenerator("lanczos")(x, r2)
    assert r1.bit_generator.state == r2.bit_generator.state


def test_noise_stream_independent_of_default_rng():
    a = noise_rng(1).standard_normal(5)
    b = np.random.default_rng(1).standard_normal(5)
    assert not np.allclose(a, b)
    np.testing.assert_array_equal(a, noise_rng(1).standard_normal(5))


# -- integrators: update equations ------------------------------------------------------------
class FixedNoise:
    """A noise 'generator' returning a given array (and counting its calls)."""

    def __init__(self, value):
        self.value = np.asarray(value, dtype=np.float64)
        self.calls = 0

    def __call__(self, positions, rng):
        self.calls += 1
        return self.value.copy()


def linear_rhs(rate):
    return lambda y: -rate * y


@pytest.mark.parametrize("cls", [EulerMaruyama, ItoHeun])
def test_update_equation(cls, rng):
    y0 = rng.standard_normal((4, 3))
    e = rng.standard_normal((4, 3))
    h, pe, lam = 0.01, 2.0, 3.0
    integ = cls(h, peclet=pe, seed=0, noise=FixedNoise(e))
    y1, dt = integ.step(linear_rhs(lam), y0)
    w = math.sqrt(2 * (1 / pe) * h) * e
    if cls is EulerMaruyama:
        expected = y0 - h * lam * y0 + w
    else:
        pred = y0 - h * lam * y0 + w
        expected = y0 + 0.5 * h * (-lam * y0 - lam * pred) + w
    assert dt == h
    np.testing.assert_allclose(y1, expected, rtol=1e-14, atol=1e-15)
    assert integ.noise.calls == 1 and integ.n_accepted == 1


@pytest.mark.parametrize(("cls", "det"), [(EulerMaruyama, Euler), (ItoHeun, Heun)])
def test_infinite_peclet_is_the_deterministic_method(cls, det, rng):
    y0 = rng.standard_normal((5, 3))

    def rhs(y):
        return np.sin(y) - 0.3 * y

    noise = FixedNoise(np.ones((5, 3)))
    a, _ = cls(0.02, peclet=math.inf, seed=1, noise=noise).step(rhs, y0)
    b, _ = det(0.02).step(rhs, y0)
    np.testing.assert_array_equal(a, b)
    assert noise.calls == 0


def test_clipped_step_scales_the_noise():
    e = np.ones((1, 3))
    integ = EulerMaruyama(0.01, peclet=1.0, noise=FixedNoise(e))
    y1, dt = integ.step(lambda y: np.zeros_like(y), np.zeros((1, 3)), max_dt=0.0025)
    assert dt == 0.0025
    np.testing.assert_allclose(y1, math.sqrt(2 * 0.0025) * e)


def _ou_coefficients(cls, h, lam):
    """(A, c): one step of the scheme on dy = -lam y dt + sqrt(2 kT) dW is y1 = A y0 + c xi."""
    unit = cls(h, peclet=1.0, noise=FixedNoise(np.zeros((1, 1))))
    a = unit.step(linear_rhs(lam), np.ones((1, 1)))[0].item()
    kick = cls(h, peclet=1.0, noise=FixedNoise(np.ones((1, 1))))
    c = kick.step(linear_rhs(lam), np.zeros((1, 1)))[0].item()
    return a, c


def test_weak_order_on_ornstein_uhlenbeck():
    """Additive noise: stationary variance error is O(h) for EM and O(h^2) for Ito-Heun.

    The schemes are linear here, so the stationary variance ``c^2 / (1 - A^2)`` of the
    numerical chain is exact (no sampling); it is compared with ``kT / k``.
    """
    lam = 1.0
    hs = np.array([0.04, 0.02, 0.01, 0.005])
    for cls, order, formula in (
        (EulerMaruyama, 1, lambda z: 2 / (2 - z)),
        (ItoHeun, 2, lambda z: (2 - z) / (2 - z + z * z / 2)),
    ):
        errs = []
        for h in hs:
            a, c = _ou_coefficients(cls, h, lam)
            ratio = c * c / (1 - a * a) / (1.0 / lam)
            assert ratio == pytest.approx(formula(h * lam), rel=1e-12)
            errs.append(abs(ratio - 1.0))
        slope = np.polyfit(np.log(hs), np.log(errs), 1)[0]
        assert slope == pytest.approx(order, abs=0.05), (cls.name, slope)
        # the mean decays as exp(-lam t) to the deterministic order
        a, _ = _ou_coefficients(cls, 0.01, lam)
        assert abs(a - math.exp(-0.01)) < 2 * 0.01 ** (order + 1)


# -- reproducibility and checkpoints ---------------------------------------------------------
def _trajectory(integ, steps, y0):
    def rhs(y):
        return rpy_velocities(y, -(y - y.mean(axis=0)) - [0, 0, 1.0])

    y = y0.copy()
    out = []
    for _ in range(steps):
        y, _ = integ.step(rhs, y)
        out.append(y)
    return np.array(out)


@pytest.mark.parametrize("name", BROWNIAN_NAMES)
def test_same_seed_same_trajectory(name):
    y0 = random_chain(8)
    a = _trajectory(make(name, 0.01, peclet=2.0, seed=5), 20, y0)
    b = _trajectory(make(name, 0.01, peclet=2.0, seed=5), 20, y0)
    c = _trajectory(make(name, 0.01, peclet=2.0, seed=6), 20, y0)
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)


@pytest.mark.parametrize("noise", ["cholesky", "lanczos"])
def test_state_round_trip_continues_the_same_noise(noise):
    """get_state -> JSON and TOML -> set_state on a fresh integrator: identical steps."""
    y0 = random_chain(8)
    ref = make("ito_heun", 0.01, peclet=2.0, seed=9, noise=noise)
    first = _trajectory(ref, 10, y0)
    state = ref.get_state()
    cont = _trajectory(ref, 10, first[-1])
    for encode, decode in ((json.dumps, json.loads), (tomli_w.dumps, tomllib.loads)):
        restored = make("ito_heun", 0.01, peclet=2.0, seed=12345, noise=noise)
        restored.set_state(decode(encode(state)))
        assert restored.n_accepted == 10
        np.testing.assert_array_equal(_trajectory(restored, 10, first[-1]), cont)


def test_state_is_plain_data():
    state = make("euler_maruyama", 0.01, peclet=2.0, seed=1).get_state()
    assert all(isinstance(v, (int, float, str)) for v in state.values())
    assert json.loads(state["rng_state"])["bit_generator"] == "PCG64"
    np.savez(__import__("io").BytesIO(), **{"s": np.array(json.dumps(state))})


# -- configuration ----------------------------------------------------------------------------
def test_config_keys():
    cfg = RunConfig.from_dict(
        {
            "run": {
                "peclet": 2.0,
                "integrator": "ito_heun",
                "noise": "lanczos",
                "lanczos_tolerance": 1e-5,
                "timestep": 0.002,
            }
        }
    )
    assert cfg["run.noise"] == "lanczos" and cfg["run.lanczos_tolerance"] == 1e-5
    default = RunConfig.from_dict({})
    assert default["run.noise"] == "auto" and default["run.lanczos_tolerance"] == 1e-6
    with pytest.raises(ConfigError, match="run.noise"):
        RunConfig.from_dict({"run": {"noise": "sqrtm"}})
    with pytest.raises(ConfigError, match="run.lanczos_tolerance"):
        RunConfig.from_dict({"run": {"lanczos_tolerance": 0.0}})


def test_integrator_from_config():
    cfg = RunConfig.from_dict(
        {
            "run": {
                "peclet": 2.0,
                "integrator": "ito_heun",
                "noise": "lanczos",
                "lanczos_tolerance": 1e-5,
                "timestep": 0.002,
                "seed": 17,
            }
        }
    )
    integ = integrator_from_config(cfg)
    assert isinstance(integ, ItoHeun)
    assert integ.kT == 0.5 and integ.timestep == 0.002 and integ.seed == 17
    assert integ.noise.method == "lanczos" and integ.noise.tolerance == 1e-5
    assert "Pe = 2" in integ.describe()
    np.testing.assert_array_equal(integ.rng.standard_normal(3), noise_rng(17).standard_normal(3))
    # deterministic runs are unchanged
    det = integrator_from_config(RunConfig.from_dict({}))
    assert isinstance(det, RK23) and det.tolerance == 1e-4
    # a Brownian integrator at Pe = inf is its deterministic counterpart
    em = integrator_from_config(RunConfig.from_dict({"run": {"integrator": "euler_maruyama"}}))
    assert em.kT == 0.0
    # finite Pe alone: integrator "auto" and no timestep or tolerance give ito_heun_adaptive,
    # first step 0.002 tau_d, tolerance 0.02 (10 / Pe)^0.5 d (0.02 d at Pe = 10)
    auto = integrator_from_config(RunConfig.from_dict({"run": {"peclet": 2.0}}))
    assert (auto.name, auto.timestep, auto.kT) == ("ito_heun_adaptive", 0.002, 0.5)
    assert auto.tolerance == pytest.approx(0.02 * 5**0.5, rel=1e-12)
    at_ten = integrator_from_config(RunConfig.from_dict({"run": {"peclet": 10.0}}))
    assert at_ten.tolerance == 0.02
    # ito_heun without a step gets 0.002 tau_d; an explicit step is kept; a deterministic
    # auto run keeps rk23 and 0.01 tau_d
    heun = integrator_from_config(RunConfig.from_dict({"run": {"peclet": 2.0,
                                                                "integrator": "ito_heun"}}))
    assert isinstance(heun, ItoHeun) and heun.timestep == 0.002
    kept = integrator_from_config(RunConfig.from_dict({"run": {"peclet": 2.0, "timestep": 1e-3,
                                                               "integrator": "ito_heun"}}))
    assert isinstance(kept, ItoHeun) and kept.timestep == 1e-3
    assert integrator_from_config(RunConfig.from_dict({})).timestep == 0.01
    # adaptive + finite Pe: one line naming the key and the fix
    with pytest.raises(ConfigError, match=r"run.integrator = 'rk23'.*ito_heun"):
        integrator_from_config(
            RunConfig.from_dict({"run": {"peclet": 2.0, "integrator": "rk23"}})
        )
    with pytest.raises(ConfigError, match="run.integrator"):
        make("rk23", 0.01, peclet=2.0, seed=1)


# -- through the Simulation and its checkpoint files ------------------------------------------
def _brownian_simulation(positions, seed):
    from knotmm.engine.simulation import Simulation
    from knotmm.model.system import ChainModel

    cfg = RunConfig.from_dict(
        {"run": {"peclet": 2.0, "integrator": "ito_heun", "timestep": 0.002, "seed": seed}}
    )
    return Simulation(
        positions, ChainModel.from_config(cfg), integrator_from_config(cfg), platform="Reference"
    )


def test_simulation_same_seed_same_trajectory_and_exact_resume(tmp_path, trefoil40):
    """Seeded runs repeat exactly; a checkpoint resumes the same noise."""
    from knotmm.engine.checkpoint import read_checkpoint

    a = _brownian_simulation(trefoil40, seed=3)
    b = _brownian_simulation(trefoil40, seed=3)
    a.step(10)
    b.step(10)
    np.testing.assert_array_equal(a.positions, b.positions)
    a.saveCheckpoint(tmp_path / "checkpoint.npz", {"frames": 0, "rows": 0})
    a.step(10)
    ckpt = read_checkpoint(tmp_path / "checkpoint.npz")
    resumed = _brownian_simulation(ckpt["positions"], seed=999)  # the seed is overridden
    resumed.integrator.set_state(ckpt["integrator_state"])
    resumed.step(10)
    np.testing.assert_array_equal(resumed.positions, a.positions)
    other = _brownian_simulation(trefoil40, seed=4)
    other.step(10)
    assert not np.allclose(other.positions, b.positions)
