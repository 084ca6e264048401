"""The plugin's Lanczos noise: ``mu^(1/2) z`` against a dense square root and the Python engine's
Lanczos, the stream it draws, the Boltzmann bond of a stiff dimer, and exact resume.

References: ``scipy.linalg.sqrtm`` of the dense :func:`knotmm.dynamics.mobility.rpy_matrix`
(an independent square root), :func:`knotmm.dynamics.noise.lanczos_noise` (the Python
engine's Lanczos, the method the plugin reproduces), Boltzmann's distribution of the bond
(``test_plugin_lm.py``'s quadrature).
"""

from __future__ import annotations

import numpy as np
import openmm
import pytest
import scipy.linalg
from plugin_helpers import checkpoint_round_trip, dimer_system, plugin_context, positions_of
from test_plugin_lapack import compact_coil
from test_plugin_lm import KT, R0, H, K, batch_error, boltzmann

import knotmm.plugin as kp
from knotmm.dynamics.brownian import ItoHeun
from knotmm.dynamics.mobility import rpy_matrix
from knotmm.dynamics.noise import lanczos_noise
from knotmm.model.system import chain_system as build_system
from knotmm.plugin import RPYIntegrator, from_python_integrator, noise_settings
from knotmm.shapes import torus_knot

SHAPES = {"torus": torus_knot(2, 3, 60), "coil": compact_coil(60)}


@pytest.mark.parametrize("shape", SHAPES)
def test_lanczos_sqrt_is_the_symmetric_square_root(shape):
    """At tolerance 1e-8 the plugin's ``mu^(1/2) z`` equals ``sqrtm(mu) z`` to 1e-6 (relative),
    and the Python engine's Lanczos
    result to 1e-7 with about the same number of iterations (+- 3: near 1e-8 the change
    between iterates levels off, and rounding, which differs between the two pair loops,
    moves the iteration where it first falls below the tolerance)."""
    x = SHAPES[shape]
    kp.use_lapack_cholesky()
    z = np.random.default_rng(11).standard_normal(3 * len(x))
    dense = np.real(scipy.linalg.sqrtm(rpy_matrix(x))) @ z
    y, iterations = kp.rpyplugin.lanczosSqrt(x, z, 1e-8, 1.0, 1.0)
    assert y.shape == x.shape and 5 < iterations < 3 * len(x)
    assert np.linalg.norm(y.reshape(-1) - dense) <= 1e-6 * np.linalg.norm(dense)
    python = lanczos_noise(x, tolerance=1e-8, xi=z).reshape(-1)
    assert np.linalg.norm(y.reshape(-1) - python) <= 1e-7 * np.linalg.norm(python)
    from knotmm.dynamics.noise import _lanczos_mobility

    assert abs(_lanczos_mobility(x, z, 1e-8, None)[1] - iterations) <= 3


def test_lanczos_sqrt_scales_with_mu0_and_stops_on_an_invariant_space():
    """mu0 = 4 doubles the root; two beads (6 dimensions) finish in at most 6 iterations,
    exactly (to rounding); z = 0 gives 0 without a product."""
    x = np.array([[0.0, 0.0, 0.0], [1.3, 0.4, -0.2]])
    z = np.array([0.3, -1.0, 2.0, 0.7, 0.1, -0.5])
    exact = np.real(scipy.linalg.sqrtm(rpy_matrix(x))) @ z
    y, iterations = kp.rpyplugin.lanczosSqrt(x, z, 1e-14, 1.0, 4.0)
    assert iterations <= 6
    np.testing.assert_allclose(y.reshape(-1), 2 * exact, rtol=0, atol=1e-12)
    zero, used = kp.rpyplugin.lanczosSqrt(x, np.zeros(6), 1e-6, 1.0, 1.0)
    assert used == 0 and not zero.any()


def test_an_unreached_tolerance_raises_with_the_python_message():
    """270 unknowns, 200 iterations at most: a tolerance of 1e-30 is never met."""
    x = torus_knot(2, 3, 90)
    z = np.random.default_rng(2).standard_normal(270)
    with pytest.raises(openmm.OpenMMException, match="lanczos_tolerance = 1e-30 not reached"):
        kp.rpyplugin.lanczosSqrt(x, z, 1e-30, 1.0, 1.0)


def test_settings_defaults_checks_and_xml():
    integ = RPYIntegrator(0.01, "ito_heun", kT=0.5)
    assert integ.getNoiseMethod() == "cholesky" and integ.getLanczosTolerance() == 1e-6
    with pytest.raises(openmm.OpenMMException, match="noiseMethod='qr'"):
        integ.setNoiseMethod("qr")
    with pytest.raises(openmm.OpenMMException, match="lanczosTolerance"):
        integ.setLanczosTolerance(0.0)
    integ.setNoiseMethod("lanczos")
    integ.setLanczosTolerance(1e-7)
    xml = openmm.XmlSerializer.serialize(integ)
    assert 'noiseMethod="lanczos"' in xml and 'lanczosTolerance="1e-07"' in xml
    # the copy (an openmm.Integrator to Python) serialises to the same settings
    assert openmm.XmlSerializer.serialize(openmm.XmlSerializer.deserialize(xml)) == xml


@pytest.mark.parametrize(("noise", "beads", "method"), [
    ("auto", 300, "cholesky"), ("auto", 301, "lanczos"), ("lanczos", 10, "lanczos"),
    ("cholesky", 1000, "cholesky")])
def test_from_python_integrator_passes_the_noise_method(noise, beads, method):
    python = ItoHeun(0.002, peclet=2.0, seed=1, noise=noise, lanczos_tolerance=3e-7)
    assert noise_settings(python, beads) == (method, 3e-7)
    integ = from_python_integrator(python, n_beads=beads)
    assert integ.getNoiseMethod() == method and integ.getLanczosTolerance() == 3e-7
    # without the size "auto" is the plugin's default
    assert from_python_integrator(python).getNoiseMethod() == (
        "cholesky" if noise == "auto" else noise)


def far_apart_beads(n=3, gap=1e8):
    """``n`` beads ``gap`` d apart and no forces: mu = mu0 I to 4e-9, so L = mu^(1/2) nearly."""
    system = openmm.System()
    for _ in range(n):
        system.addParticle(1.0)
    return system, np.array([[gap * i, 0.0, 0.0] for i in range(n)])


@pytest.mark.parametrize("method", ["euler_maruyama", "ito_heun", "leimkuhler_matthews"])
def test_both_noise_methods_draw_the_same_normals(method):
    """Where the Cholesky factor and the symmetric root agree (mu = I to 4e-9), the two noise
    methods give the same trajectory from the same seed: both take 3N normals per sample."""
    out = {}
    for noise in ("cholesky", "lanczos"):
        system, x = far_apart_beads()
        integ = RPYIntegrator(0.01, method, kT=0.5, seed=5, noise=noise)
        ctx = plugin_context(system, x, integ)
        integ.step(20)
        out[noise] = positions_of(ctx) - x
    assert np.abs(out["cholesky"]).max() > 0.1  # it moved
    np.testing.assert_allclose(out["lanczos"], out["cholesky"], rtol=0, atol=1e-7)


def test_stiff_dimer_is_boltzmann_with_lanczos_noise():
    """leimkuhler_matthews with Lanczos noise at h lambda = 0.56 (``test_plugin_lm.py``'s
    dimer): bond-length mean and variance within 5 standard errors of Boltzmann's."""
    samples, every = 20_000, 5
    integ = RPYIntegrator(H, "leimkuhler_matthews", kT=KT, seed=23, noise="lanczos")
    ctx = plugin_context(dimer_system(K, R0), np.array([[0.0, 0.0, 0.0], [R0, 0.0, 0.0]]), integ)
    integ.step(100)
    lengths = np.empty(samples)
    for i in range(samples):
        integ.step(every)
        x = positions_of(ctx)
        lengths[i] = np.linalg.norm(x[1] - x[0])
    mean, var, _ = boltzmann(K, R0, KT)
    se_var = batch_error((lengths - mean) ** 2) / var
    assert abs(lengths.var() / var - 1) < 5 * se_var, (lengths.var() / var, se_var)
    assert abs(lengths.mean() - mean) < 5 * batch_error(lengths), (lengths.mean(), mean)


@pytest.mark.parametrize("method", ["ito_heun", "leimkuhler_matthews"])
def test_checkpoint_resumes_lanczos_runs_bit_for_bit(method):
    """Resume from a mid-run checkpoint into the same and into a fresh Context (the noise
    method is the integrator's setting, the stream is in the checkpoint): same positions bit
    for bit, and not those of the Cholesky noise."""
    x = torus_knot(2, 3, 40)
    system = build_system(x)
    a = RPYIntegrator(0.005, method, kT=0.5, seed=21, noise="lanczos")
    ctx_a = plugin_context(system, x, a)
    saved, first, again = checkpoint_round_trip(ctx_a, a, 0.05, 0.1)
    np.testing.assert_array_equal(again, first)
    b = RPYIntegrator(0.005, method, kT=0.5, seed=99, noise="lanczos")
    ctx_b = plugin_context(system, x, b)
    ctx_b.loadCheckpoint(saved)
    b.stepTo(0.1)
    np.testing.assert_array_equal(positions_of(ctx_b), first)
    b.setNoiseMethod("cholesky")
    ctx_b.loadCheckpoint(saved)
    b.stepTo(0.1)
    assert np.abs(positions_of(ctx_b) - first).max() > 1e-4



def test_lanczos_without_lapack_is_refused_in_one_line():
    """No built-in eigen-solver: without LAPACK's dstev, Lanczos noise says what to do."""
    kp.use_lapack_cholesky()
    kept = kp.rpyplugin.getTridiagonalEigenRoutine()
    kp.rpyplugin.setTridiagonalEigenRoutine(0)
    try:
        x = torus_knot(2, 3, 30)
        with pytest.raises(openmm.OpenMMException, match="needs LAPACK's dstev"):
            kp.rpyplugin.lanczosSqrt(x, np.ones(90), 1e-6, 1.0, 1.0)
    finally:
        kp.rpyplugin.setTridiagonalEigenRoutine(kept)
    assert kp.rpyplugin.getTridiagonalEigenRoutine() == kept != 0
