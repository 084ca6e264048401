"""The plugin's Cholesky factor through LAPACK (scipy's dpotrf) against its built-in routine."""

from __future__ import annotations

import numpy as np
import pytest

import knotmm.plugin as kp
from knotmm.dynamics.mobility import rpy_matrix
from knotmm.plugin import RPYIntegrator
from knotmm.shapes import torus_knot


def compact_coil(n, seed=4):
    """Beads of a random walk with 0.7 d steps: many pairs overlap (r < d, the near branch)."""
    rng = np.random.default_rng(seed)
    steps = rng.standard_normal((n, 3))
    return np.cumsum(0.7 * steps / np.linalg.norm(steps, axis=1, keepdims=True), axis=0)


def test_a_stochastic_integrator_switches_lapack_on():
    RPYIntegrator(0.01, "ito_heun", kT=0.5)
    assert kp.use_lapack_cholesky()
    assert kp.rpyplugin.getCholeskyRoutine() != 0


@pytest.mark.parametrize("positions", [torus_knot(2, 3, 90), compact_coil(90)],
                         ids=["torus", "coil"])
def test_lapack_factor_equals_builtin_factor(positions):
    m = rpy_matrix(positions)
    assert kp.use_lapack_cholesky()
    lapack = kp.rpyplugin.choleskyFactor(m, False)
    builtin = kp.rpyplugin.choleskyFactor(m, True)
    scale = np.abs(builtin).max()
    assert np.abs(lapack - builtin).max() <= 1e-12 * scale
    # both are the lower factor (upper triangle exactly zero) of m
    assert not np.triu(lapack, 1).any() and not np.triu(builtin, 1).any()
    np.testing.assert_allclose(lapack @ lapack.T, m, rtol=0, atol=1e-13)
    np.testing.assert_allclose(lapack, np.linalg.cholesky(m), rtol=0, atol=1e-12 * scale)


@pytest.mark.parametrize("builtin", [False, True])
def test_not_positive_definite_is_refused(builtin):
    kp.use_lapack_cholesky()
    with pytest.raises(ValueError, match="not positive definite"):
        kp.rpyplugin.choleskyFactor(np.diag([1.0, -1.0, 2.0]), builtin)
