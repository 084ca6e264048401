"""The plugin engine: :class:`knotmm.plugin.RPYIntegrator` takes the steps, Python watches.

:class:`knotmm.engine.simulation.Simulation` with ``engine = "plugin"`` binds an
:class:`~knotmm.plugin.RPYIntegrator` to its OpenMM Context (same method, step, tolerance,
step bounds; ``kT = 1 / run.peclet`` in F0 d; the seed from ``run.seed``; the noise method,
``run.noise`` resolved for the chain's size, and ``run.lanczos_tolerance``) and hands each
stretch up to the next report time to :meth:`PluginEngine.advance_to`, one ``stepTo`` call
in C++. Then Python reads the positions (float64) once, updates the Simulation's time, step
and evaluation counts and the Python integrator's counters (which the run's summary and
observables read), and runs the Python engine's state checks (finite positions, bonds below
``run.max_bond_length``).

A fault inside a stretch is found exactly where the Python engine would find it: the stretch
is taken again from the Context checkpoint made at its start, one accepted step at a time
(:meth:`PluginEngine.advance_one`, the same steps as ``stepTo`` takes), with the checks
after each, so the fault names the same time, step, bead and value, and the last good state
is the one kept. A step-size underflow or non-finite positions in the plugin (an
``openmm.OpenMMException``) become the Python engine's messages too.

One limit of the step-by-step replay: the last step of a stretch is taken by
``stepTo(target)``; if error control rejects it, ``stepTo`` takes two accepted steps in that
call and a fault after the first of them is reported at the second.
"""

from __future__ import annotations

import math
import re

import numpy as np
import openmm
from openmm import unit

from knotmm.engine.openmm_state import state_array
from knotmm.errors import SimulationFault

__all__ = ["PluginEngine"]

_UNDERFLOW = re.compile(r"error estimate (\S+) x tolerance")
_NONFINITE = re.compile(r"non-finite at t = \S+ ps \(bead (\d+)\)")


class PluginEngine:
    """Steps a :class:`~knotmm.engine.simulation.Simulation` with the compiled integrator.

    Parameters
    ----------
    integrator : knotmm.dynamics.deterministic.Integrator
        The Python integrator of the run: its settings make the plugin integrator
        (:func:`knotmm.plugin.from_python_integrator`), and its counters (``n_accepted``,
        ``n_rejected``) and next step (``timestep``, adaptive methods) follow the plugin's.
    threads : int
        Threads of the plugin's RPY pair loop (same trajectory).
    n_beads : int, optional
        The chain's size, which resolves a Brownian run's ``run.noise = "auto"``
        (:func:`knotmm.plugin.noise_settings`).

    Attributes
    ----------
    rpy : knotmm.plugin.RPYIntegrator
        The OpenMM integrator the Simulation's Context is created with.
    """

    def __init__(self, integrator, threads: int = 1, n_beads: int | None = None):
        from knotmm.plugin import from_python_integrator

        self.mirror = integrator
        self.rpy = from_python_integrator(integrator, threads=threads, n_beads=n_beads)
        self.adaptive = bool(getattr(integrator, "adaptive", False))

    def stiffness(self, sim, rkc2) -> float:
        """The plugin rkc2's spectral-radius estimate at ``sim``'s positions, in 1/tau_d.

        A throwaway Context with a plugin copy of ``rkc2`` (a
        :class:`knotmm.dynamics.deterministic.RKC2`) takes one step from the positions; the
        estimate is made at the step's start (a rejected try makes it again there).
        """
        from knotmm.plugin import from_python_integrator

        probe = from_python_integrator(rkc2, threads=self.rpy.getNumThreads())
        context = openmm.Context(sim.system, probe, sim.context.getPlatform())
        context.setPositions(sim.context.getState(getPositions=True).getPositions())
        probe.step(1)
        return float(probe.getSpectralRadius())

    # -- reading the Context ------------------------------------------------------------
    def _counts(self) -> tuple[int, int, int]:
        r = self.rpy
        return r.getNumAcceptedSteps(), r.getNumForceEvaluations(), r.getNumRejectedSteps()

    def _step_size(self) -> float:
        return self.rpy.getStepSize().value_in_unit(unit.picosecond)

    @staticmethod
    def _read(sim) -> tuple[np.ndarray, float]:
        """Bead positions, shape (n_beads, 3), float64 in d, and the time (tau_d)."""
        state = sim.context.getState(getPositions=True)
        out = state_array(state, "positions", sim.system.getNumParticles())
        return out[: sim.n_beads].copy(), state.getTime().value_in_unit(unit.picosecond)

    def _count(self, sim, before, steps: bool = True) -> None:
        """Add the plugin's counts since ``before`` to the Simulation and the mirror."""
        accepted, evaluations, rejected = self._counts()
        sim.n_evaluations += evaluations - before[1]
        self.mirror.n_rejected += rejected - before[2]
        if steps:
            sim.currentStep += accepted - before[0]
            self.mirror.n_accepted += accepted - before[0]
        if self.adaptive:
            self.mirror.timestep = self._step_size()

    def _fine(self, sim, y: np.ndarray) -> bool:
        return bool(np.all(np.isfinite(y))
                    and np.max(sim.bond_lengths(y)) <= sim.max_bond_length)

    # -- stepping -----------------------------------------------------------------------
    def advance_to(self, sim, target: float) -> None:
        """Advance ``sim`` to ``target`` (tau_d) in one ``stepTo`` call, then check the state.

        Raises
        ------
        SimulationFault
            As the Python engine would, at the first bad step (found by replaying the
            stretch); ``sim`` then holds the last good state.
        """
        sim._sync_context()  # reporters may have moved the Context's positions
        start = sim.context.createCheckpoint()
        before = self._counts()
        try:
            self.rpy.stepTo(target)
        except openmm.OpenMMException:
            fine = False
        else:
            y, t = self._read(sim)
            fine = self._fine(sim, y)
        if fine:
            sim.positions = y
            sim.time = t
            self._count(sim, before)
            return
        sim.context.loadCheckpoint(start)  # the counters go back with it
        while sim.time < target - _slack(target):
            self.advance_one(sim, target)

    def advance_one(self, sim, target: float) -> float:
        """One accepted step of at most ``target - sim.time`` (what ``stepTo`` would take).

        Returns
        -------
        float
            The step taken, in tau_d.
        """
        sim._sync_context()  # reporters may have moved the Context's positions
        remaining = target - sim.time
        before = self._counts()
        h = self._step_size()
        landing = math.isfinite(target) and not sim.time + h < target - _slack(target)
        last_good = sim.context.createCheckpoint()
        try:
            if landing:
                self.rpy.stepTo(target)
            else:
                self.rpy.step(1)  # not clipped by the target: the same step stepTo takes
        except openmm.OpenMMException as exc:
            self._count(sim, before, steps=False)  # the plugin kept the last good state
            raise self._fault(sim, str(exc), min(h, remaining)) from None
        y, t = self._read(sim)
        try:
            sim._check_state(y, dt=t - sim.time)
        except SimulationFault:
            self._count(sim, before, steps=False)
            sim.context.loadCheckpoint(last_good)
            raise
        dt = t - sim.time
        sim.positions = y
        sim.time = t
        self._count(sim, before)
        return dt

    def _fault(self, sim, message: str, h: float) -> SimulationFault:
        """The Python engine's fault for an exception of the plugin's step."""
        underflow = _UNDERFLOW.search(message)
        if underflow and self.adaptive:
            err = float(underflow.group(1))
            reason = f"{self.mirror.name} error estimate {err:.3g} x tolerance"
            return sim._underflow_fault(self._step_size(), reason)
        nonfinite = _NONFINITE.search(message)
        if nonfinite:
            y = sim.positions.copy()
            y[int(nonfinite.group(1))] = math.nan
            try:
                sim._check_state(y, dt=h)
            except SimulationFault as fault:
                return fault
        return SimulationFault(
            f"the plugin's step failed at t = {sim.time:.6g} tau_d (step {sim.currentStep}; "
            f"this last good state is kept): {' '.join(message.split())}. Hint: "
            f"run.engine = \"python\" runs the same model with the Python integrators"
        )

    # -- energies -----------------------------------------------------------------------
    def group_energies(self, groups) -> list[float]:
        """Energy of each force group at the Context's positions, in F0 d (one C++ call).

        Evaluated as the steps evaluate forces, with the beads shifted to their centre of
        mass (:meth:`knotmm.plugin.RPYIntegrator.getGroupEnergies`): an external field's
        energy (gravity) is the shifted one. The Context and the integrator's state are left
        as they were, so the run goes on bit for bit as without the call.
        """
        return list(self.rpy.getGroupEnergies(list(groups)))

    # -- checkpoints --------------------------------------------------------------------
    def checkpoint(self, sim) -> bytes:
        """The Context's checkpoint (positions, time, integrator and noise state)."""
        sim._sync_context()  # reporters may have moved the Context's positions
        return sim.context.createCheckpoint()

    @staticmethod
    def restore(sim, blob: bytes) -> None:
        sim.context.loadCheckpoint(blob)


def _slack(t: float) -> float:
    """The landing tolerance of ``stepTo`` and of the Python engine: relative 1e-9."""
    return 1e-9 * max(1.0, abs(t))
