"""benchmarks/numba_brownian.py (issue 12's Brownian yardstick) is knotmm's Brownian model.

The hand-written numba + LAPACK program must take knotmm's steps (same dense RPY matrix,
same Cholesky noise, same schemes), or the benchmark's ratio would compare different
programs; and on its own it must sample Boltzmann's distribution (a check that does not go
through knotmm).
"""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from knotmm.dynamics.brownian import EulerMaruyama, ItoHeun, LeimkuhlerMatthews
from knotmm.dynamics.mobility import rpy_matrix
from knotmm.dynamics.noise import cholesky_noise
from knotmm.engine.simulation import Simulation
from knotmm.shapes import torus_knot

_BENCH = Path(__file__).resolve().parents[2] / "benchmarks"


def _load(name):
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, _BENCH / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module  # numba's cache looks the module up by name
        spec.loader.exec_module(module)
    return sys.modules[name]


@pytest.fixture(scope="module")
def nb():
    _load("numba_chain")
    return _load("numba_brownian")


@pytest.mark.parametrize("scale", [1.0, 0.45], ids=["template", "shrunk"])
def test_rpy_matrix_equals_knotmm(nb, scale):
    """Both branches (r >= d and the overlap form r < d); bead-major order."""
    x = torus_knot(2, 3, 40) * scale
    m = np.empty((120, 120))
    nb.rpy_matrix(x, m)
    expected = rpy_matrix(x)
    assert np.max(np.abs(m - expected)) < 1e-14
    d = np.linalg.norm(x[:, None] - x[None], axis=-1)
    assert (d[d > 0] < 1).any() and (d > 1).any()


class _Fed:
    """knotmm noise callable that uses the given standard normals, one row per call."""

    def __init__(self, xi):
        self.xi = iter(xi)

    def __call__(self, y, rng):
        return cholesky_noise(y, xi=next(self.xi))


@pytest.mark.parametrize("scheme, cls, dt", [("euler_maruyama", EulerMaruyama, 0.002),
                                             ("ito_heun", ItoHeun, 0.002),
                                             ("leimkuhler_matthews", LeimkuhlerMatthews, 0.01)])
def test_steps_equal_knotmm_with_the_same_normals(nb, scheme, cls, dt):
    """20 steps from the N = 90 template at Pe = 2 (gravity on), Reference platform:
    the same normals fed to both give the same positions to 1e-12 d."""
    x = torus_knot(2, 3, 90)
    steps = 20
    rows = steps + (scheme == "leimkuhler_matthews")
    xi = np.random.default_rng(5).standard_normal((rows, 270))
    sim = Simulation(x, integrator=cls(dt, peclet=2.0, noise=_Fed(xi)), platform="Reference")
    sim.step(steps)
    p = nb.parameters()
    got = nb.run(scheme, x, p, 0.5, dt, steps, xi=xi)
    assert np.max(np.abs(got - sim.positions)) < 1e-12
    quiet = nb.run(scheme, x, p, 0.0, dt, steps, xi=xi)  # the noise mattered
    assert np.max(np.abs(got - quiet)) > 1e-2


def _boltzmann_variance(stiffness, rest, kt):
    """Variance of one side of a harmonic triangle: ``p(l) ~ l exp(-B (l - l0)^2 / (2 kT))``.

    Three points in space have the measure ``l1 l2 l3 dl1 dl2 dl3`` in their side lengths;
    far from the triangle inequality each side's marginal is ``l`` times the Gaussian.
    """
    sd = math.sqrt(kt / stiffness)
    grid = np.linspace(rest - 12 * sd, rest + 12 * sd, 100_001)
    w = grid * np.exp(-stiffness * (grid - rest) ** 2 / (2 * kt))
    mean = np.sum(w * grid) / np.sum(w)
    return float(np.sum(w * (grid - mean) ** 2) / np.sum(w))


def test_triangle_bond_variance_is_boltzmann(nb):
    """Three beads, harmonic sides (l0 = 0.6 d, B = 200 F0/d), nothing else, kT = 1 F0 d
    (sd 0.071 d): ito_heun at h = 2e-4 tau_d (h lambda <= 0.06 for the stiffest mode: bias
    below 0.1 %) samples the side-length variance of the Boltzmann distribution, which
    the RPY coupling (here 0.45 of two free beads' relative mobility along a side) does not
    change. A noise with the wrong scale or covariance misses it by tens of per cent."""
    p = nb.parameters(bond_stiffness=200.0, bending_stiffness=0.0, lj_epsilon=0.0, gravity=0.0)
    x = np.array([[0.0, 0.0, 0.0], [0.6, 0.0, 0.0], [0.3, 0.52, 0.0]])
    x = nb.run("ito_heun", x, p, 1.0, 2e-4, 500, seed=1)
    chunks, every = 12_000, 60
    sides = np.empty((chunks, 3))
    for k in range(chunks):
        x = nb.run("ito_heun", x, p, 1.0, 2e-4, every, seed=k + 2)
        sides[k] = np.linalg.norm(np.roll(x, -1, axis=0) - x, axis=1)
    ref = _boltzmann_variance(200.0, 0.6, 1.0)
    blocks = [b.var() / ref for b in np.array_split(sides, 20)]
    ratio, se = np.mean(blocks), np.std(blocks, ddof=1) / math.sqrt(len(blocks))
    assert abs(ratio - 1) < max(4 * se, 0.01) and abs(ratio - 1) < 0.03, (ratio, se)
    assert abs(sides.mean() - (0.6 + 1.0 / (200 * 0.6))) < 0.003  # l weighting: mean + 0.008


def test_command_line_prints_one_summary(nb, tmp_path, capsys):
    """``--start t.npy`` runs the scheme's default step and prints one summary line."""
    np.save(tmp_path / "t.npy", torus_knot(2, 3, 40))
    nb.main(["--start", str(tmp_path / "t.npy"), "--scheme", "leimkuhler_matthews",
             "--duration", "0.1", "--gravity", "0"])
    out = capsys.readouterr().out.strip().splitlines()
    assert len(out) == 1
    assert "N=40 leimkuhler_matthews dt=0.01 Pe=2 steps=10" in out[0]


def test_probe_heun_baseline_samples_boltzmann(nb):
    """benchmarks/probe_fsal_brownian.py: its adaptive Heun branch (the plugin's
    ito_heun_adaptive control, re-written in numba) gives the Boltzmann bond-length variance
    at Pe = 2, tolerance 0.02 d, within 3 % (the baseline its one-evaluation variant is
    compared with)."""
    probe = _load("probe_fsal_brownian")
    ratio, se, steps, evals = probe.main(["2", "0.02", "0", "12", "3"])
    assert abs(ratio - 1.0) < max(0.03, 4 * se), (ratio, se)
    assert 2 * steps < evals < 2.2 * steps  # two a step, one more per rejected try
