"""RPYIntegrator.getGroupEnergies: the four energies in one call, the run undisturbed."""

from __future__ import annotations

import numpy as np
import openmm
import pytest
import reference_model as rm
from openmm import unit
from plugin_helpers import plugin_context, positions_of

from knotmm.dynamics.brownian import ItoHeun
from knotmm.dynamics.deterministic import RK23
from knotmm.engine.simulation import Simulation
from knotmm.model.system import FORCE_GROUPS
from knotmm.model.system import chain_system as build_system
from knotmm.plugin import METHODS, RPYIntegrator
from knotmm.shapes import torus_knot

TERMS = tuple(FORCE_GROUPS)

#: (method, step, integrator keywords); leimkuhler_matthews joins once the plugin has it.
RUNS = [
    ("rk23", 0.01, {}),
    ("rkc2", 0.01, {}),
    ("heun", 0.01, {}),
    ("ito_heun", 0.002, {"kT": 0.5, "seed": 11}),
    ("euler_maruyama", 0.002, {"kT": 0.5, "seed": 12}),
] + ([("leimkuhler_matthews", 0.002, {"kT": 0.5, "seed": 13})]
     if "leimkuhler_matthews" in METHODS else [])


def _state(ctx, integ):
    step = integ.getStepSize()
    return (positions_of(ctx), ctx.getState().getTime().value_in_unit(openmm.unit.picosecond),
            integ.getNumForceEvaluations(), integ.getNumAcceptedSteps(),
            integ.getNumRejectedSteps(), step.value_in_unit(step.unit))


def _assert_same(a, b):
    np.testing.assert_array_equal(a[0], b[0])
    assert a[1:] == b[1:]


@pytest.mark.parametrize(("method", "step", "kwargs"), RUNS)
@pytest.mark.parametrize("platform", ["Reference", "CPU"])
def test_energy_call_leaves_the_next_steps_bit_identical(method, step, kwargs, platform):
    """Two identical runs, one asking for the energies between steps: the same trajectory bit
    for bit (rk23's cached FSAL velocity, step size and error memory, rkc2's spectral radius,
    the Brownian noise stream), and the call leaves the Context's positions as they were."""
    x = torus_knot(2, 3, 40) + np.array([1.0, -2.0, -50.0])  # off the origin: a real shift
    system = build_system(x)
    runs = []
    for ask in (False, True):
        integ = RPYIntegrator(step, method, **kwargs)
        ctx = plugin_context(system, x, integ, platform)
        integ.stepTo(0.1)
        history = []
        for k in range(5):
            if ask:
                before = positions_of(ctx)
                integ.getGroupEnergies(list(FORCE_GROUPS.values()))
                integ.getGroupEnergies([2])
                np.testing.assert_array_equal(positions_of(ctx), before)
            now = ctx.getState().getTime().value_in_unit(unit.picosecond)
            integ.step(1) if k % 2 else integ.stepTo(now + 0.01 * (k + 1))
            history.append(_state(ctx, integ))
        runs.append(history)
    assert np.abs(runs[0][-1][0] - x).max() > 0.01
    for plain, asked in zip(*runs, strict=True):
        _assert_same(plain, asked)


def test_group_energies_equal_a_naive_closed_form():
    """Each group's energy against the closed forms of docs/model.md (tests/reference_model.py)
    at the centred positions; gravity is the centred one, g sum (z - z_com) = 0."""
    rng = np.random.default_rng(3)
    x = rm.close_contact_ring(40, rng) + np.array([2.0, 1.0, -300.0])
    integ = RPYIntegrator(0.01, "rk23")
    ctx = plugin_context(build_system(x), x, integ)  # noqa: F841 - keeps the Context alive
    got = dict(zip(TERMS, integ.getGroupEnergies(list(FORCE_GROUPS.values())), strict=True))
    want = rm.energies(x - x.mean(axis=0))
    for term in ("bond", "bend", "steric"):
        assert want[term] > 0.0, term
        assert got[term] == pytest.approx(want[term], rel=1e-10), term
    assert abs(got["gravity"]) < 1e-10 * abs(x[:, 2]).sum()
    # one group, any order, repeats
    again = integ.getGroupEnergies((2, 0, 2))
    assert again == (got["steric"], got["bond"], got["steric"])
    assert integ.getGroupEnergies([]) == ()


@pytest.mark.parametrize("groups", [[32], [-1]])
def test_group_out_of_range_is_refused(groups):
    x = torus_knot(2, 3, 40)
    integ = RPYIntegrator(0.01, "rk23")
    ctx = plugin_context(build_system(x), x, integ)  # noqa: F841 - keeps the Context alive
    with pytest.raises(openmm.OpenMMException, match="force group .* 0 to 31"):
        integ.getGroupEnergies(groups)
    with pytest.raises(TypeError, match="groups"):
        integ.getGroupEnergies(["bond"])


def test_group_energies_need_a_context():
    with pytest.raises(openmm.OpenMMException, match="not bound to a Context"):
        RPYIntegrator(0.01).getGroupEnergies([0])


@pytest.mark.parametrize(("method", "step", "kwargs"), RUNS[:1] + RUNS[3:4])
def test_simulation_energies_plugin_path_equals_the_getstate_path(method, step, kwargs):
    """Simulation.energies() with the plugin engine (one C++ call) against the four-getState
    path (positions given) and the naive closed form, on a chain that has fallen, after a
    run and between frames; then the run goes on exactly as a run that never asked."""
    x = torus_knot(2, 3, 40)

    def simulation():
        integrator = (RK23(step) if method == "rk23"
                      else ItoHeun(step, peclet=1.0 / kwargs["kT"], seed=kwargs["seed"]))
        return Simulation(x, integrator=integrator, platform="Reference", engine="plugin")

    sim, plain = simulation(), simulation()
    for sim_ in (sim, plain):
        sim_.run(2.0)
    got = sim.energies()
    by_getstate = sim.energies(sim.positions.copy())
    naive = rm.energies(sim.positions)
    assert sim.positions[:, 2].mean() < -1.0  # it has fallen: gravity's shift matters
    for term in (*TERMS, "total"):
        assert got[term] == pytest.approx(by_getstate[term], rel=1e-10, abs=1e-12), term
        assert got[term] == pytest.approx(naive[term], rel=1e-10, abs=1e-9), term
    sim.energies()  # the Context may have been moved by the getState path: put back first
    for sim_ in (sim, plain):
        sim_.run(0.5)
    np.testing.assert_array_equal(sim.positions, plain.positions)
    assert sim.n_evaluations == plain.n_evaluations


@pytest.mark.parametrize("segment_repulsion", [False, True])
def test_simulation_energies_after_the_context_was_moved(segment_repulsion):
    """The Context holds other positions (Simulation.forces at a probe, as stiffness() does;
    virtual midpoint sites with segment_repulsion): energies() still describes `positions`."""
    from knotmm.model.system import ChainModel

    x = torus_knot(2, 3, 40)
    sim = Simulation(x, model=ChainModel(segment_repulsion=segment_repulsion),
                     platform="Reference", engine="plugin")
    sim.run(1.0)
    sim.forces(sim.positions * 1.05)  # not a translate: other energies
    got = sim.energies()
    want = sim.energies(sim.positions.copy())
    naive = rm.energies(sim.positions)
    for term in (*TERMS, "total"):
        assert got[term] == pytest.approx(want[term], rel=1e-10, abs=1e-12), term
        if not segment_repulsion:  # the closed form knows no segment sites
            assert got[term] == pytest.approx(naive[term], rel=1e-10, abs=1e-9), term
