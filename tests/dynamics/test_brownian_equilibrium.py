"""Boltzmann statistics of Brownian dynamics, judged against a Metropolis Monte Carlo.

Issue 20: at Pe = 0.5, 1, 2 and 10 (T(2,3), N = 60, gravity 0) the Brownian integrator must
sample ``exp(-E / kT)`` of the chain's energy. The reference is ``mc_reference.py``, a
Metropolis Monte Carlo of the same energy that knows nothing of dynamics. Compared: the
bond-length standard deviation (within 2 %), the mean cosine of the angle between successive
bonds and the mean distance ``|r_{i+2} - r_i|`` (each within 1 %). The tolerances are the
issue's and are not widened by the statistical errors; both sides' errors are printed in the
assertion message so that a failure can be told from noise.

The energy lets bonds pass through each other (the steric range is shorter than a bond), and
the knot type moves the mean cosine by about 1 %: both sides are compared within one knot
type (the dynamics' samples labelled by topoly, the Monte Carlo kept in that type; see
``test_adaptive_ito_heun_boltzmann``).

The fast test checks the Monte Carlo itself: its local energy change against the full energy
of ``reference_model.py``, and its distributions against closed forms (a free harmonic dimer,
an open trimer with bending and the 1-3 steric pair, by quadrature).

Model units: d = 1, F0 = 1, tau_d = 1; ``kT = 1 / Pe``.
"""

from __future__ import annotations

import math
import time

import mc_reference as mc
import numpy as np
import pytest
import reference_model as rm

from knotmm.dynamics.adaptive_brownian import AdaptiveItoHeun
from knotmm.dynamics.deterministic import StepSizeUnderflow
from knotmm.dynamics.registry import resolve_tolerance
from knotmm.engine.simulation import Simulation
from knotmm.model.system import ChainModel
from knotmm.shapes.geometry import torus_knot

N_BEADS = 60
#: Tolerances of issue 20 (relative): bond-length standard deviation; mean cos and |r_{i+2} - r_i|.
TARGETS = {"bond_sd": 0.02, "cos": 0.01, "d13": 0.01}


# -- the dynamics side ----------------------------------------------------------------------------
def sample_brownian(integ, duration: float, burn_in: float = 1.0, sample_every: float = 0.05,
                    n_beads: int = N_BEADS, identify_every: float | None = 1.0) -> dict:
    """Run ``integ`` on T(2,3) (``n_beads``, gravity 0, Python engine) and sample the chain.

    Samples every ``sample_every`` tau_d after ``burn_in``; adaptive steps are clipped to land
    on the sample times, fixed steps are counted. Every ``identify_every`` tau_d the knot type
    is identified (topoly, through knotmm.knots.homfly): a sample is labelled with the type
    found at both ends of its interval, or ``"?"`` if they differ (bonds can pass through
    each other, and at Pe <~ 1 the trefoil unties within tens of tau_d). Returns the
    per-sample chain averages (``series``, columns ``mc_reference.SERIES``), their ``labels``,
    the accepted and rejected steps, and the wall time of the dynamics (s, identification
    excluded). A non-finite state or a bond past 3 d raises AssertionError.
    """
    x = torus_knot(2, 3, n_beads)
    sim = Simulation(x, ChainModel(gravity=0.0), integrator=integ, engine="python",
                     platform="CPU")
    y = np.array(sim.positions, dtype=np.float64, copy=True)
    n_samples = int(round((duration - burn_in) / sample_every))
    n_burn = int(round(burn_in / sample_every))
    per_id = None if identify_every is None else int(round(identify_every / sample_every))
    series = np.empty((n_samples, 4))
    labels = np.full(n_samples, "3_1" if per_id is None else "?", dtype=object)
    adaptive = getattr(integ, "adaptive", False)
    per_sample = None if adaptive else int(round(sample_every / integ.timestep))
    identify = None
    if per_id is not None:
        from knotmm.knots.homfly import identify_here as identify
    last_type = "3_1"
    wall = 0.0
    t = 0.0
    for k in range(n_burn + n_samples):
        t0 = time.perf_counter()
        target = (k + 1) * sample_every
        if adaptive:
            while target - t > 1e-9:
                try:
                    y, h = integ.step(sim.velocity, y, target - t)
                except StepSizeUnderflow as exc:  # pragma: no cover - a failure report
                    raise AssertionError(f"step size underflow at t = {t:.4g}: {exc}") from exc
                t += h
        else:
            for _ in range(per_sample):
                y, h = integ.step(sim.velocity, y)
            t = target
        wall += time.perf_counter() - t0
        ell = np.linalg.norm(np.roll(y, -1, axis=0) - y, axis=1)
        assert np.all(np.isfinite(y)) and ell.max() < 3.0, f"blow-up at t = {t:.4g}"
        if k >= n_burn:
            series[k - n_burn] = mc.ring_observables(y)
        if per_id is not None and (k + 1) % per_id == 0:
            kind = identify(y)
            lo = max(0, k + 1 - per_id - n_burn)
            if kind == last_type and k >= n_burn:
                labels[lo : k + 1 - n_burn] = kind
            last_type = kind
    return {"series": series, "labels": labels, "accepted": integ.n_accepted,
            "rejected": integ.n_rejected, "wall": wall, "duration": duration,
            "burn_in": burn_in, "sample_every": sample_every}


#: The knot type each Pe is judged in (see test_adaptive_ito_heun_boltzmann).
JUDGED_KNOT = {0.5: "0_1", 1.0: "0_1", 2.0: "3_1", 10.0: "3_1"}
#: tau_d discarded after the chain first shows a knot type other than its start (T(2,3)):
#: the unknot just after a strand passage is still compact and opens up slowly.
SETTLE = 10.0


def select_samples(dyn: dict, knot: str, settle: float = SETTLE) -> np.ndarray:
    """The samples labelled ``knot``; for a type other than the start's, only those later
    than ``settle`` tau_d after the first such label."""
    labels = np.asarray(dyn["labels"], dtype=str)
    keep = labels == knot
    if knot != "3_1" and keep.any():
        first = int(np.argmax(keep))
        keep[: first + int(round(settle / dyn.get("sample_every", 0.05)))] = False
    return np.asarray(dyn["series"])[keep]


def compare(dyn: dict, ref: dict, n_blocks: int = 20, knot: str | None = None) -> dict:
    """``{name: (dynamics, its error, mc, its error, relative deviation, its error)}``.

    With ``knot``, only the dynamics' samples of that knot type are used (:func:`select_samples`).
    """
    series = np.asarray(dyn["series"]) if knot is None else select_samples(dyn, knot)
    est = mc.chain_estimates(series, n_blocks)
    out = {}
    for name in TARGETS:
        v, e = est[name]
        r, re = ref[name][:2]
        out[name] = (v, e, r, re, v / r - 1.0, math.hypot(e / r, v * re / r**2))
    return out


def default_tolerance(peclet: float) -> float:
    """The tolerance a run at ``peclet`` takes when none is given (the registry's rule)."""
    return resolve_tolerance("ito_heun_adaptive", None, peclet)


# -- the Monte Carlo, checked (fast) ---------------------------------------------------------------
def test_local_energy_matches_reference_model():
    """dE of single-bead moves equals the difference of reference_model's full energies."""
    rng = np.random.default_rng(11)
    for x in (rm.close_contact_ring(N_BEADS, rng), rm.random_ring(24, rng, noise=0.15),
              torus_knot(2, 3, N_BEADS)):
        x = np.array(x, dtype=np.float64)
        args = (mc.STUDY["bond_stiffness"], mc.STUDY["bond_length"],
                mc.STUDY["bending_stiffness"], mc.STUDY["lj_sigma"], mc.STUDY["lj_epsilon"])
        e_full = rm.energies(x, gravity=0.0)["total"]
        assert mc.total_energy(x, True, *args) == pytest.approx(e_full, rel=1e-12, abs=1e-12)
        for _ in range(40):
            i = int(rng.integers(len(x)))
            y = x.copy()
            y[i] += rng.normal(scale=0.15, size=3)
            de_local = mc.local_energy(y, i, True, *args) - mc.local_energy(x, i, True, *args)
            de_full = rm.energies(y, gravity=0.0)["total"] - e_full
            assert de_local == pytest.approx(de_full, rel=1e-9, abs=1e-9)


def test_observables_match_numpy():
    x = rm.random_ring(30, np.random.default_rng(2), noise=0.1)
    full = mc.full_observables(x)
    got = mc.ring_observables(x)
    want = [full["bond"].mean(), (full["bond"] ** 2).mean(), full["cos"].mean(),
            full["d13"].mean()]
    np.testing.assert_allclose(got, want, rtol=1e-12)
    # cos theta is minus the cosine of the bending angle phi of reference_model
    np.testing.assert_allclose(np.sort(full["cos"]), np.sort(-np.cos(np.pi - rm.bend_deviation(x))),
                               atol=1e-12)


def _dimer_exact(kT, B=50.0, l0=0.6):
    r = np.linspace(max(1e-6, l0 - 12 * math.sqrt(kT / B)), l0 + 12 * math.sqrt(kT / B), 20001)
    w = r**2 * np.exp(-B * (r - l0) ** 2 / (2 * kT))
    m1 = np.trapezoid(w * r, r) / np.trapezoid(w, r)
    m2 = np.trapezoid(w * r * r, r) / np.trapezoid(w, r)
    return m1, math.sqrt(m2 - m1**2)


def test_mc_dimer_radial_distribution():
    """A free harmonic bond: <l> and sd from r^2 exp(-B (l - l0)^2 / 2kT)."""
    for kT in (2.0, 0.5):
        res = mc.metropolis(np.array([[0.0, 0, 0], [0.6, 0, 0]]), kT, sweeps=400_000,
                            burn_in=2000, stride=2, seed=5, closed=False, keep_full=True)
        ell = res.full["bond"][:, 0]
        mean, sd = _dimer_exact(kT)
        se, _, _ = mc.blocking_error(ell)
        assert abs(ell.mean() - mean) < 5 * se, (kT, ell.mean(), mean, se)
        se_sd, _, _ = mc.blocking_error((ell - mean) ** 2)
        assert abs(ell.var() - sd**2) < 5 * se_sd, (kT, ell.std(), sd)
        assert abs(ell.std() / sd - 1) < 0.01


def test_mc_trimer_bending_and_steric():
    """An open trimer at kT = 2 (folds reach the 1-3 steric core) and 0.5: quadrature."""
    x0 = np.array([[0.0, 0, 0], [0.6, 0, 0], [1.2, 0.1, 0]])
    for kT in (2.0, 0.5):
        res = mc.metropolis(x0, kT, sweeps=300_000, burn_in=2000, stride=2, seed=7,
                            closed=False)
        cos_exact, d13_exact = mc.trimer_exact(kT)
        for col, exact in ((2, cos_exact), (3, d13_exact)):
            se, _, _ = mc.blocking_error(res.series[:, col])
            got = res.series[:, col].mean()
            assert abs(got - exact) < 5 * se + 1e-4 * abs(exact), (kT, col, got, exact, se)


def test_strand_passage_check():
    """A bead lifted through another bond is caught; the same move the other way is not."""
    x = np.array([[0.0, 0, 0], [0.6, 0, 0], [1.2, 0, 0], [1.2, 1.5, 0], [0.5, 0.5, 0.3],
                  [0.5, -0.5, 0.3], [-1.0, -1.5, 0]])
    old = x[1].copy()
    for lift, hit in ((1.0, True), (-1.0, False)):
        y = x.copy()
        y[1] = old + [0.0, 0.0, lift]
        assert mc.passes_strand(y, 1, old) is hit


def test_fixed_topology_keeps_the_trefoil():
    """At kT = 2 the free chain unties T(2,3) within 20 000 sweeps; the fixed one does not."""
    from knotmm.knots.identify import identify_knot, topoly_available

    if not topoly_available():  # (the worker process runs topoly; never this one)
        pytest.skip("topoly not installed")
    x0 = torus_knot(2, 3, N_BEADS)
    fixed = mc.metropolis(x0, 2.0, sweeps=20_000, burn_in=2000, seed=3, fixed_topology=True)
    free = mc.metropolis(x0, 2.0, sweeps=20_000, burn_in=2000, seed=3)
    assert identify_knot(fixed.final) == "3_1"
    assert identify_knot(free.final) != "3_1"


def test_mc_ring_sanity():
    """N = 60 at kT = 1: the bond spread of docs/model.md (0.134 d), cos and 1-3 in range."""
    ref = mc.reference(1.0, sweeps=40_000)
    assert ref["bond_sd"][0] == pytest.approx(0.134, abs=0.002)
    assert 0.6 < ref["bond"][0] < 0.7
    assert 0.7 < ref["cos"][0] < 0.9
    assert 1.1 < ref["d13"][0] < 1.3
    assert 0.3 < ref["acceptance"] < 0.5


# -- the dynamics, judged (slow) -------------------------------------------------------------------
#: Run lengths (tau_d) per Pe: long enough that both sides' errors are well inside the targets.
DURATION = {0.5: 100.0, 1.0: 100.0, 2.0: 100.0, 10.0: 100.0}
BURN_IN = 5.0
#: The least run time (tau_d) of the judged knot type for a comparison.
MIN_SAMPLED = 20.0
SEEDS = {0.5: 1, 1.0: 2, 2.0: 3, 10.0: 4}


@pytest.mark.slow
@pytest.mark.parametrize("peclet", sorted(DURATION))
def test_adaptive_ito_heun_boltzmann(peclet):
    """AdaptiveItoHeun at the tolerance a run takes at this Pe samples the Monte Carlo's
    equilibrium.

    Both sides are compared in one knot type. The energy lets bonds pass through each other,
    and the knot type shifts the mean cosine by about 1 % (0.889 trefoil, 0.902 unknot at
    kT = 0.5), so a run that unties partway matches neither the trefoil nor the free
    (almost all unknot at N = 60) Monte Carlo. At Pe <= 1 the T(2,3) start unties within
    about 10 tau_d and hardly ever ties again: judged in the unknot, SETTLE tau_d after it
    first appears (it opens up slowly from the compact shape it unties in). At Pe >= 2 the
    trefoil lives tens of tau_d (Pe = 2) or for ever (Pe = 10): judged in the trefoil. The
    dynamics' samples are labelled by knot type (topoly); the Monte Carlo keeps its knot type
    (``mc_reference.metropolis(fixed_topology=True)``).
    """
    pytest.importorskip("topoly")
    kT = 1.0 / peclet
    knot = JUDGED_KNOT[peclet]
    integ = AdaptiveItoHeun(0.002, peclet=peclet, seed=SEEDS[peclet], noise="cholesky",
                            tolerance=default_tolerance(peclet), max_timestep=0.05)  # as measured
    dyn = sample_brownian(integ, DURATION[peclet], BURN_IN)
    n_used = len(select_samples(dyn, knot))
    used = n_used * dyn["sample_every"]
    assert used >= MIN_SAMPLED, f"only {used:.0f} tau_d of {knot} at Pe = {peclet:g}"
    ref = mc.reference(kT, knot=knot, seed=SEEDS[peclet])
    cmp = compare(dyn, ref, knot=knot)
    lines = [f"Pe = {peclet:g}, tolerance {integ.tolerance:g}, "
             f"{dyn['accepted']} accepted / {dyn['rejected']} rejected steps, "
             f"{used:.0f} tau_d of {knot} compared, "
             f"dynamics {dyn['wall']:.0f} s, MC {ref['wall']:.0f} s"]
    for name, (v, e, r, re, dev, dev_e) in cmp.items():
        lines.append(f"  {name}: dynamics {v:.5f} +- {e:.5f}, MC {r:.5f} +- {re:.5f}, "
                     f"deviation {100 * dev:+.2f} +- {100 * dev_e:.2f} % "
                     f"(target {100 * TARGETS[name]:g} %)")
    message = "\n".join(lines)
    print(message)
    for name, (*_, dev, _dev_e) in cmp.items():
        assert abs(dev) < TARGETS[name], message
