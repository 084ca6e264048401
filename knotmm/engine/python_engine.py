"""The Python engine: the integrators of :mod:`knotmm.dynamics`, stepped from Python.

Each step calls the integrator's ``step(rhs, y, max_dt)`` with
:meth:`knotmm.engine.simulation.Simulation.velocity` as ``rhs`` (OpenMM forces from the
Context, then the RPY mobility of :mod:`knotmm.dynamics.mobility`), so every formula of a
run is Python that can be read next to its docstring. It is the reference the compiled
plugin is held to (``tests/plugin``, ``tests/engine/test_engine_choice.py``), and the engine
that runs where no plugin is compiled, on GPU platforms, and with ``run.engine =
"python"``.
"""

from __future__ import annotations

import numpy as np
import openmm

from knotmm.dynamics.deterministic import StepSizeUnderflow
from knotmm.engine.base import Engine
from knotmm.engine.interrupt import raise_if_requested
from knotmm.engine.schedule import landing_slack
from knotmm.errors import SimulationFault

__all__ = ["PythonEngine"]


class PythonEngine(Engine):
    """Steps a :class:`~knotmm.engine.simulation.Simulation` with its Python integrator.

    Parameters
    ----------
    integrator : knotmm.dynamics.deterministic.Integrator
        Steps the run; its ``timestep`` and ``n_rejected`` are the engine's (the RPY pair
        loop's threads are the Simulation's ``mobility_threads``).

    Attributes
    ----------
    openmm_integrator : openmm.VerletIntegrator
        Never stepped (knotmm integrates); it holds the step size OpenMM reporters may read.
    """

    name = "python"

    def __init__(self, integrator):
        super().__init__(integrator)
        self.openmm_integrator = openmm.VerletIntegrator(integrator.timestep)
        # After a refused state the integrator holds the velocity of that state, not of the
        # kept one: a checkpoint must not store it.
        self._held_stale = False

    @property
    def n_rejected(self) -> int:
        return self.integrator.n_rejected

    @property
    def timestep(self) -> float:
        return self.integrator.timestep

    # -- stepping -----------------------------------------------------------------------
    def advance_to(self, sim, target: float) -> None:
        """Step up to ``target`` (tau_d); a stop asked for by a signal is taken between steps."""
        while True:
            self.advance_one(sim, target)
            if target - sim.time <= landing_slack(target):
                return
            raise_if_requested()

    def advance_one(self, sim, target: float) -> float:
        try:
            y_new, dt = self.integrator.step(sim.velocity, sim.positions, target - sim.time)
        except StepSizeUnderflow as exc:
            raise sim.underflow_fault(exc.timestep, exc.reason) from None
        try:
            sim.check_state(y_new, dt=dt)
        except SimulationFault:
            self._held_stale = True
            raise
        sim.positions = y_new
        sim.time += dt
        self.n_accepted += 1
        return dt

    def reset(self, sim) -> None:
        self.integrator.reset()
        self._held_stale = False

    def use_integrator(self, integrator) -> bool:
        """The integrator is Python: taken in place when it has the same step (which the
        Context's never-stepped ``VerletIntegrator`` holds) and no step was taken yet."""
        if self.n_accepted or integrator.timestep != self.integrator.timestep:
            return False
        self.integrator = integrator
        self._held_stale = False
        return True

    def stiffness(self, sim) -> float:
        from knotmm.dynamics.deterministic import RKC2

        counted = self.n_evaluations
        try:
            return RKC2(self.integrator.timestep).spectral_radius(
                sim.velocity, sim.positions, sim.velocity(sim.positions))
        finally:
            self.n_evaluations = counted

    # -- checkpoints --------------------------------------------------------------------
    def checkpoint(self, sim) -> dict:
        """Counters, the integrator's state and the velocity it holds (FSAL), if any."""
        held = self.integrator.held_velocity
        return {
            "step": self.n_accepted,
            "evaluations": self.n_evaluations,
            "integrator": self.integrator.name,
            "integrator_state": self.integrator.get_state(),
            "velocity": None if held is None or self._held_stale else np.asarray(held),
        }

    def restore(self, sim, state: dict) -> None:
        self.integrator.set_state(state["integrator_state"])  # forgets a held velocity
        if state["velocity"] is not None:
            self.integrator.held_velocity = state["velocity"]
        self._held_stale = False
        self._restore_counters(state)
