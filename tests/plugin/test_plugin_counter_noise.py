"""The plugin's counter-based noise (``plugin/stepper/include/knotmm/stepper/Philox.h``).

Normal j of draw d of a run seeded s is Box-Muller of the Philox4x64-10 block with counter
(j // 4, d, 0, 0) and key (s, 0). The references are independent of the plugin: numpy's own
Philox bit generator (``numpy.random.Philox``, the same cipher, counted from the other end),
Box-Muller written out here, the normal distribution's closed forms, and an Euler-Maruyama
integration written here with the naive RPY tensor (``tests/reference_model.py``) and numpy's
Cholesky factor, which every platform the plugin runs on must follow step for step.
"""

from __future__ import annotations

import numpy as np
import openmm
import pytest
import reference_model as rm
from plugin_helpers import checkpoint_round_trip, positions_of
from scipy import stats

import knotmm.plugin as kp
from knotmm.engine.engines import DEVICE_PLATFORMS, plugin_platforms
from knotmm.plugin import RPYIntegrator

MASK = (1 << 64) - 1


def philox_block(counter, key) -> np.ndarray:
    """Philox4x64-10(counter, key) by numpy: its generator adds one to the 256-bit counter
    before each block, so it starts one below."""
    c = (sum(int(v) << (64 * i) for i, v in enumerate(counter)) - 1) % (1 << 256)
    words = lambda value, n: np.array([(value >> (64 * i)) & MASK for i in range(n)],  # noqa: E731
                                      dtype=np.uint64)
    gen = np.random.Philox(counter=words(c, 4),
                           key=words(sum(int(v) << (64 * i) for i, v in enumerate(key)), 2))
    return gen.random_raw(4)


def naive_normals(seed: int, draw: int, count: int) -> np.ndarray:
    """The normals of draw ``draw``, Box-Muller of numpy's Philox words, one block at a time."""
    out = []
    for block in range(-(-count // 4)):
        w = philox_block((block, draw, 0, 0), (seed, 0))
        for radius, angle in ((w[0], w[1]), (w[2], w[3])):
            u = (float(int(radius) >> 11) + 1.0) * 2.0**-53
            v = float(int(angle) >> 11) * 2.0**-53
            r = np.sqrt(-2.0 * np.log(u))
            out += [r * np.cos(2 * np.pi * v), r * np.sin(2 * np.pi * v)]
    return np.array(out[:count])


def test_the_cipher_is_philox4x64_10():
    """The known-answer vector of Philox4x64-10 (counter 0, key 0) by numpy, as a check that the
    reference above is what it says."""
    words = philox_block((0, 0, 0, 0), (0, 0))
    assert [f"{int(w):016x}" for w in words] == [
        "16554d9eca36314c", "db20fe9d672d0fdc", "d7e772cee186176b", "7e68b68aec7ba23b"]


@pytest.mark.parametrize(("seed", "draw", "count"), [
    (7, 0, 1), (7, 3, 10), (1, 0, 90), (2**32 - 1, 123456789, 33), (2**63 + 5, 2**64 - 1, 12)])
def test_normals_are_philox_box_muller(seed, draw, count):
    got = kp.rpyplugin.counterNormals(seed, draw, count)
    np.testing.assert_allclose(got, naive_normals(seed, draw, count), rtol=1e-14, atol=1e-15)


def test_normals_are_standard_normal_and_independent():
    """6e5 normals from 2000 draws: moments, the distribution (Kolmogorov-Smirnov), and no
    correlation between neighbouring numbers of a draw, between draws, or between seeds."""
    draws = np.array([kp.rpyplugin.counterNormals(3, d, 300) for d in range(2000)])
    z = draws.ravel()
    n = z.size
    assert abs(z.mean()) < 4.5 / np.sqrt(n)
    assert abs(z.var() - 1.0) < 4.5 * np.sqrt(2.0 / n)
    assert abs(stats.skew(z)) < 4.5 * np.sqrt(6.0 / n)
    assert abs(stats.kurtosis(z)) < 4.5 * np.sqrt(24.0 / n)
    assert stats.kstest(z, "norm").pvalue > 1e-4
    for a, b in [(draws[:, :-1], draws[:, 1:]),        # neighbours in a draw (and in a block)
                 (draws[:, :-4], draws[:, 4:]),        # neighbouring blocks
                 (draws[:-1], draws[1:])]:             # consecutive draws
        r = np.corrcoef(a.ravel(), b.ravel())[0, 1]
        assert abs(r) < 4.5 / np.sqrt(a.size)
    other = np.array([kp.rpyplugin.counterNormals(4, d, 300) for d in range(2000)])
    assert abs(np.corrcoef(z, other.ravel())[0, 1]) < 4.5 / np.sqrt(n)


# --- a Brownian run on every platform against a naive integration ------------------------------

K_BOND, L0, KT, H, STEPS, SEED = 10.0, 0.75, 1.0, 1e-3, 100, 11  # float-exact parameters


def ring_system(n: int) -> openmm.System:
    """n beads joined in a ring by harmonic bonds k/2 (r - l0)^2; k and l0 are float32 numbers,
    so the device platforms, which keep parameters in float32, see the same model."""
    system = openmm.System()
    bonds = openmm.HarmonicBondForce()
    for i in range(n):
        system.addParticle(1.0)
        bonds.addBond(i, (i + 1) % n, L0, K_BOND)
    system.addForce(bonds)
    return system


def ring_forces(x: np.ndarray) -> np.ndarray:
    n = len(x)
    f = np.zeros_like(x)
    for i in range(n):
        j = (i + 1) % n
        d = x[j] - x[i]
        r = np.linalg.norm(d)
        pull = K_BOND * (r - L0) * d / r
        f[i] += pull
        f[j] -= pull
    return f


def naive_euler_maruyama(x: np.ndarray) -> np.ndarray:
    """STEPS steps of y1 = y + h mu F + sqrt(2 kT h) L xi, L L^T = mu (numpy's Cholesky), xi the
    normals of draw k at step k."""
    y = x.copy()
    for k in range(STEPS):
        mu = rm.rpy_dense(y)
        xi = naive_normals(SEED, k, y.size)
        v = (mu @ ring_forces(y).ravel()).reshape(y.shape)
        w = np.sqrt(2 * KT * H) * (np.linalg.cholesky(mu) @ xi).reshape(y.shape)
        y = y + H * v + w
    return y


PLATFORMS = plugin_platforms() if kp.available() else ()
#: How far (d) the 100 steps may be from the naive ones: double precision on Reference and the
#: device platforms (in double); the CPU platform's forces are single precision, and so is a
#: single-precision noise factor (L L^T = mu to about 1e-7: 5.4e-8 d after the 100 steps, measured).
TOLERANCE = {"Reference": 1e-10, "CPU": 1e-6}
SINGLE_FACTOR_TOLERANCE = 3e-7


def brownian_run(platform, x, noise_precision):
    """The positions after STEPS Euler-Maruyama steps from x on `platform` (a device in double
    precision, the CPU platform on one thread)."""
    kp.use_lapack_cholesky()
    integ = RPYIntegrator(H, "euler_maruyama", kT=KT, seed=SEED, noise="cholesky",
                          noise_precision=noise_precision)
    props = ({"Precision": "double"} if platform in DEVICE_PLATFORMS
             else {"Threads": "1"} if platform == "CPU" else {})
    ctx = openmm.Context(ring_system(12), integ, openmm.Platform.getPlatformByName(platform),
                         props)
    ctx.setPositions(x)
    integ.step(STEPS)
    return positions_of(ctx)


@pytest.mark.parametrize("noise_precision", ["double", "single"])
@pytest.mark.parametrize("platform", [pytest.param(p, id=p) for p in PLATFORMS]
                         or [pytest.param(None, marks=pytest.mark.skip(reason="no plugin"))])
def test_brownian_steps_follow_the_naive_integration(platform, noise_precision):
    """The first 100 Euler-Maruyama steps of a 12-bead ring, kT = 1, on each platform, are the
    naive integration's with the same counter-based normals: the noise does not depend on the
    platform (on a device the normals are made on the device); with the noise factor in single
    precision they stay within float rounding of it."""
    rng = np.random.default_rng(5)
    x = rm.circle(12, bond=L0) + rng.normal(scale=0.05, size=(12, 3))
    moved = np.abs(brownian_run(platform, x, noise_precision) - naive_euler_maruyama(x)).max()
    tolerance = TOLERANCE.get(platform, 1e-9)
    if noise_precision == "single":
        tolerance = max(tolerance, SINGLE_FACTOR_TOLERANCE)
    assert moved <= tolerance, f"{platform}, {noise_precision}: {moved:.3g} d from the naive run"


@pytest.mark.parametrize("platform", [pytest.param(p, id=p) for p in PLATFORMS]
                         or [pytest.param(None, marks=pytest.mark.skip(reason="no plugin"))])
def test_auto_noise_precision_follows_the_platforms_forces(platform):
    """"auto" (the default) factorises in single precision where the forces are single (the
    CPU platform) and in double where they are double (Reference, a device in double): the
    same steps, bit for bit, as the precision it stands for, and not those of the other."""
    x = rm.circle(12, bond=L0) + np.random.default_rng(6).normal(scale=0.05, size=(12, 3))
    runs = {p: brownian_run(platform, x, p) for p in ("auto", "single", "double")}
    same, other = ("single", "double") if platform == "CPU" else ("double", "single")
    np.testing.assert_array_equal(runs["auto"], runs[same])
    assert np.abs(runs["auto"] - runs[other]).max() > 0.0


@pytest.mark.parametrize("method", ["euler_maruyama", "ito_heun_adaptive"])
@pytest.mark.parametrize("platform", [pytest.param(p, id=p) for p in PLATFORMS]
                         or [pytest.param(None, marks=pytest.mark.skip(reason="no plugin"))])
def test_checkpoint_continues_the_counter_stream(method, platform):
    """A checkpoint holds the draw counter: the run continued from it is the uninterrupted run,
    bit for bit, on every platform."""
    x = rm.circle(12, bond=L0)
    integ = RPYIntegrator(H, method, 1e-3, kT=KT, seed=SEED)
    props = {"Precision": "double"} if platform in DEVICE_PLATFORMS else {}
    ctx = openmm.Context(ring_system(12), integ, openmm.Platform.getPlatformByName(platform),
                         props)
    ctx.setPositions(x)
    _, first, again = checkpoint_round_trip(ctx, integ, 0.05, 0.1)
    np.testing.assert_array_equal(again, first)
