"""The engine interface: what :class:`~knotmm.engine.simulation.Simulation` asks of an engine.

A :class:`~knotmm.engine.simulation.Simulation` owns the run's state (positions, time, the
OpenMM Context, the reporters and their schedule, the state checks); its engine owns how the
state moves (``docs/architecture.md``, "The engine in one loop"). Two engines implement
:class:`Engine`:

* :class:`knotmm.engine.python_engine.PythonEngine`: the integrators of
  :mod:`knotmm.dynamics`, stepped from Python, one velocity (OpenMM forces, then the RPY
  mobility) at a time: the readable reference the plugin is held to, and the engine of a
  checkout without a compiled plugin;
* :class:`knotmm.engine.plugin_engine.PluginEngine`: the compiled
  :class:`knotmm.plugin.RPYIntegrator`, which takes every step up to a report time in C++.

:func:`knotmm.engine.engines.make_engine` makes one by name; the Simulation has no other
knowledge of which one it has.
"""

from __future__ import annotations

import numpy as np
import openmm

__all__ = ["Engine"]


class Engine:
    """Base class of the engines: stepping, energies, checkpoints and counters of a run.

    Every method that takes ``sim`` works on that
    :class:`~knotmm.engine.simulation.Simulation`: it reads the positions and time, sets them
    after a step (``sim.positions``, ``sim.time``) and uses the Simulation's public hooks
    (:meth:`~knotmm.engine.simulation.Simulation.check_state`,
    :meth:`~knotmm.engine.simulation.Simulation.sync_context`, ...).

    Parameters
    ----------
    integrator : knotmm.dynamics.deterministic.Integrator
        The run's integrator (method and settings; the Python engine steps it).

    Attributes
    ----------
    name : str
        ``"python"`` or ``"plugin"`` (``run.engine``, and a checkpoint's ``engine``).
    integrator : knotmm.dynamics.deterministic.Integrator
    openmm_integrator : openmm.Integrator
        The integrator the Simulation's Context is created with.
    n_accepted : int
        Accepted steps of the run so far (:attr:`Simulation.currentStep`).
    n_evaluations : int
        Velocity (force + mobility) evaluations so far
        (:attr:`Simulation.n_evaluations`; :meth:`Simulation.velocity` adds one a call).
    """

    name = "base"

    def __init__(self, integrator):
        self.integrator = integrator
        self.openmm_integrator: openmm.Integrator | None = None
        self.n_accepted = 0
        self.n_evaluations = 0

    # -- counters -----------------------------------------------------------------------
    @property
    def n_rejected(self) -> int:
        """Steps rejected by error control so far (adaptive methods; 0 otherwise)."""
        raise NotImplementedError

    @property
    def timestep(self) -> float:
        """The next step to try (adaptive methods) or the fixed step, in tau_d."""
        raise NotImplementedError

    # -- stepping -----------------------------------------------------------------------
    def advance_to(self, sim, target: float) -> None:
        """Take every step from ``sim.time`` up to ``target`` (tau_d, finite), landing on it.

        Ends within :func:`knotmm.engine.schedule.landing_slack` of ``target``.

        Raises
        ------
        knotmm.errors.SimulationFault
            At the first bad step; ``sim`` then holds the last good state.
        knotmm.engine.interrupt.StopRequested
            A stop asked for by a signal, between two steps (the plugin engine: between two
            of its C++ calls, at most about a second apart).
        """
        raise NotImplementedError

    def advance_one(self, sim, target: float) -> float:
        """Take one accepted step of at most ``target - sim.time`` (``target`` may be inf).

        Returns
        -------
        float
            The step taken, in tau_d.

        Raises
        ------
        knotmm.errors.SimulationFault
            The step failed or gave a bad state; ``sim`` keeps the last good state.
        """
        raise NotImplementedError

    def reset(self, sim) -> None:
        """Forget what is held for the current positions (they were replaced from outside)."""
        self.integrator.reset()

    def use_integrator(self, integrator) -> bool:
        """Step with ``integrator`` from now on, before the first step, on the same Context
        (a run's ``auto`` choice after its stiffness probe). False: this engine cannot, and
        nothing changed: the caller builds a new Simulation (the Python engine and the
        plugin engine can: :meth:`PythonEngine.use_integrator
        <knotmm.engine.python_engine.PythonEngine.use_integrator>`, :meth:`PluginEngine.
        use_integrator <knotmm.engine.plugin_engine.PluginEngine.use_integrator>`)."""
        return False

    def stiffness(self, sim) -> float:
        """Spectral radius of the velocity Jacobian at ``sim``'s positions, in 1/tau_d.

        RKC's estimate (:meth:`knotmm.dynamics.deterministic.RKC2.spectral_radius`); its
        evaluations are not counted in :attr:`n_evaluations`.
        """
        raise NotImplementedError

    # -- energies -----------------------------------------------------------------------
    def group_energies(self, sim, positions: np.ndarray | None = None) -> dict[str, float]:
        """Energy of each term of :data:`knotmm.model.forces.FORCE_GROUPS`, in F0 d.

        Evaluated at ``positions`` (default: ``sim``'s), shifted to their centre of mass as
        forces are (the gravity term is the shifted one): one ``getState`` per force group
        (:meth:`Simulation.context_energies`).

        Parameters
        ----------
        sim : knotmm.engine.simulation.Simulation
        positions : ndarray, shape (n_beads, 3), in d, optional

        Returns
        -------
        dict
            Term name -> energy, in :data:`~knotmm.model.forces.FORCE_GROUPS`'s order.
        """
        pos = sim.positions if positions is None else positions
        return sim.context_energies(pos - pos.mean(axis=0))

    # -- checkpoints --------------------------------------------------------------------
    def checkpoint(self, sim) -> dict:
        """The engine's entries of a checkpoint (:func:`knotmm.engine.checkpoint.write_checkpoint`).

        Returns
        -------
        dict
            ``step``, ``evaluations``, ``integrator`` (name), ``integrator_state`` (dict),
            ``velocity`` (ndarray or None); the plugin engine adds ``engine`` and
            ``openmm_checkpoint``.
        """
        raise NotImplementedError

    def restore(self, sim, state: dict) -> None:
        """Restore what :meth:`checkpoint` saved.

        ``state`` is :func:`knotmm.engine.checkpoint.read_checkpoint`'s dict. Called after
        ``sim``'s positions and time were restored; the Simulation then puts them into the
        Context.
        """
        raise NotImplementedError

    def _restore_counters(self, state: dict) -> None:
        self.n_accepted = int(state["step"])
        self.n_evaluations = int(state["evaluations"])
