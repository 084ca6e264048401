"""ito_heun_adaptive in the plugin: Boltzmann's distribution, the Wiener variance, exact resume.

Two beads held by a stiff anharmonic bond make error control reject and shorten steps; their
bond length must still follow ``r^2 exp(-U/kT)`` (quadrature). A third bead far from them
(10^6 d) and free of forces moves by ``sqrt(2 kT mu0) W(t)`` up to the hydrodynamic coupling
(``~ 3 d / (4 r) = 1e-6``): over seeds its displacement has the Wiener variance ``2 kT t``
however the steps were split and retried. (The plugin evaluates forces with the beads
shifted to their centre of mass, so the test's forces are translation invariant, as the
model's are.)
"""

from __future__ import annotations

import numpy as np
import openmm
import pytest
from plugin_helpers import plugin_context, positions_of

import knotmm.plugin as kp
from knotmm.model.system import ChainModel, chain_system
from knotmm.shapes.geometry import torus_knot

FAR = 1e6


def trapped_pair(k=400.0):
    """Beads 0 and 2 joined by a stiff bond ``k ((r-1)^2 + (r-1)^4)``; bead 1 free, FAR away."""
    system = openmm.System()
    for _ in range(3):
        system.addParticle(1.0)
    bond = openmm.CustomBondForce("k * ((r - 1)^2 + (r - 1)^4)")
    bond.addGlobalParameter("k", k)
    bond.addBond(0, 2, [])
    system.addForce(bond)
    return system, np.array([[0.0, 0.0, 0.0], [FAR, 0.0, 0.0], [1.3, 0.0, 0.0]])


def _run(tolerance, seed, kT=0.5, until=(0.25, 0.5, 1.0)):
    system, x = trapped_pair()
    integ = kp.rpyplugin.RPYIntegrator(0.01, "ito_heun_adaptive", tolerance)
    integ.setThermalEnergy(kT)
    integ.setRandomNumberSeed(seed)
    integ.setMaximumStepSize(0.05)
    ctx = plugin_context(system, x, integ)
    out = []
    for t in until:
        integ.stepTo(t)
        out.append(positions_of(ctx)[1] - x[1])
    return np.array(out), integ.getNumAcceptedSteps(), integ.getNumRejectedSteps()


def test_dimer_samples_boltzmann_despite_frequent_rejections():
    """Bond length of an anharmonic pair against r^2 exp(-U/kT) by quadrature (the mobility
    does not change the equilibrium), at a tolerance where many tries are rejected. The
    tolerance must stay well below the thermal spread of the stiffest mode: at 0.3 of it (a
    bond of sd 0.035 d at tolerance 0.01 d) the variance comes out 8 % low."""
    from scipy.integrate import quad

    kT, k = 1.0, 25.0  # bond sd 0.14 d, as the chain's at Pe = 1; tolerance 0.07 of it

    def u(r):
        return k * ((r - 1) ** 2 + (r - 1) ** 4)

    def moment(n):
        return quad(lambda r: r ** (2 + n) * np.exp(-u(r) / kT), 0.3, 2.0)[0]
    mean = moment(1) / moment(0)
    var = moment(2) / moment(0) - mean**2
    kp.use_lapack_cholesky()  # the same factor whatever ran before in this process
    system, x = trapped_pair(k)
    integ = kp.rpyplugin.RPYIntegrator(0.01, "ito_heun_adaptive", 0.01)
    integ.setThermalEnergy(kT)
    integ.setRandomNumberSeed(3)
    integ.setMaximumStepSize(0.05)
    ctx = plugin_context(system, x, integ)
    samples = []
    for i in range(1, 8001):
        integ.stepTo(0.05 * i)
        p = positions_of(ctx)
        samples.append(np.linalg.norm(p[2] - p[0]))
    assert integ.getNumRejectedSteps() > 0.1 * integ.getNumAcceptedSteps()
    r = np.array(samples[40:])
    blocks = r[: len(r) // 40 * 40].reshape(40, -1)
    mean_err = blocks.mean(axis=1).std(ddof=1) / np.sqrt(40)
    var_err = blocks.var(axis=1).std(ddof=1) / np.sqrt(40)
    assert abs(r.mean() - mean) < 4 * mean_err, (r.mean(), mean, mean_err)
    assert abs(r.var() - var) < 4 * var_err, (r.var(), var, var_err)


def test_free_bead_displacement_has_the_wiener_variance():
    """Over 120 seeds, with rejections on every run: mean 0 and variance 2 kT mu0 t."""
    kT, t = 0.5, 1.0
    ends = np.array([_run(2e-3, seed=s, kT=kT, until=(t,))[0][0] for s in range(1, 121)])
    var = ends.var(axis=0, ddof=1)  # three coordinates, 120 samples each
    expected = 2 * kT * t
    # the sample variance of 120 normals has relative sd sqrt(2/119) = 0.13; 4 sd
    assert np.all(np.abs(var / expected - 1) < 4 * np.sqrt(2 / 119)), var / expected
    assert np.all(np.abs(ends.mean(axis=0)) < 4 * np.sqrt(expected / 120))


@pytest.mark.parametrize("platform", ["Reference", "CPU"])
def test_checkpoint_resumes_bit_for_bit_with_increments_queued(platform):
    x = torus_knot(2, 3, 30)
    system = chain_system(x, ChainModel(gravity=0.0))

    def make():
        integ = kp.rpyplugin.RPYIntegrator(0.02, "ito_heun_adaptive", 2e-3)
        integ.setThermalEnergy(1.0)
        integ.setRandomNumberSeed(9)
        return integ, plugin_context(system, x, integ, platform)

    integ, ctx = make()
    integ.stepTo(0.3)
    assert integ.getNumRejectedSteps() > 0
    blob = ctx.createCheckpoint()
    integ.stepTo(0.6)
    want = positions_of(ctx)
    counts = (integ.getNumAcceptedSteps(), integ.getNumRejectedSteps())
    again, ctx2 = make()
    ctx2.loadCheckpoint(blob)
    again.stepTo(0.6)
    np.testing.assert_array_equal(positions_of(ctx2), want)
    assert (again.getNumAcceptedSteps(), again.getNumRejectedSteps()) == counts


def test_deterministic_limit_is_adaptive_heun():
    """At kT = 0 the pair is Heun with an embedded Euler: error control keeps a relaxing
    ring within its tolerance of a tightly resolved rk23 run."""
    x = torus_knot(2, 3, 30)
    system = chain_system(x, ChainModel())
    ref = kp.rpyplugin.RPYIntegrator(0.01, "rk23", 1e-9)
    ctx_ref = plugin_context(system, x, ref)
    ref.stepTo(2.0)
    integ = kp.rpyplugin.RPYIntegrator(0.01, "ito_heun_adaptive", 1e-5)
    ctx = plugin_context(system, x, integ)
    integ.stepTo(2.0)
    assert np.abs(positions_of(ctx) - positions_of(ctx_ref)).max() < 1e-3
