"""The plugin's Cholesky factor through LAPACK (scipy's dpotrf, and spotrf for the
single-precision noise factor) against its built-in routine and numpy's factor."""

from __future__ import annotations

import subprocess
import sys
import textwrap

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


def _in_a_fresh_interpreter(code: str) -> str:
    """Run ``code`` in a new Python (where scipy.linalg is not imported yet); its stdout."""
    done = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    return done.stdout.split()


def test_lapack_is_found_without_running_scipy_linalg_init():
    """The extension module is loaded from its file: scipy.linalg stays unimported, the
    routines are there, and a later package import gets the very same module."""
    out = _in_a_fresh_interpreter("""
        import sys
        import knotmm.plugin as kp
        module = kp._cython_lapack()
        print("scipy.linalg" in sys.modules)
        print(all(n in module.__pyx_capi__ for n in ("dpotrf", "spotrf", "dstev")))
        from scipy.linalg import cython_lapack
        print(cython_lapack is module)
    """)
    assert out == ["False", "True", "True"]


def test_lapack_falls_back_to_the_package_import_where_the_file_is_not_found():
    out = _in_a_fresh_interpreter("""
        import importlib.machinery, sys
        importlib.machinery.EXTENSION_SUFFIXES[:] = [".not-an-extension"]
        import knotmm.plugin as kp
        module = kp._cython_lapack()
        print("scipy.linalg" in sys.modules)
        print("dpotrf" in module.__pyx_capi__)
    """)
    assert out == ["True", "True"]


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


@pytest.mark.parametrize("positions", [torus_knot(2, 3, 90), compact_coil(90)],
                         ids=["torus", "coil"])
def test_single_precision_factor_is_the_factor_to_float_rounding(positions):
    """The factor a noise precision of "single" makes: float numbers (each one a float32
    exactly), the lower factor of the mobility to float32 rounding (numpy's double factor as
    the reference), and so a noise covariance L L^T within 1e-6 of mu."""
    m = rpy_matrix(positions)
    assert kp.use_lapack_cholesky() and kp.rpyplugin.getSingleCholeskyRoutine() != 0
    single = kp.rpyplugin.singleCholeskyFactor(m)
    exact = np.linalg.cholesky(m)
    scale = np.abs(exact).max()
    assert not np.triu(single, 1).any()
    np.testing.assert_array_equal(single, single.astype(np.float32).astype(np.float64))
    error = np.abs(single - exact).max()
    assert 1e-10 * scale < error <= 2e-6 * scale  # rounded as float32 is, no further
    np.testing.assert_allclose(single @ single.T, m, rtol=0, atol=1e-6 * np.abs(m).max())


def test_single_precision_factor_refuses_what_is_not_positive_definite():
    kp.use_lapack_cholesky()
    with pytest.raises(ValueError, match="not positive definite"):
        kp.rpyplugin.singleCholeskyFactor(np.diag([1.0, -1.0, 2.0]))


def test_noise_precision_setting_is_checked():
    integ = RPYIntegrator(0.01, "ito_heun", kT=0.5)
    assert integ.getNoisePrecision() == "auto"
    for value in ("single", "double", "auto"):
        integ.setNoisePrecision(value)
        assert integ.getNoisePrecision() == value
    with pytest.raises(Exception, match="noisePrecision='half'"):
        integ.setNoisePrecision("half")
