"""The plugin's leimkuhler_matthews: Euler at kT = 0, Boltzmann bonds at a large step, resume.

The statistical checks follow ``test_plugin_brownian.py``: one long run, standard errors from
batch means, tolerances of a few standard errors; ``ito_heun`` through the same check at the
same step must fail it (the bias the scheme removes), so the check can tell.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from plugin_helpers import dimer_system, plugin_context, positions_of
from scipy.integrate import quad

from knotmm.dynamics.brownian import LeimkuhlerMatthews
from knotmm.dynamics.deterministic import Euler
from knotmm.engine.simulation import Simulation
from knotmm.model.system import chain_system as build_system
from knotmm.plugin import METHODS, RPYIntegrator, from_python_integrator
from knotmm.shapes import torus_knot

NAME = "leimkuhler_matthews"


def test_listed_as_a_stochastic_fixed_step_method():
    assert METHODS[NAME] == (1, False, True)
    integ = from_python_integrator(LeimkuhlerMatthews(0.01, peclet=4.0, seed=3))
    assert integ.getMethod() == NAME and integ.isStochastic() and not integ.isAdaptive()
    assert integ.getThermalEnergy() == 0.25


def test_zero_temperature_is_euler():
    """kT = 0: y1 = y0 + h v(y0), equal to the plugin's euler (bit for bit) and the Python
    engine's Euler and LeimkuhlerMatthews at Pe = inf (1e-12 d) over 30 steps."""
    x = torus_knot(2, 3, 40)
    h, steps = 0.01, 30
    out = {}
    for method in (NAME, "euler"):
        integ = RPYIntegrator(h, method)
        ctx = plugin_context(build_system(x), x, integ)
        integ.step(steps)
        out[method] = positions_of(ctx)
    np.testing.assert_array_equal(out[NAME], out["euler"])
    for python in (Euler(h), LeimkuhlerMatthews(h)):
        sim = Simulation(x, integrator=python, platform="Reference")
        sim.step(steps)
        np.testing.assert_allclose(out[NAME], sim.positions, rtol=0, atol=1e-12)
    assert np.abs(out[NAME] - x).max() > 0.05  # it moved


def pair_coefficients(r):
    """mu_12 / mu0 = a I + c rhat rhat of two beads r apart (d = 1), the RPY formulas."""
    if r >= 1.0:
        return 3 / (8 * r) * (1 + 1 / (6 * r * r)), 3 / (8 * r) * (1 - 1 / (2 * r * r))
    return 1 - 9 * r / 16, 3 * r / 16


def boltzmann(k, r0, kT):
    """<r>, var r and the centre-of-mass mobility <(1 + a + c/3) / 2> per component under
    p(r) ~ r^2 exp(-k (r - r0)^2 / (2 kT))."""
    sd = math.sqrt(kT / k)
    lo, hi = max(0.0, r0 - 12 * sd), r0 + 12 * sd

    def p(r):
        return r * r * math.exp(-k * (r - r0) ** 2 / (2 * kT))

    def mean_of(f):
        return quad(lambda r: f(r) * p(r), lo, hi, points=[1.0])[0] / z

    z = quad(p, lo, hi, points=[1.0])[0]
    mean = mean_of(lambda r: r)
    mob = mean_of(lambda r: (1 + pair_coefficients(r)[0] + pair_coefficients(r)[1] / 3) / 2)
    return mean, mean_of(lambda r: (r - mean) ** 2), mob


def batch_error(samples, batches=40):
    means = samples[: len(samples) // batches * batches].reshape(batches, -1).mean(axis=1)
    return means.std(ddof=1) / math.sqrt(batches)


# A bond as stiff as the chain's stiffest modes: relaxation rate 2 k (1 - a - c) ~ k 3 r0 / 4
# = 56 / tau_d, h lambda = 0.56 at h = 0.01 tau_d; bond sd 0.1 d as the study's at Pe = 2.
K, R0, KT, H = 125.0, 0.6, 1.25, 0.01


def stiff_dimer(method, samples, every=5, seed=17):
    """Bond lengths every ``every`` steps and centre-of-mass displacements over 1 tau_d."""
    integ = RPYIntegrator(H, method, kT=KT, seed=seed)
    ctx = plugin_context(dimer_system(K, R0), np.array([[0.0, 0.0, 0.0], [R0, 0.0, 0.0]]), integ)
    integ.step(100)  # 1 tau_d, about 56 relaxation times
    lengths = np.empty(samples)
    com = np.empty((samples, 3))
    for i in range(samples):
        integ.step(every)
        x = positions_of(ctx)
        lengths[i] = np.linalg.norm(x[1] - x[0])
        com[i] = x.mean(axis=0)
    window = round(1.0 / (H * every))
    return lengths, np.diff(com[::window], axis=0).reshape(-1)


@pytest.mark.parametrize("method", [NAME, "ito_heun"])
def test_stiff_dimer_is_boltzmann_at_a_large_step(method):
    """leimkuhler_matthews at h lambda = 0.56: bond-length mean and variance within 5 standard
    errors (variance: about 1 %) of Boltzmann's, centre-of-mass diffusion 2 kT <mob> t within
    5 errors (about 2.5 %). ito_heun at the same step misses the variance (0.87x)."""
    lengths, disp = stiff_dimer(method, 30_000)
    mean, var, mob = boltzmann(K, R0, KT)
    var_ratio = lengths.var() / var
    se_var = batch_error((lengths - mean) ** 2) / var
    if method == "ito_heun":
        assert var_ratio < 1 - 5 * se_var, (var_ratio, se_var)
        return
    assert abs(var_ratio - 1) < 5 * se_var, (var_ratio, se_var)
    assert abs(lengths.mean() - mean) < 5 * batch_error(lengths), (lengths.mean(), mean)
    # a displacement over m steps holds 2 kT mu (m - 1/2) h (half kicks at both ends)
    expected = 2 * KT * mob * (1.0 - H / 2)
    se = expected * math.sqrt(2.0 / disp.size)
    assert abs(np.mean(disp**2) - expected) < 5 * se, (np.mean(disp**2), expected, se)


@pytest.mark.parametrize("platform", ["Reference", "CPU"])
def test_checkpoint_keeps_the_held_kick(platform):
    """Resume from a checkpoint taken mid-run, into the same and into a fresh Context: the
    same positions bit for bit (the held half kick is in the checkpoint). Setting the same
    positions from outside keeps the kick; other positions drop it (a fresh one is drawn)."""
    x = torus_knot(2, 3, 40)
    system = build_system(x)
    a = RPYIntegrator(0.01, NAME, kT=0.5, seed=21)
    ctx_a = plugin_context(system, x, a, platform)
    a.stepTo(0.2)
    saved = ctx_a.createCheckpoint()
    a.stepTo(0.4)
    first = positions_of(ctx_a)
    assert np.abs(first - x).max() > 0.3

    ctx_a.loadCheckpoint(saved)
    a.stepTo(0.4)
    np.testing.assert_array_equal(positions_of(ctx_a), first)

    b = RPYIntegrator(0.01, NAME, kT=0.5, seed=99)  # the seed is in the checkpoint too
    ctx_b = plugin_context(system, x, b, platform)
    ctx_b.loadCheckpoint(saved)
    at = positions_of(ctx_b)
    ctx_b.setPositions(at)  # the same positions again: the kick stays
    b.stepTo(0.4)
    np.testing.assert_array_equal(positions_of(ctx_b), first)

    ctx_b.loadCheckpoint(saved)
    ctx_b.setPositions(at + 1e-9)  # moved: a fresh kick, another trajectory
    b.stepTo(0.4)
    assert np.abs(positions_of(ctx_b) - first).max() > 1e-3


def test_auto_runs_it_on_the_plugin_and_resumes_exactly(tmp_path):
    """run.engine = "auto" takes the plugin; a Simulation checkpoint file taken mid-run and
    loaded into a new Simulation continues bit for bit (the held kick rides in it)."""
    from knotmm.config import RunConfig

    cfg = RunConfig.from_dict({
        "knot": {"beads": 40},
        "run": {"peclet": 2.0, "integrator": NAME, "seed": 4, "platform": "Reference",
                "engine": "auto"},
    })
    sim = Simulation.from_config(cfg)
    assert sim.engine == "plugin" and sim.openmm_integrator.getMethod() == NAME
    sim.run(0.1)
    sim.saveCheckpoint(tmp_path / "mid.chk")
    sim.run(0.1)
    assert sim.currentStep == 20 and sim.n_evaluations == 20  # one velocity a step
    resumed = Simulation.from_config(cfg)
    resumed.loadCheckpoint(tmp_path / "mid.chk")
    resumed.run(0.1)
    np.testing.assert_array_equal(resumed.positions, sim.positions)
    assert resumed.time == sim.time and resumed.currentStep == sim.currentStep
