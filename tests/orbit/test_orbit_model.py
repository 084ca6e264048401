"""The orbit of a real run, checked against independent references.

* the orbit is an orbit of the model: the Python engine with a different integrator (rk23 at
  a tight tolerance) brings the state back to itself after one period;
* its period and falling speed equal what the run's analysis measures from the trajectory;
* the neutral multipliers equal their closed forms (1, 1, 1, exp(-+i theta));
* ARPACK's leading multipliers equal those of a dense monodromy matrix built column by
  column in the test;
* (slow) a perturbation along the leading mode grows as the leading exponent says.
"""

from __future__ import annotations

import cmath

import numpy as np
import pytest

from knotmm.orbit.flow import centre, rms, rotate_z


@pytest.fixture(scope="module")
def floquet40(orbit40):
    from knotmm.orbit.floquet import floquet

    flow, orbit, _ = orbit40
    return floquet(flow, orbit, k=6)


def test_orbit_converges_to_the_tolerance(orbit40):
    _, orbit, _ = orbit40
    assert orbit.converged
    assert orbit.residual <= 1e-9
    assert abs(orbit.positions.mean(axis=0)).max() < 1e-9  # the translations are fixed


def test_orbit_returns_under_an_independent_integrator(orbit40):
    from knotmm.dynamics.deterministic import RK23
    from knotmm.engine.simulation import Simulation

    flow, orbit, _ = orbit40
    sim = Simulation(orbit.positions, flow.model, RK23(0.001, 1e-8), platform="Reference",
                     engine="python")
    sim.run(orbit.period, write_at_start=False)
    back = rotate_z(centre(sim.positions), -orbit.rotation)
    # Heun at 0.01 tau_d differs from the exact flow by ~1e-5 d per period; the shape
    # itself moves by ~0.5 d in a period, so a wrong period or angle would show
    assert rms(back - orbit.positions) < 2e-4
    moved = rms(centre(flow(orbit.positions, 0.5 * orbit.period)) - orbit.positions)
    assert moved > 0.05


def test_period_and_speed_match_the_runs_analysis(run40, orbit40):
    from knotmm.analysis.core import analyze
    from knotmm.io.run_data import load_run

    _, orbit, start = orbit40
    result = analyze(load_run(run40), knot_samples=0, fit=False)
    assert orbit.period == pytest.approx(result.tau_swirl, rel=1e-3)
    assert start.tau_swirl == result.tau_swirl
    assert orbit.sedimentation_velocity == pytest.approx(result.sedimentation_velocity,
                                                         rel=1e-3)
    # the run turns clockwise seen from above (right-handed T(2,3)): negative angle
    assert orbit.rotation < 0


def test_neutral_multipliers_have_their_closed_forms(orbit40, floquet40):
    _, orbit, _ = orbit40
    res = floquet40
    named = dict(zip(res.neutral_names, res.neutral, strict=False))
    assert named["translation z"] == pytest.approx(1.0, abs=1e-5)
    assert named["rotation about z"] == pytest.approx(1.0, abs=1e-5)
    assert named["time shift"] == pytest.approx(1.0, abs=1e-3)
    pair = sorted((m for n, m in zip(res.neutral_names, res.neutral, strict=False) if "x, y" in n),
                  key=lambda z: z.imag)
    expected = sorted([cmath.exp(1j * orbit.rotation), cmath.exp(-1j * orbit.rotation)],
                      key=lambda z: z.imag)
    for got, want in zip(pair, expected, strict=False):
        assert abs(got - want) < 1e-6


@pytest.mark.slow
def test_arnoldi_matches_a_dense_monodromy_matrix(orbit40, floquet40):
    flow, orbit, _ = orbit40
    x = orbit.positions
    end = flow(x, orbit.period)
    n3 = x.size
    dense = np.empty((n3, n3))
    for k in range(n3):
        e = np.zeros(n3)
        e[k] = 1.0
        dense[:, k] = rotate_z(flow.jvp(x, orbit.period, end, e), -orbit.rotation).ravel()
    values = np.linalg.eigvals(dense)
    # drop the five neutral ones: the five closest to {1, 1, 1, exp(+-i theta)}
    neutral = [1, 1, 1, cmath.exp(1j * orbit.rotation), cmath.exp(-1j * orbit.rotation)]
    rest = list(values)
    for target in neutral:
        rest.pop(int(np.argmin([abs(v - target) for v in rest])))
    rest = np.array(sorted(rest, key=lambda v: -abs(v)))
    got = floquet40.multipliers
    np.testing.assert_allclose(np.abs(got[:4]), np.abs(rest[:4]), rtol=1e-3)
    assert abs(got[0] - rest[0]) < 1e-3 or abs(got[0] - np.conj(rest[0])) < 1e-3


def test_leading_mode_is_described(orbit40, floquet40):
    from knotmm.orbit.modes import describe_mode

    _, orbit, _ = orbit40
    shape = describe_mode(orbit.positions, floquet40.modes[0])
    total = shape.tilt + shape.out_of_plane + shape.radial + shape.tangential + shape.rigid_other
    assert total == pytest.approx(1.0, abs=1e-9)
    assert shape.rigid_other < 1e-3  # a quotient mode has no translation or spin in it


@pytest.mark.slow
def test_leading_exponent_predicts_a_plain_run(orbit40, floquet40):
    """Perturb by 1e-6 d along the leading mode and run with the Python engine (the same
    Heun step, Reference platform): the amplitude of the deviation in the leading mode's
    plane grows by |mu_1| per period; the fitted rate agrees with ln|mu_1|/T within 10 %."""
    from knotmm.dynamics.deterministic import Heun
    from knotmm.engine.simulation import Simulation

    flow, orbit, _ = orbit40
    res = floquet40
    mode = res.modes[0]
    basis = np.column_stack([mode.real.ravel(), mode.imag.ravel()])
    if np.linalg.norm(basis[:, 1]) < 1e-12 * np.linalg.norm(basis[:, 0]):
        basis = basis[:, :1]
    start = mode.real / rms(mode.real) * 1e-6
    sim = Simulation(orbit.positions + start, flow.model, Heun(flow.timestep),
                     platform="Reference", engine="python")
    periods = 12
    amplitudes = []
    for k in range(1, periods + 1):
        sim.run(orbit.period, write_at_start=False)
        dev = rotate_z(centre(sim.positions), -k * orbit.rotation) - orbit.positions
        coef = np.linalg.lstsq(basis, dev.ravel(), rcond=None)[0]
        amplitudes.append(np.linalg.norm(coef))
    t = orbit.period * np.arange(1, periods + 1)
    rate = np.polyfit(t[3:], np.log(amplitudes[3:]), 1)[0]
    assert res.leading_exponent > 0
    assert rate == pytest.approx(res.leading_exponent, rel=0.10)


@pytest.mark.slow
def test_arclength_continuation_lands_on_orbits_of_the_model(orbit40):
    """Each point of a pseudo-arclength branch is the orbit at its parameter: solving at that
    parameter from scratch (plain Newton at fixed p) gives the same period and rotation."""
    from knotmm.model.parameters import ChainModel
    from knotmm.orbit.continuation import continue_orbit
    from knotmm.orbit.flow import make_flow
    from knotmm.orbit.shooting import solve_orbit

    _, orbit, start = orbit40

    def flow_for(model, positions, step=None):
        return make_flow(positions, model, step)

    branch = continue_orbit(orbit, start.model, "model.bending_stiffness", 5.0, 7.0,
                            flow_for, points=3, modes=0)
    values = [p.value for p in branch]
    assert values == sorted(values) and len(values) in (3, 4)
    assert values[-1] == pytest.approx(7.0, abs=0.01)
    last = branch[-1]
    model = ChainModel.from_config(start.config.replace({"model.bending_stiffness": last.value}))
    direct = solve_orbit(make_flow(last.orbit.positions, model, last.orbit.timestep),
                         orbit.positions, orbit.period, orbit.rotation, tolerance=1e-9)
    assert direct.converged
    assert direct.period == pytest.approx(last.orbit.period, rel=1e-6)
    assert direct.rotation == pytest.approx(last.orbit.rotation, rel=1e-5)
