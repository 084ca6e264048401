"""Convergence order and error control of the time steppers.

Orders are measured, not assumed: global errors at t = T for several step sizes against an
exact solution (a linear system, scipy.linalg.expm), a tight scipy DOP853 solution (a smooth
nonlinear system) or a fine-step solution of the real chain (Reference platform). The
adaptive integrators are run with fixed steps by making the tolerance huge and
``max_timestep`` equal to the step.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg
from scipy.integrate import solve_ivp

from knotmm.config import RunConfig
from knotmm.dynamics.deterministic import (
    RK23,
    RKC2,
    Euler,
    Heun,
    Midpoint,
    StepSizeUnderflow,
)
from knotmm.dynamics.registry import REGISTRY, make
from knotmm.engine.simulation import Simulation
from knotmm.shapes import build_template

ORDERS = {"euler": 1, "heun": 2, "midpoint": 2, "rk23": 3, "rkc2": 2}
SHAPE = (5, 3)


def _fixed(name, h):
    """An integrator of the given name taking steps of exactly h."""
    if name in ("rk23", "rkc2"):
        return REGISTRY[name].load()(h, tolerance=1e12, max_timestep=h)
    return REGISTRY[name].load()(h)


def _integrate(integrator, rhs, y0, t_end):
    y, t, steps = np.array(y0, dtype=np.float64), 0.0, []
    while t < t_end * (1 - 1e-12):
        y, dt = integrator.step(rhs, y, t_end - t)
        assert 0 < dt <= t_end - t + 1e-15
        t += dt
        steps.append(dt)
    return y, t, steps


def _err(y, ref):
    return float(np.max(np.linalg.norm(y - ref, axis=1)))


def _slopes(hs, errs):
    return np.diff(np.log(errs)) / np.diff(np.log(hs))


@pytest.fixture(scope="module")
def problems():
    rng = np.random.default_rng(11)
    q, _ = np.linalg.qr(rng.normal(size=(15, 15)))
    k = q @ np.diag(np.linspace(0.5, 3.0, 15)) @ q.T
    y0 = rng.normal(size=SHAPE)

    def linear(y):
        return -(k @ y.reshape(-1)).reshape(SHAPE)

    def nonlinear(y):
        return (-(k @ y.reshape(-1)) + 0.5 * np.sin(y.reshape(-1))).reshape(SHAPE)

    t_end = 2.0
    exact_linear = (scipy.linalg.expm(-k * t_end) @ y0.reshape(-1)).reshape(SHAPE)
    sol = solve_ivp(
        lambda t, y: nonlinear(y.reshape(SHAPE)).reshape(-1),
        (0, t_end),
        y0.reshape(-1),
        method="DOP853",
        rtol=1e-13,
        atol=1e-14,
    )
    exact_nonlinear = sol.y[:, -1].reshape(SHAPE)
    return {
        "linear": (linear, y0, t_end, exact_linear),
        "nonlinear": (nonlinear, y0, t_end, exact_nonlinear),
        "k": k,
        "q": q,
    }


@pytest.mark.parametrize("problem", ["linear", "nonlinear"])
@pytest.mark.parametrize("name", sorted(ORDERS))
def test_measured_order_on_smooth_systems(problems, problem, name):
    rhs, y0, t_end, exact = problems[problem]
    hs = [t_end / n for n in (20, 40, 80, 160)]
    errs = []
    for h in hs:
        y, t, steps = _integrate(_fixed(name, h), rhs, y0, t_end)
        assert t == pytest.approx(t_end, rel=1e-12)
        np.testing.assert_allclose(steps, h, rtol=1e-12)  # the steps really were fixed
        errs.append(_err(y, exact))
    slopes = _slopes(hs, errs)
    assert slopes[-1] == pytest.approx(ORDERS[name], abs=0.12), (errs, slopes)
    assert REGISTRY[name].load().order == ORDERS[name] == REGISTRY[name].order


def test_heun_and_midpoint_are_different_methods(problems):
    """On a linear system they coincide (same stability polynomial); not on a nonlinear one."""
    for problem, same in (("linear", True), ("nonlinear", False)):
        rhs, y0, _, _ = problems[problem]
        a = Heun(0.1).step(rhs, y0)[0]
        b = Midpoint(0.1).step(rhs, y0)[0]
        assert np.allclose(a, b, rtol=1e-13, atol=1e-15) == same


@pytest.mark.parametrize("name", ["euler", "heun", "midpoint", "rk23"])
def test_stability_polynomial(name):
    """One step on y' = lam y multiplies y by the Taylor polynomial of exp(z) of the order."""
    p = ORDERS[name]
    for z in (-0.3, -1.0, -2.2):
        y1, _ = _fixed(name, 0.1).step(lambda y, z=z: (z / 0.1) * y, np.ones((1, 3)))
        want = sum(z**k / math.factorial(k) for k in range(p + 1))
        np.testing.assert_allclose(y1, want, rtol=1e-13)


@pytest.mark.parametrize("name", ["rk23", "rkc2"])
def test_adaptive_global_error_follows_tolerance(problems, name):
    rhs, y0, t_end, exact = problems["nonlinear"]
    tols = [1e-3, 1e-4, 1e-5, 1e-6, 1e-7]
    errs, counts = [], []
    for tol in tols:
        integ = make(name, 0.01, tolerance=tol)
        y, _, steps = _integrate(integ, rhs, y0, t_end)
        errs.append(_err(y, exact))
        counts.append(len(steps))
    assert all(np.diff(errs) < 0), errs  # tighter tolerance, smaller error
    assert all(np.diff(counts) > 0), counts  # ... and more steps
    slope = np.polyfit(np.log(tols), np.log(errs), 1)[0]
    # error per step control: global error ~ tol^(p/(p+1)) .. tol
    lo = ORDERS[name] / (ORDERS[name] + 1) - 0.1
    assert lo < slope < 1.1, (slope, errs)
    ratio = np.array(errs) / np.array(tols)
    if name == "rk23":  # measured: 0.27 .. 0.6
        assert ratio.max() < 1.0, ratio
    else:  # error per step of an order-2 method: measured 1.4 .. 32, growing as tol^(-1/3)
        assert ratio[:3].max() < 10.0, ratio


def test_rkc2_is_stable_on_a_stiff_system_with_few_evaluations(problems):
    """Eigenvalues up to 1e4: RKC2 follows accuracy, not stability, and stays accurate."""
    q = problems["q"]
    lam = np.concatenate([np.linspace(0.5, 3.0, 12), [1e3, 3e3, 1e4]])
    k = q @ np.diag(lam) @ q.T
    y0 = problems["linear"][1]
    t_end = 2.0
    exact = (scipy.linalg.expm(-k * t_end) @ y0.reshape(-1)).reshape(SHAPE)
    counts = {}
    for name in ("rkc2", "rk23"):
        calls = [0]

        def rhs(y, calls=calls):
            calls[0] += 1
            return -(k @ y.reshape(-1)).reshape(SHAPE)

        integ = make(name, 0.01, tolerance=1e-5)
        y, _, _ = _integrate(integ, rhs, y0, t_end)
        counts[name] = calls[0]
        assert _err(y, exact) < 1e-3, name
    # an explicit method needs h < ~2.5/1e4 for stability: rk23 ~ 3 * 2 / 2.5e-4 evaluations
    assert counts["rk23"] > 15000
    assert counts["rkc2"] < counts["rk23"] / 5, counts


def test_rkc2_spectral_radius_estimate(problems):
    """The power iteration gives an upper estimate of the largest decay rate, within RKC's
    1.2 safety factor; exact (times 1.2) when the top eigenvalue is well separated."""
    q, y0 = problems["q"], problems["linear"][1]
    for lam, exact in ((np.linspace(0.5, 3.0, 15), False), (np.r_[np.ones(14), 40.0], True)):
        k = q @ np.diag(lam) @ q.T

        def rhs(y, k=k):
            return -(k @ y.reshape(-1)).reshape(SHAPE)

        est = RKC2(0.01).spectral_radius(rhs, y0, rhs(y0))
        assert lam.max() <= est <= 1.2 * lam.max() * (1 + 1e-6)
        if exact:
            assert est == pytest.approx(1.2 * lam.max(), rel=1e-3)


def test_steps_never_pass_max_dt(problems):
    rhs, y0, _, _ = problems["nonlinear"]
    for name in ORDERS:
        integ = make(name, 0.05)
        _, dt = integ.step(rhs, y0, max_dt=0.0123)
        assert 0 < dt <= 0.0123, name


def test_underflow_is_reported():
    """A step that cannot meet the tolerance above min_timestep raises StepSizeUnderflow."""
    integ = RK23(0.1, tolerance=1e-12, min_timestep=1e-3)

    def rhs(y):
        return np.exp(5 * y)  # blows up: errors stay large

    with pytest.raises(StepSizeUnderflow), np.errstate(over="ignore", invalid="ignore"):
        integ.step(rhs, np.full((1, 3), 3.0))


def test_make_integrator_rejects_unknown_names():
    with pytest.raises(ValueError, match="run.integrator = 'rk4'"):
        make("rk4", 0.01)
    with pytest.raises(ValueError, match="timestep"):
        Euler(0.0)


# -- the real chain ---------------------------------------------------------------------------
def test_measured_order_on_the_chain(trefoil40):
    """T(2,3), N = 40, study parameters, 0.5 tau_d, Reference platform: fixed steps against
    an RK23 solution with steps of 5e-4 tau_d."""
    sim = Simulation(trefoil40, platform="Reference")
    t_end = 0.5
    ref, _, _ = _integrate(_fixed("rk23", 5e-4), sim.velocity, trefoil40, t_end)
    hs = [0.008, 0.004, 0.002]
    measured = {}
    for name in sorted(ORDERS):
        errs = [
            _err(_integrate(_fixed(name, h), sim.velocity, trefoil40, t_end)[0], ref) for h in hs
        ]
        measured[name] = _slopes(hs, errs)
        assert measured[name][-1] == pytest.approx(ORDERS[name], abs=0.15), (name, errs)


def test_default_run_is_within_1e3_d_of_converged_solution():
    """The issue's accuracy requirement: the default run file (rk23, tolerance 1e-4 d, default
    platform) from the default T(2,3), N = 90 start stays within 1e-3 d of a converged
    solution (rk23, tolerance 1e-8 d, Reference platform) over 4 tau_d."""
    from knotmm.config import resolve_stepping, resolve_tolerance
    from knotmm.dynamics.registry import integrator_from_config

    cfg = RunConfig.from_dict({})
    assert resolve_stepping(cfg) == ("rk23", 0.01)
    assert (resolve_tolerance(cfg, "rk23"), cfg["knot.beads"]) == (1e-4, 90)
    x0 = build_template(cfg).positions

    def frames(integrator, platform):
        sim = Simulation(x0, integrator=integrator, platform=platform)
        out = []
        for _ in range(4):
            sim.run(1.0)
            out.append(sim.positions.copy())
        assert sim.time == pytest.approx(4.0, abs=1e-12)
        return np.array(out)

    default = integrator_from_config(cfg)  # what a run builds from the same file
    assert isinstance(default, RK23)
    got = frames(default, cfg["run.platform"])
    ref = frames(RK23(0.01, tolerance=1e-8), "Reference")
    dev = np.linalg.norm(got - ref, axis=2).max(axis=1)
    assert dev.max() < 1e-3, dev
    # the chain really moved (fell ~40 d) so the comparison is not trivial
    assert np.abs(ref[-1] - x0).max() > 10


@pytest.mark.slow
@pytest.mark.parametrize("name", ["rk23", "rkc2"])
def test_chain_error_decreases_with_tolerance(trefoil90, name):
    sim = Simulation(trefoil90, platform="Reference")
    ref, _, _ = _integrate(RK23(0.01, tolerance=1e-10), sim.velocity, trefoil90, 4.0)
    errs = []
    for tol in (1e-3, 1e-4, 1e-5, 1e-6):
        y, _, _ = _integrate(make(name, 0.01, tolerance=tol), sim.velocity, trefoil90, 4.0)
        errs.append(_err(y, ref))
    assert all(np.diff(errs) < 0), errs
    assert errs[1] < 1e-3
