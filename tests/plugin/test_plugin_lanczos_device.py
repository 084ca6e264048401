"""Lanczos noise with its Krylov loop on the device (``plugin/platforms/common/src/
CommonRPYNoise.cpp``), on every device platform the plugin has a kernel on (OpenCL on pocl
here), in double and mixed precision; skipped with the reason where there is none.

- Covariance against the mobility: beads that feel no force, ``euler_maruyama`` with Lanczos
  noise (tolerance 1e-8), S = 3000 single steps of h from the same positions (set again before
  each step): ``dx = sqrt(2 kT h) B xi``, so ``Cov(dx) / (2 kT h)`` is the RPY matrix of
  ``tests/reference_model.py`` (``rpy_dense``, double loops). Each entry within 5 standard
  errors ``sqrt((mu_ii mu_jj + mu_ij^2) / S)`` of the sample covariance. Six beads, some
  overlapping (r < d).
- The normals are the stepper's counter-based stream's on every platform, so 20 Lanczos
  ``euler_maruyama`` steps of a ring of 40 agree with the Reference platform's host Lanczos
  (LanczosSqrt) to 1e-7 d: both stop at relative change 1e-8 and differ in the order of their
  sums and in the Gram-Schmidt passes.
"""

from __future__ import annotations

import numpy as np
import openmm
import pytest
import reference_model as rm
from plugin_helpers import positions_of

import knotmm.plugin as kp
from knotmm.engine.engines import DEVICE_PLATFORMS, plugin_platforms
from knotmm.model.system import chain_system

DEVICES = [name for name in plugin_platforms() if name in DEVICE_PLATFORMS]
PARAMS = [pytest.param((name, precision), id=f"{name}-{precision}")
          for name in DEVICES for precision in ("double", "mixed")]
device = pytest.mark.parametrize(
    "where", PARAMS or [pytest.param(None, marks=pytest.mark.skip(
        reason="no device platform has the plugin's kernel here (knotmm --version says why)"),
        id="none")])


def _context(system, integ, where):
    name, precision = where
    return openmm.Context(system, integ, openmm.Platform.getPlatformByName(name),
                          {"Precision": precision})


def _lanczos(h, seed):
    assert kp.use_lapack_cholesky()
    integ = kp.RPYIntegrator(h, "euler_maruyama", kT=1.0, seed=seed, noise="lanczos")
    integ.setLanczosTolerance(1e-8)
    return integ


@device
def test_device_lanczos_covariance_is_the_mobility(where):
    x0 = np.array([[0, 0, 0], [0.8, 0.1, 0], [1.5, 0.7, 0.3], [0.2, 1.6, -0.4],
                   [-1.1, 0.4, 0.9], [2.6, 0.2, -0.7]], dtype=float)
    n, samples, h = len(x0), 3000, 1e-3
    system = openmm.System()
    none = openmm.CustomExternalForce("0")
    for i in range(n):
        system.addParticle(1.0)
        none.addParticle(i, [])
    system.addForce(none)
    integ = _lanczos(h, 99)
    ctx = _context(system, integ, where)
    ctx.setPositions(x0)
    start = positions_of(ctx)
    d = np.empty((samples, 3 * n))
    for s in range(samples):
        ctx.setPositions(start)
        integ.step(1)
        d[s] = ((positions_of(ctx) - start) / np.sqrt(2.0 * h)).ravel()
    cov = np.cov(d, rowvar=False, bias=True)
    mu = rm.rpy_dense(start)
    se = np.sqrt((np.outer(np.diag(mu), np.diag(mu)) + mu**2) / samples)
    worst = float(np.max(np.abs(cov - mu) / se))
    assert worst < 5.0, f"sample covariance {worst:.2f} standard errors from mu"


@device
def test_device_lanczos_agrees_with_reference(where):
    x = rm.circle(40) + np.c_[np.zeros(40), np.zeros(40), 0.3 * np.cos(np.arange(40) * 0.3)]
    out = []
    for platform in ("Reference", where):
        integ = _lanczos(1e-3, 1234)
        system = chain_system(x)
        ctx = (openmm.Context(system, integ, openmm.Platform.getPlatformByName("Reference"))
               if platform == "Reference" else _context(system, integ, platform))
        ctx.setPositions(x)
        integ.step(20)
        out.append(positions_of(ctx))
    assert np.max(np.abs(out[0] - x)) > 0.05  # the noise moved the beads
    # double: the Reference's float64 force field against the device's float32 parameters
    # (about 1e-6 d over a few tau_d, test_plugin_platforms.py); 20 steps of 1e-3 stay far below
    assert np.max(np.abs(out[1] - out[0])) < 1e-7
