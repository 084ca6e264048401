"""The run loop: velocities, invariants of the dynamics, reporter scheduling, faults."""

from __future__ import annotations

import io
import math

import numpy as np
import openmm.app
import pytest
import reference_model as rm
from engine_platforms import ENGINE_PLATFORMS, engine_velocity
from scipy.spatial.transform import Rotation

from knotmm.dynamics.deterministic import RK23, RKC2, Euler, Heun
from knotmm.engine.simulation import Simulation
from knotmm.errors import SimulationFault
from knotmm.model.system import ChainModel

GRAVITY_ONLY = dict(bond_stiffness=0.0, bending_stiffness=0.0, lj_epsilon=0.0)


# -- velocities -------------------------------------------------------------------------------
@pytest.mark.parametrize(("engine", "platform"), ENGINE_PLATFORMS)
@pytest.mark.parametrize("g", [1.0, 2.5])
def test_gravity_only_velocity_is_the_mobility_sum(rng, g, engine, platform):
    """No chain forces: every bead moves with sum_j mu_ij (0, 0, -g) (naive loop)."""
    for n in (4, 9):
        x = rng.uniform(-1.2, 1.2, size=(n, 3))  # a mix of r < d and r > d pairs
        x[:, 0] *= 2
        f = np.zeros_like(x)
        f[:, 2] = -g
        want = rm.rpy_velocities(x, f)
        got, rel = engine_velocity(x, engine, platform, model=ChainModel(gravity=g, **GRAVITY_ONLY),
                                   max_bond_length=100.0)
        np.testing.assert_allclose(got, want, rtol=0, atol=rel * np.abs(want).max())


@pytest.mark.parametrize(("engine", "platform"), ENGINE_PLATFORMS)
def test_square_of_four_beads_falls_with_the_closed_form_speed(engine, platform):
    """A lone bead falls at mu0 F0 = 1; a horizontal square of 4 beads with sides d falls at
    1 + 2 (3/8 + 1/16) + (3/(8 s) + 1/(16 s^3)), s = sqrt(2): two neighbours side by side at
    r = d (the contact value of both branches) and one across the diagonal."""
    x = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float)
    v, rel = engine_velocity(x, engine, platform, model=ChainModel(**GRAVITY_ONLY))
    s = math.sqrt(2)
    want = 1 + 2 * (3 / 8 + 1 / 16) + (3 / (8 * s) + 1 / (16 * s**3))
    np.testing.assert_allclose(v[:, 2], -want, rtol=rel)
    np.testing.assert_allclose(v[:, :2], 0, atol=rel * want)


@pytest.mark.parametrize(("engine", "platform"), ENGINE_PLATFORMS)
@pytest.mark.parametrize("config", ["trefoil", "close_contact"])
def test_velocity_is_mobility_times_numpy_forces(trefoil40, rng, config, engine, platform):
    x = (
        trefoil40 + rng.normal(scale=0.05, size=trefoil40.shape)
        if config == "trefoil"
        else (rm.close_contact_ring(30, rng))
    )
    want = rm.rpy_velocities(x, rm.forces(x)["total"])
    got, rel = engine_velocity(x, engine, platform, max_bond_length=100.0)
    np.testing.assert_allclose(got, want, rtol=0, atol=rel * np.abs(want).max())


def test_one_velocity_is_one_evaluation(trefoil40):
    sim = Simulation(trefoil40, platform="Reference")
    sim.velocity(trefoil40)
    assert sim.n_evaluations == 1


def test_internal_forces_cancel(rng):
    """Newton's third law: the total force is the weight, N g along -z."""
    x = rm.close_contact_ring(30, rng)
    sim = Simulation(x, ChainModel(gravity=1.7), platform="Reference", max_bond_length=100.0)
    np.testing.assert_allclose(sim.forces(x).sum(axis=0), [0, 0, -1.7 * 30], atol=1e-9)


def test_rotation_about_the_vertical_commutes_with_the_velocity(trefoil40, rng):
    """Gravity is along z, so rotating the chain about z rotates its velocities."""
    x = trefoil40 + rng.normal(scale=0.05, size=trefoil40.shape)
    sim = Simulation(x, platform="Reference")
    rot = Rotation.from_rotvec([0, 0, 0.7]).as_matrix()
    v = sim.velocity(x)
    np.testing.assert_allclose(
        sim.velocity(x @ rot.T + [5, -3, 100]), v @ rot.T, rtol=0, atol=1e-9 * np.abs(v).max()
    )
    # mirror z -> -z and flip gravity: velocities mirror (a consistency check of signs)
    mirror = np.diag([1.0, 1.0, -1.0])
    sim_up = Simulation(x @ mirror, ChainModel(gravity=-1.0), platform="Reference")
    np.testing.assert_allclose(
        sim_up.velocity(x @ mirror), v @ mirror, rtol=0, atol=1e-9 * np.abs(v).max()
    )


# -- invariants of the dynamics ---------------------------------------------------------------
@pytest.mark.parametrize("gravity", [0.0, 1.0])
def test_energy_never_increases(trefoil40, rng, gravity):
    """Overdamped with a positive definite mobility: dE/dt = -F . mu F <= 0."""
    x = trefoil40 + rng.normal(scale=0.06, size=trefoil40.shape)
    sim = Simulation(
        x, ChainModel(gravity=gravity), integrator=RK23(0.01, tolerance=1e-7), platform="Reference"
    )
    energies = [sim.energies()["total"]]
    f = sim.forces(sim.positions)
    assert np.sum(f * sim.velocity(sim.positions)) > 0  # -dE/dt = F . v > 0
    for _ in range(20):
        sim.run(0.1)
        energies.append(sim.energies()["total"])
    assert np.all(np.diff(energies) < 1e-9), np.diff(energies)
    assert energies[-1] < energies[0] - 0.01


def test_run_lands_exactly_on_report_times_with_adaptive_steps(trefoil40):
    times = []

    class Recorder:
        def __init__(self, interval):
            self.interval, self.index = interval, 0

        def next_report_time(self, simulation):
            return self.index * self.interval

        def report(self, simulation, state):
            times.append((simulation.time, simulation.currentStep))
            self.index += 1

    sim = Simulation(trefoil40, integrator=RK23(0.01), platform="Reference")
    sim.reporters.append(Recorder(0.3))
    sim.run(3.0)
    got = np.array([t for t, _ in times])
    np.testing.assert_allclose(got, 0.3 * np.arange(11), rtol=0, atol=1e-12)
    assert sim.time == pytest.approx(3.0, abs=1e-12)
    assert times[0][1] == 0
    assert sim.currentStep > 10  # several adaptive steps per report
    sim.run(0.45)  # continues: next report at 3.3, none at 3.45
    assert times[-1][0] == pytest.approx(3.3, abs=1e-12)
    assert sim.time == pytest.approx(3.45, abs=1e-12)


# -- OpenMM reporters -------------------------------------------------------------------------
class StepSpy:
    """An OpenMM-style reporter (tuple protocol of older OpenMM) recording what it sees."""

    def __init__(self, interval):
        self.interval = interval
        self.seen = []

    def describeNextReport(self, simulation):
        steps = self.interval - simulation.currentStep % self.interval
        return (steps, True, False, False, True)

    def report(self, simulation, state):
        self.seen.append(
            (
                simulation.currentStep,
                simulation.time,
                simulation.positions.copy(),
                state.getStepCount(),
                state.getTime().value_in_unit(openmm.unit.picosecond),
                state.getPositions(asNumpy=True).value_in_unit(openmm.unit.nanometer),
            )
        )


def _read_state_data(buffer):
    lines = buffer.getvalue().strip().splitlines()
    header = [h.strip('#"') for h in lines[0].split(",")]
    rows = np.array([[float(v) for v in line.split(",")] for line in lines[1:]])
    return header, rows


@pytest.mark.parametrize("integrator", ["heun", "rk23"])
def test_state_data_reporter_reports_at_the_right_steps_and_times(trefoil40, integrator):
    buffer = io.StringIO()
    reporter = openmm.app.StateDataReporter(buffer, 5, step=True, time=True, potentialEnergy=True)
    spy = StepSpy(5)
    integ = Heun(0.004) if integrator == "heun" else RK23(0.01)
    sim = Simulation(trefoil40, integrator=integ, platform="Reference")
    sim.reporters.extend([reporter, spy])
    sim.step(23)
    assert sim.currentStep == 23
    header, rows = _read_state_data(buffer)
    assert header[:3] == ["Step", "Time (ps)", "Potential Energy (kJ/mole)"]
    np.testing.assert_array_equal(rows[:, 0], [5, 10, 15, 20])  # never at step 0
    assert [s[0] for s in spy.seen] == [5, 10, 15, 20]
    for row, (step, t, pos, state_step, state_time, state_pos) in zip(rows, spy.seen, strict=True):
        assert state_step == step and state_time == pytest.approx(t, rel=1e-12)
        assert row[1] == pytest.approx(t, rel=1e-5)
        np.testing.assert_allclose(state_pos, pos, rtol=1e-12)
        # the energy reported is the model's energy of the positions at that step
        assert row[2] == pytest.approx(rm.energies(pos)["total"], rel=1e-5, abs=1e-5)
    if integrator == "heun":
        np.testing.assert_allclose(
            [s[1] for s in spy.seen], 0.004 * np.array([5, 10, 15, 20]), rtol=1e-12
        )


def test_step_and_time_reporters_together(trefoil40):
    """A run(duration) with both kinds: OpenMM reporters fire every k accepted steps, time
    reporters at their times, and both see consistent step counts."""
    spy = StepSpy(7)
    frames = []

    class Frames:
        index = 0

        def next_report_time(self, simulation):
            return self.index * 0.25

        def report(self, simulation, state):
            frames.append((simulation.time, simulation.currentStep))
            self.index += 1

    sim = Simulation(trefoil40, integrator=RK23(0.01), platform="Reference")
    sim.reporters.extend([spy, Frames()])
    sim.run(2.0)
    steps = [s[0] for s in spy.seen]
    assert steps == list(range(7, sim.currentStep + 1, 7))
    np.testing.assert_allclose([f[0] for f in frames], 0.25 * np.arange(9), atol=1e-12)
    assert all(np.diff([f[1] for f in frames]) > 0)


# -- faults -----------------------------------------------------------------------------------
def test_unstable_step_raises_a_fault_and_keeps_the_last_good_state(trefoil40):
    sim = Simulation(trefoil40, integrator=Euler(0.2), platform="Reference")
    with pytest.raises(SimulationFault) as info:
        sim.run(10.0)
    message = str(info.value)
    assert "bond" in message and "run.max_bond_length = 3" in message and "Hint" in message
    assert "\n" not in message
    assert np.all(np.isfinite(sim.positions))
    assert sim.bond_lengths().max() <= 3.0  # the last good state
    assert 0 < sim.time < 10.0


def test_fault_message_names_the_time_of_the_bad_state(trefoil40):
    """The message says "bond ... is L d long at t = T": T must be the time of the state in
    which the bond is L long (the rejected step's end), not the last good time."""
    sim = Simulation(trefoil40, integrator=Euler(0.2), platform="Reference")
    with pytest.raises(SimulationFault) as info:
        sim.run(10.0)
    message = str(info.value)
    t_msg = float(message.split(" at t = ")[1].split(" tau_d")[0])
    assert sim.bond_lengths().max() <= 3.0  # state kept: last good one, at sim.time
    assert t_msg == pytest.approx(sim.time + 0.2, rel=1e-6), message


def test_bad_starting_positions_fault_with_context(trefoil40):
    x = trefoil40.copy()
    x[5] += [4.0, 0.0, 0.0]
    with pytest.raises(SimulationFault, match=r"bond [45] \(beads [45]-[56]\) is .* the starting"):
        Simulation(x, platform="Reference")
    x = trefoil40.copy()
    x[7, 1] = np.nan
    with pytest.raises(Exception, match="NaN|non-finite"):
        Simulation(x, platform="Reference")


def test_tiny_max_bond_length_stops_the_run(trefoil40):
    sim = Simulation(trefoil40, integrator=RK23(0.01), platform="Reference", max_bond_length=0.6005)
    with pytest.raises(SimulationFault, match="past run.max_bond_length = 0.6005"):
        sim.run(5.0)
    assert sim.bond_lengths().max() <= 0.6005


def test_set_positions_forgets_the_cached_velocity(trefoil40, rng):
    """After set_positions, the FSAL integrators must not reuse the old velocity: the next
    step from the new positions equals a step of a fresh integrator."""
    for make in (lambda: RK23(0.01), lambda: RKC2(0.01)):
        sim = Simulation(trefoil40, integrator=make(), platform="Reference")
        sim.run(0.2)
        y = trefoil40 + rng.normal(scale=0.02, size=trefoil40.shape)
        sim.set_positions(y)
        fresh = make()
        fresh.set_state(sim.integrator.get_state())
        want, dt = fresh.step(sim.velocity, y)
        got, dt2 = sim.integrator.step(sim.velocity, y)
        assert dt == dt2
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-13)


def test_mobility_threads_do_not_change_the_trajectory(trefoil40):
    one = Simulation(trefoil40)
    two = Simulation(trefoil40, mobility_threads=2)
    one.run(2.0)
    two.run(2.0)
    assert one.currentStep == two.currentStep
    np.testing.assert_array_equal(two.positions, one.positions)
