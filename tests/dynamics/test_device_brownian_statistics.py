"""Brownian statistics of the plugin on every platform it runs on, Lanczos noise at N = 600.

Issue 32: on each OpenMM platform where the plugin has its kernel (Reference, CPU, and the
device platforms: OpenCL here on pocl, CUDA where a GPU is lent), a Brownian run with
Lanczos noise must sample the Boltzmann distribution and diffuse as the Kirkwood mobility
says. The system is 200 open trimers (600 beads: the noise is one Krylov approximation of
mu^(1/2) over the whole 1800 x 1800 mobility, the trimers coupled by hydrodynamics only),
5 d apart, gravity 0, kT = 1 (Pe = 1). Independent references, written here or in
``mc_reference.py``:

* statics: a trimer's bond-length standard deviation, mean bond cosine and mean 1-3 distance
  by quadrature over (r1, r2, theta) of exp(-E / kT) (``mc_reference.trimer_averages``;
  hydrodynamics leaves the Boltzmann distribution as it is), within issue 20's tolerances
  (2 %, 1 %, 1 %);
* diffusion: each trimer's centre-of-mass mean-square displacement over a short lag (0.002
  tau_d, from 8000 sampled configurations) against 6 kT D_K t, D_K = (1/9) sum_ij tr(mu_ij) / 3
  the Kirkwood mobility of its beads at the lag's start by the naive RPY tensor of
  ``reference_model.py`` (3 %, about three standard errors).

Slow (about a minute on the CPU platform, a few on pocl): ``python -m pytest -m slow``.
"""

from __future__ import annotations

import mc_reference as mc
import numpy as np
import pytest
import reference_model as rm

import knotmm.plugin as kp
from knotmm.dynamics.adaptive_brownian import AdaptiveItoHeun
from knotmm.engine.engines import DEVICE_PLATFORMS, plugin_platforms
from knotmm.engine.simulation import Simulation
from knotmm.model.layout import ChainLayout
from knotmm.model.system import ChainModel

TRIMERS = 200
KT = 1.0
BURN_IN, SAMPLE_EVERY, SAMPLES = 0.3, 0.05, 40
#: The lag of the short-time diffusion: a tenth of a trimer's internal relaxation time
#: (about 0.03 tau_d), so its shape, and the mobility, hardly change over it.
LAG = 0.002
#: Issue 20's tolerances (relative), as ``test_brownian_equilibrium.py``'s.
TARGETS = {"bond_sd": 0.02, "cos": 0.01, "d13": 0.01}

PLATFORMS = plugin_platforms() if kp.available() else ()
platforms = pytest.mark.parametrize(
    "platform", [pytest.param(n, id=n) for n in PLATFORMS]
    or [pytest.param(None, marks=pytest.mark.skip(reason=f"no plugin: {kp.load_error()}"),
                     id="none")])


def trimers() -> np.ndarray:
    grid = np.array([(i, j, k) for i in range(6) for j in range(6) for k in range(6)],
                    float)[:TRIMERS] * 5.0
    one = np.array([[0.0, 0.0, 0.0], [0.6, 0.0, 0.0], [1.2, 0.1, 0.0]])
    return (grid[:, None, :] + one[None]).reshape(-1, 3)


def sample(platform: str) -> tuple[np.ndarray, np.ndarray]:
    """Positions at the sample times and ``LAG`` after each, two arrays of shape
    (SAMPLES, TRIMERS, 3, 3)."""
    integ = AdaptiveItoHeun(peclet=1.0 / KT, seed=11, noise="lanczos")
    extra = {"precision": "double"} if platform in DEVICE_PLATFORMS else {}
    sim = Simulation(trimers(), ChainModel(gravity=0.0), integrator=integ, platform=platform,
                     engine="plugin", layout=ChainLayout((3,) * TRIMERS, (False,) * TRIMERS),
                     **extra)
    assert sim.engine == "plugin" and sim.platform_name == platform
    sim.run(BURN_IN)
    starts, ends = [], []
    for _ in range(SAMPLES):
        starts.append(sim.positions.copy())
        sim.run(LAG)
        ends.append(sim.positions.copy())
        sim.run(SAMPLE_EVERY - LAG)
    shape = (SAMPLES, TRIMERS, 3, 3)
    return np.array(starts).reshape(shape), np.array(ends).reshape(shape)


def kirkwood(trimer: np.ndarray) -> float:
    """(1/9) sum_ij tr(mu_ij) / 3 of one trimer (mu0 = 1), by the naive RPY tensor."""
    return sum(np.trace(rm.rpy_block(a, b) if i != j else np.eye(3)) / 3.0
               for i, a in enumerate(trimer) for j, b in enumerate(trimer)) / 9.0


@pytest.mark.slow
@platforms
def test_lanczos_brownian_statistics_and_diffusion(platform):
    x, after = sample(platform)
    exact = mc.trimer_averages(KT)
    b1 = np.linalg.norm(x[:, :, 1] - x[:, :, 0], axis=-1)
    b2 = np.linalg.norm(x[:, :, 2] - x[:, :, 1], axis=-1)
    bonds = np.concatenate([b1.ravel(), b2.ravel()])
    u, w = x[:, :, 1] - x[:, :, 0], x[:, :, 2] - x[:, :, 1]
    cos = (np.sum(u * w, axis=-1) / (b1 * b2)).ravel()
    d13 = np.linalg.norm(x[:, :, 2] - x[:, :, 0], axis=-1).ravel()
    got = {"bond_sd": bonds.std(), "cos": cos.mean(), "d13": d13.mean()}
    errors = {"bond_sd": bonds.std() / np.sqrt(2 * bonds.size),
              "cos": cos.std() / np.sqrt(cos.size), "d13": d13.std() / np.sqrt(d13.size)}
    for key, tol in TARGETS.items():
        assert abs(got[key] - exact[key]) < tol * abs(exact[key]), (
            platform, key, got[key], exact[key], errors[key])

    # short-time diffusion: E |dX_com|^2 = 6 kT D_K(x) t for each trimer from where it is
    step = np.sum((after.mean(axis=2) - x.mean(axis=2)) ** 2, axis=-1).ravel()
    d_k = np.array([kirkwood(t) for t in x.reshape(-1, 3, 3)])
    ratio = step.mean() / (6.0 * KT * LAG * d_k.mean())
    error = step.std() / step.mean() / np.sqrt(step.size)
    assert abs(ratio - 1.0) < 0.03, (platform, ratio, error)
