"""The plugin engine: :class:`knotmm.plugin.RPYIntegrator` takes the steps, Python watches.

:class:`knotmm.engine.simulation.Simulation` with ``engine = "plugin"`` binds an
:class:`~knotmm.plugin.RPYIntegrator` to its OpenMM Context (same method, step, tolerance,
step bounds; ``kT = 1 / run.peclet`` in F0 d; the seed from ``run.seed``; the noise method,
``run.noise`` resolved for the chain's size, and ``run.lanczos_tolerance``) and hands each
stretch up to the next report time to :meth:`PluginEngine.advance_to`. The stretch is
stepped in C++ by ``stepToWithin(target, chunk_seconds)`` calls, each of which gives control
back between two steps once :attr:`PluginEngine.chunk_seconds` of wall-clock time are spent
(issue 30: one ``stepTo`` call for the whole stretch held a blown-up run, or one whose step
is far below the stretch, in C++ for minutes, deaf to SIGINT and SIGTERM). After each call
Python reads the positions (float64) once, updates the Simulation's time and the engine's
counters (steps, evaluations, rejections: the plugin's since the call began; the step size is
the plugin's), runs the Python engine's state checks (finite positions, bonds below
``run.max_bond_length``) and takes a stop asked for by a signal
(:func:`knotmm.engine.interrupt.raise_if_requested`). Where the calls end never changes a
step: the steps are those of one ``stepTo(target)``, so runs, checkpoints and resumed runs
are the same bit for bit whatever the machine's speed.

A fault inside a call is found exactly where the Python engine would find it: the call's
steps are taken again from the Context checkpoint made at its start, one accepted step at a
time (:meth:`PluginEngine.advance_one`, ``stepToWithin(target, 0)``: the same steps), with the
checks after each, so the fault names the same time, step, bead and value, and the last good
state is the one kept. A failed plugin step raises :class:`knotmm.plugin.StepFault` (an
``openmm.OpenMMException`` that says its ``kind``, ``bead`` and ``error_estimate``): a step-size
underflow or non-finite positions become the Python engine's messages too.
"""

from __future__ import annotations

import logging
import math

import numpy as np
import openmm
from openmm import unit

from knotmm.engine.base import Engine
from knotmm.engine.interrupt import raise_if_requested
from knotmm.engine.openmm_state import state_array
from knotmm.engine.schedule import landing_slack
from knotmm.errors import SimulationFault

log = logging.getLogger(__name__)

__all__ = ["PluginEngine"]


class PluginEngine(Engine):
    """Steps a :class:`~knotmm.engine.simulation.Simulation` with the compiled integrator.

    Parameters
    ----------
    integrator : knotmm.dynamics.deterministic.Integrator
        The Python integrator of the run: its settings make the plugin integrator
        (:func:`knotmm.plugin.from_python_integrator`); it is never stepped, and its
        counters and step size stay as they were (the engine's are the plugin's).
    threads : int
        Threads of the plugin's RPY pair loop (same trajectory).
    n_beads : int, optional
        The chain's size, which resolves a Brownian run's ``run.noise = "auto"``
        (:func:`knotmm.plugin.noise_settings`).

    Attributes
    ----------
    rpy, openmm_integrator : knotmm.plugin.RPYIntegrator
        The OpenMM integrator the Simulation's Context is created with.
    chunk_seconds : float
        Wall-clock seconds one C++ call steps before it gives control back, between two
        steps (a single step that takes longer ends its call when it is done): how soon a
        signal, a stop request or a bad state is seen. It decides where calls end, never a
        step.
    """

    name = "plugin"
    chunk_seconds = 0.25

    def __init__(self, integrator, threads: int = 1, n_beads: int | None = None):
        from knotmm.plugin import from_python_integrator

        super().__init__(integrator)
        self.rpy = from_python_integrator(integrator, threads=threads, n_beads=n_beads)
        self.openmm_integrator = self.rpy
        self._threads, self._n_beads = threads, n_beads
        self.adaptive = bool(getattr(integrator, "adaptive", False))
        self._rejected = 0
        self.group = None  # a knotmm.engine.copies.CopyGroup that takes the steps, or None
        self.copy_index = -1

    # -- counters -----------------------------------------------------------------------
    @property
    def n_rejected(self) -> int:
        return self._rejected

    @property
    def timestep(self) -> float:
        """The plugin's next step (adaptive methods), else the integrator's fixed step."""
        return self._step_size() if self.adaptive else self.integrator.timestep

    def use_integrator(self, integrator) -> bool:
        """Step with ``integrator``'s method and settings from now on, on the same Context
        (``RPYIntegrator.setMethod``: the kernel made again for the method, as in a new
        Context; before the first step). False, nothing changed, where a setting cannot
        change in a Context (the noise's seed, kT), for a replica of a copy group, or with a
        plugin built before ``setMethod``."""
        from knotmm.plugin import from_python_integrator

        r = self.rpy
        if self.n_accepted or self.group is not None or not hasattr(r, "setMethod"):
            return False
        fresh = from_python_integrator(integrator, threads=self._threads, n_beads=self._n_beads)
        if (fresh.getRandomNumberSeed(), fresh.getThermalEnergy()) != (
                r.getRandomNumberSeed(), r.getThermalEnergy()):
            return False
        r.setErrorTolerance(fresh.getErrorTolerance())
        r.setMinimumStepSize(fresh.getMinimumStepSize())
        r.setMaximumStepSize(fresh.getMaximumStepSize())
        r.setNoiseMethod(fresh.getNoiseMethod())
        r.setLanczosTolerance(fresh.getLanczosTolerance())
        r.setStepSize(fresh.getStepSize())
        r.setMethod(fresh.getMethod())
        self.integrator = integrator
        self.adaptive = bool(getattr(integrator, "adaptive", False))
        self._rejected = self.n_evaluations = 0
        return True

    def stiffness(self, sim) -> float:
        """The plugin rkc2's spectral-radius estimate at ``sim``'s positions, in 1/tau_d.

        Asked of the run's own Context (``RPYIntegrator.estimateSpectralRadius``: rkc2's
        power iteration from its start vector, as a fresh rkc2 makes it before its first
        step; no step, nothing else changed, no second Context). No numba kernel is loaded.
        """
        sim.sync_context()
        try:
            rho = float(self.rpy.estimateSpectralRadius())
        except openmm.OpenMMException as exc:  # the run itself reports a start it cannot step
            log.info("stiffness probe failed (%s)", " ".join(str(exc).split()))
            return math.inf
        return rho if math.isfinite(rho) else math.inf

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

    def _count(self, before, steps: bool = True) -> None:
        """Add the plugin's counts since ``before`` to the engine's."""
        accepted, evaluations, rejected = self._counts()
        self.n_evaluations += evaluations - before[1]
        self._rejected += rejected - before[2]
        if steps:
            self.n_accepted += accepted - before[0]

    @staticmethod
    def _fine(sim, y: np.ndarray) -> bool:
        return bool(np.all(np.isfinite(y))
                    and np.max(sim.bond_lengths(y)) <= sim.max_bond_length)

    # -- stepping -----------------------------------------------------------------------
    def advance_to(self, sim, target: float) -> None:
        """Advance ``sim`` to ``target`` (tau_d) in calls of :attr:`chunk_seconds` each.

        Between two calls the state is checked and a stop asked for by a signal is taken.

        Raises
        ------
        SimulationFault
            As the Python engine would, at the first bad step (found by replaying the call
            that reached it); ``sim`` then holds the last good state.
        knotmm.engine.interrupt.StopRequested
            A stop asked for by a signal, between two calls; ``sim`` holds a whole step.
        """
        if self.group is not None and self._advance_with_group(sim, target):
            return
        while not self._advance_within(sim, target):
            raise_if_requested()

    def _advance_with_group(self, sim, target: float) -> bool:
        """The stretch to ``target`` stepped by :attr:`group` with the other replicas'; the
        replica's Context then holds what it reached. False: the copy failed, or reached a
        state the checks refuse, and nothing changed here (the caller takes the stretch
        alone, where the fault is found as in a run alone)."""
        sim.sync_context()
        before = self._counts()
        positions, time, state = self.group.advance(self.copy_index, sim, target)
        if positions is None or not self._fine(sim, positions):  # found again alone
            return False
        self.rpy.setIntegratorState(state)
        sim.positions = positions
        sim.time = time
        self._count(before)
        sim.sync_context()
        return True

    def _advance_within(self, sim, target: float) -> bool:
        """One ``stepToWithin(target, chunk_seconds)`` call, checked; True at ``target``."""
        sim.sync_context()  # reporters may have moved the Context's positions
        start = sim.context.createCheckpoint()
        before = self._counts()
        failed = False
        try:
            with sim.core_pin.stepping():  # OpenMM's pool thread on this core: same bits
                reached = self.rpy.stepToWithin(target, self.chunk_seconds)
        except openmm.OpenMMException:
            failed = True  # the plugin kept the last good state, before the failed step
        y, t = self._read(sim)
        if not failed and self._fine(sim, y):
            sim.positions = y
            sim.time = t
            self._count(before)
            return bool(reached)
        # Take the call's steps again, one at a time and checked: the fault is raised at the
        # step the Python engine would name. The counters go back with the checkpoint.
        sim.context.loadCheckpoint(start)
        while sim.time < t - landing_slack(t):
            self.advance_one(sim, target)
        if failed:
            self.advance_one(sim, target)  # the step that failed: raises its fault
        return target - sim.time <= landing_slack(target)

    def advance_one(self, sim, target: float) -> float:
        """One accepted step of at most ``target - sim.time`` (a step ``stepTo`` would take)."""
        from knotmm.plugin import StepFault

        sim.sync_context()  # reporters may have moved the Context's positions
        remaining = target - sim.time
        before = self._counts()
        h = self._step_size()
        last_good = sim.context.createCheckpoint()
        try:
            with sim.core_pin.stepping():
                if math.isfinite(target):
                    self.rpy.stepToWithin(target, 0.0)  # exactly one of stepTo's steps
                else:
                    self.rpy.step(1)
        except openmm.OpenMMException as exc:
            self._count(before, steps=False)  # the plugin kept the last good state
            fault = exc if isinstance(exc, StepFault) else None
            raise self._fault(sim, fault, str(exc), min(h, remaining)) from None
        y, t = self._read(sim)
        try:
            sim.check_state(y, dt=t - sim.time)
        except SimulationFault:
            self._count(before, steps=False)
            sim.context.loadCheckpoint(last_good)
            raise
        dt = t - sim.time
        sim.positions = y
        sim.time = t
        self._count(before)
        return dt

    def _fault(self, sim, fault, message: str, h: float) -> SimulationFault:
        """The Python engine's fault for a failed plugin step.

        ``fault`` is the :class:`knotmm.plugin.StepFault` (``None`` for another
        ``openmm.OpenMMException``), ``message`` its text, ``h`` the step tried (tau_d).
        """
        kind = None if fault is None else fault.kind
        if kind == "step_underflow" and self.adaptive:
            reason = f"{self.integrator.name} error estimate {fault.error_estimate:.3g} x tolerance"
            return sim.underflow_fault(self._step_size(), reason)
        if kind == "non_finite" and 0 <= fault.bead < sim.n_beads:
            y = sim.positions.copy()
            y[fault.bead] = math.nan
            try:
                sim.check_state(y, dt=h)
            except SimulationFault as found:
                return found
        return SimulationFault(
            f"the plugin's step failed at t = {sim.time:.6g} tau_d (step {sim.currentStep}; "
            f"this last good state is kept): {' '.join(message.split())}. Hint: "
            f"run.engine = \"python\" runs the same model with the Python integrators"
        )

    # -- energies -----------------------------------------------------------------------
    def group_energies(self, sim, positions: np.ndarray | None = None) -> dict[str, float]:
        """Energy of each force group, in F0 d; at ``sim``'s positions in one C++ call.

        Without ``positions``, :meth:`knotmm.plugin.RPYIntegrator.getGroupEnergies`
        evaluates every group at the Context's positions (a translate of ``sim``'s), with
        the beads shifted to their centre of mass as the steps evaluate forces: no
        ``setPositions``, one evaluation per group. The Context and the integrator's state
        are left as they were, so the run goes on bit for bit as without the call. With
        ``positions``: :meth:`Engine.group_energies`.
        """
        if positions is not None:
            return super().group_energies(sim, positions)
        from knotmm.model.forces import FORCE_GROUPS

        if not sim.context_current:
            sim.sync_context()
        energies = self.rpy.getGroupEnergies(list(FORCE_GROUPS.values()))
        return dict(zip(FORCE_GROUPS, energies, strict=True))

    # -- checkpoints --------------------------------------------------------------------
    def checkpoint(self, sim) -> dict:
        """Counters and the Context's checkpoint (``Context.createCheckpoint``: positions,
        time, the plugin's step size, counters, cached velocity and noise stream).

        ``integrator_state`` is the Python integrator's, with the engine's step size and
        counts (as the files written before the engine interface hold it).
        """
        sim.sync_context()  # reporters may have moved the Context's positions
        state = self.integrator.get_state()
        state.update(timestep=self.timestep, n_accepted=self.n_accepted,
                     n_rejected=self.n_rejected)
        return {
            "step": self.n_accepted,
            "evaluations": self.n_evaluations,
            "integrator": self.integrator.name,
            "integrator_state": state,
            "velocity": None,
            "engine": self.name,
            "openmm_checkpoint": sim.context.createCheckpoint(),
        }

    def restore(self, sim, state: dict) -> None:
        sim.context.loadCheckpoint(state["openmm_checkpoint"])
        self._rejected = int(state["integrator_state"].get("n_rejected", 0))
        self._restore_counters(state)
