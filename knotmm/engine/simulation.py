"""The run loop: an OpenMM ``Context`` computes forces, knotmm moves the beads.

:class:`Simulation` mirrors ``openmm.app.Simulation`` closely enough that OpenMM's own
reporters (``StateDataReporter``, ...) work with it: it has ``context``, ``system``,
``topology``, ``integrator``, ``currentStep`` and ``reporters``, and schedules reporters that
implement ``describeNextReport`` by steps, as OpenMM does. knotmm's own reporters are
scheduled by simulated time instead (they implement ``next_report_time``), and the
integrator lands exactly on their times, so frames are equally spaced even with adaptive
steps. The loop, in the style of HOOMD-blue's ``Simulation.run``::

    if write_at_start: time reporters report the current state (frame 0)
    while time < end_time and step < end_step:
        take one accepted integrator step, never past the next time report
        check positions (finite) and bonds (below max_bond_length), else SimulationFault
        step += 1; time += dt
        reporters whose step or time has come report (Context step count and time updated)

:meth:`Simulation.from_config` builds one from a run configuration;
:meth:`Simulation.saveCheckpoint` and :meth:`Simulation.loadCheckpoint` save and restore its
whole state (positions, time, step, counters, integrator and random state), so that a run
goes on bit for bit after a stop (``docs/architecture.md``).

Who takes the steps is the Simulation's engine (:class:`knotmm.engine.base.Engine`: the
Python integrators or the compiled plugin, :func:`knotmm.engine.engines.make_engine`); the
Simulation asks it to advance, for energies, the stiffness, its checkpoint entries and its
counters, and never asks which one it is.

One "step" is one accepted step of the integrator, whatever its length. Positions are
float64 and live in :attr:`Simulation.positions`; the Context only sees them, shifted by
their centre of mass, when forces are needed (translation does not change the forces, and
the shift keeps single-precision platforms precise however far the chain has fallen).
"""

from __future__ import annotations

import logging
import math

import numpy as np
import openmm
from openmm import unit

from knotmm.dynamics.deterministic import RK23, Integrator
from knotmm.engine.affinity import CorePin
from knotmm.engine.checkpoint import read_checkpoint, write_checkpoint
from knotmm.engine.engines import PYTHON, make_engine, resolve_engine, select_platform
from knotmm.engine.interrupt import raise_if_requested
from knotmm.engine.openmm_state import state_array
from knotmm.engine.schedule import landing_slack
from knotmm.errors import ConfigError, SimulationFault, TrajectoryFileError
from knotmm.model.layout import ChainLayout
from knotmm.model.system import FORCE_GROUPS, ChainModel, chain_system, site_positions
from knotmm.model.topology import bead_topology

__all__ = ["Simulation"]

log = logging.getLogger(__name__)


class Simulation:
    """Overdamped dynamics of a closed chain with RPY hydrodynamics.

    Parameters
    ----------
    positions : array_like, shape (n_beads, 3), in d
        Starting positions (copied to float64).
    model : ChainModel, optional
        Model parameters; default: the study's.
    integrator : Integrator, optional
        Time stepper; default :class:`knotmm.dynamics.deterministic.RK23` with tolerance 1e-4 d.
    platform : str
        OpenMM platform name or ``"auto"`` (see :func:`knotmm.engine.engines.select_platform`).
    threads : int
        Threads of the CPU platform.
    max_bond_length : float
        A bond longer than this (in d) stops the run with :class:`SimulationFault`.
    mobility_threads : int
        Threads of the RPY pair loop (:func:`knotmm.dynamics.mobility.rpy_velocities`, or the
        plugin's); the trajectory does not depend on it.
    engine : {"python", "plugin"}
        Who takes the steps: ``integrator`` from Python, or the compiled
        :class:`knotmm.plugin.RPYIntegrator` with its settings, which takes every step up to
        the next report time in C++ (:mod:`knotmm.engine.plugin_engine`); resolve
        ``run.engine`` with :func:`knotmm.engine.engines.resolve_engine`.
    layout : ChainLayout, optional
        The chains of the system (:class:`knotmm.model.layout.ChainLayout`); default: one
        ring of all the beads. The mobility couples every bead of every chain.
    precision : {"auto", "mixed", "double"}
        A device platform's precision (``run.precision``; ``"auto"`` is mixed).

    Attributes
    ----------
    positions : ndarray, shape (n_beads, 3), float64, in d
    time : float
        Simulated time, in tau_d.
    currentStep : int
        Accepted integrator steps so far (OpenMM's name, so OpenMM reporters work).
    n_evaluations : int
        Velocity (force + mobility) evaluations so far.
    n_rejected : int
        Steps rejected by error control so far (adaptive integrators).
    timestep : float
        The next step to try (adaptive) or the fixed step, in tau_d.
    engine : str
        ``"python"`` or ``"plugin"``.
    integrator : knotmm.dynamics.deterministic.Integrator
        The run's integrator: its method and settings (the Python engine steps it; the
        plugin engine copies it, and its own counters stay unused: read the ones above).
    openmm_integrator : openmm.Integrator
        The integrator of :attr:`context` (the plugin engine's
        :class:`knotmm.plugin.RPYIntegrator`; for the Python engine a never-stepped
        ``VerletIntegrator`` holding the step size).
    """

    def __init__(
        self,
        positions,
        model: ChainModel | None = None,
        integrator: Integrator | None = None,
        platform: str = "auto",
        threads: int = 1,
        max_bond_length: float = 3.0,
        mobility_threads: int = 1,
        engine: str = PYTHON,
        layout: ChainLayout | None = None,
        precision: str = "auto",
    ):
        pos = np.array(positions, dtype=np.float64)
        self.mobility_threads = int(mobility_threads)
        self.model = ChainModel() if model is None else model
        self.layout = ChainLayout.ring(pos.shape[0]) if layout is None else layout
        self.system = chain_system(pos, self.model, self.layout)
        self._n_particles = self.system.getNumParticles()  # the beads, then any sites
        self.topology = bead_topology(self.layout)
        self.integrator = RK23(0.01) if integrator is None else integrator
        plat, props = select_platform(platform, pos.shape[0], threads, engine, precision)
        self._engine = make_engine(engine, self.integrator, threads=self.mobility_threads,
                                   n_beads=pos.shape[0])
        self.openmm_integrator = self._engine.openmm_integrator
        # The CPU platform's one pool thread and the thread asking for forces share a core
        # while the plugin steps (knotmm.engine.affinity): half the wall time of a run here.
        self.core_pin = CorePin(plat.getName() == "CPU" and int(threads) == 1
                                and self.mobility_threads == 1)
        with self.core_pin.creating():
            self.context = openmm.Context(self.system, self.openmm_integrator, plat, props)
        self.platform_name = plat.getName()
        self.positions = pos
        self.n_beads = pos.shape[0]
        self.bonds = self.layout.bonds()
        self.max_bond_length = float(max_bond_length)
        self.time = 0.0
        self.reporters: list = []
        self.last_velocity: np.ndarray | None = None
        self._context_current = False  # the Context holds a translate of `positions`
        self.check_state(self.positions, initial=True)
        self.sync_context()

    def __repr__(self) -> str:
        return (f"Simulation({self.layout.describe()}, t = {self.time:g} tau_d, "
                f"step {self.currentStep}, "
                f"{self.integrator.name} on the {self.engine} engine, {self.platform_name})")

    # -- the engine's state -------------------------------------------------------------
    @property
    def engine(self) -> str:
        """The engine that takes the steps: ``"python"`` or ``"plugin"``."""
        return self._engine.name

    @property
    def currentStep(self) -> int:  # noqa: N802 - OpenMM's name
        """Accepted integrator steps so far (settable, as OpenMM's ``Simulation``'s)."""
        return self._engine.n_accepted

    @currentStep.setter
    def currentStep(self, value: int) -> None:  # noqa: N802
        self._engine.n_accepted = int(value)

    @property
    def n_evaluations(self) -> int:
        """Velocity (force + mobility) evaluations so far, the engine's and
        :meth:`velocity`'s."""
        return self._engine.n_evaluations

    @property
    def n_rejected(self) -> int:
        """Steps rejected by error control so far (adaptive integrators; 0 otherwise)."""
        return self._engine.n_rejected

    @property
    def timestep(self) -> float:
        """The next step the engine tries (adaptive) or its fixed step, in tau_d."""
        return self._engine.timestep

    @classmethod
    def from_config(
        cls, cfg, positions=None, engine: str | None = None, layout: ChainLayout | None = None,
        integrator: Integrator | None = None,
    ) -> Simulation:
        """The Simulation a run configuration describes.

        Parameters
        ----------
        cfg : knotmm.config.RunConfig
            Model (``[model]``), integrator and platform (``[run]``) settings.
        positions : array_like, shape (n_beads, 3), in d, optional
            Starting positions; default: the template of ``cfg`` (``[knot]``), built by
            :func:`knotmm.shapes.builder.build_template`.
        engine : {"python", "plugin"}, optional
            The engine to use; default: ``run.engine`` resolved by
            :func:`knotmm.engine.engines.resolve_engine` (``"plugin"`` without the plugin
            warns once and gives the Python engine).
        layout : ChainLayout, optional
            The chains of ``positions``; default: those of the template (one ring for a
            knot).
        integrator : Integrator, optional
            A fresh integrator for the run (the run plan's, :mod:`knotmm.plan`, which built it
            once from ``cfg``); default: built here from ``cfg``'s ``[run]`` table
            (:func:`knotmm.dynamics.registry.integrator_from_config`).

        Raises
        ------
        ConfigError, TemplateError
            A bad integrator, platform or template; nothing is written.
        """
        if integrator is None:
            from knotmm.dynamics.registry import integrator_from_config

            integrator = integrator_from_config(cfg)
        if positions is None:
            from knotmm.shapes.builder import build_template

            template = build_template(cfg)
            positions, layout = template.positions, template.layout
        if engine is None:  # the engine first: "auto" takes the platform the engine can use
            platform = cfg["run.platform"]
            if platform != "auto":
                platform = select_platform(platform, np.shape(positions)[0],
                                           cfg["run.threads"])[0].getName()
            engine = resolve_engine(cfg["run.engine"], integrator.name, cfg["run.peclet"],
                                    platform)
        return cls(
            positions,
            ChainModel.from_config(cfg),
            integrator,
            platform=cfg["run.platform"],
            threads=cfg["run.threads"],
            max_bond_length=cfg["run.max_bond_length"],
            mobility_threads=cfg["run.mobility_threads"],
            engine=engine,
            layout=layout,
            precision=cfg["run.precision"],
        )

    # -- checkpoints (OpenMM's names) -------------------------------------------------------
    def saveCheckpoint(self, path, extra: dict | None = None,  # noqa: N802
                       arrays: dict | None = None) -> None:
        """Save the whole state to ``path`` atomically (:mod:`knotmm.engine.checkpoint`).

        The file holds positions and time, and the engine's entries
        (:meth:`knotmm.engine.base.Engine.checkpoint`): step, velocity evaluations, the
        integrator's name and state (step size, controller memory, random state) and the
        velocity it holds for the current positions, if any; the plugin engine adds its
        name and the Context's checkpoint (``Context.createCheckpoint``: the plugin's step
        size, counters, cached velocity and noise stream). ``extra`` (a dict of JSON values:
        a run's output counters, ...) rides along and is returned by :meth:`loadCheckpoint`;
        ``arrays`` (name -> float64 array) too, read back by
        :func:`knotmm.engine.checkpoint.read_checkpoint` (``arrays``).
        """
        write_checkpoint(path, {
            "positions": self.positions,
            "time": self.time,
            "counters": extra or {},
            **self._engine.checkpoint(self),
            **({"arrays": arrays} if arrays else {}),
        })

    def loadCheckpoint(self, path) -> dict:  # noqa: N802
        """Restore the state saved by :meth:`saveCheckpoint`; return its ``extra`` dict.

        The simulation goes on exactly as the saved one would have: same positions, time,
        step, evaluation count, step size and random stream.

        Raises
        ------
        TrajectoryFileError
            The file is missing or damaged, or it was written for another integrator, bead
            count or engine.
        """
        state = read_checkpoint(path)
        if state["engine"] != self.engine:
            raise TrajectoryFileError(
                f"checkpoint {str(path)!r} was written by the {state['engine']} engine, this "
                f"simulation uses the {self.engine} engine (run.engine); the files do not "
                f"belong together"
            )
        if state["integrator"] != self.integrator.name:
            raise TrajectoryFileError(
                f"checkpoint {str(path)!r} was written by integrator {state['integrator']!r}, "
                f"this simulation uses {self.integrator.name!r} (run.integrator); the files do "
                f"not belong together"
            )
        if state["positions"].shape != self.positions.shape:
            raise TrajectoryFileError(
                f"checkpoint {str(path)!r} holds {state['positions'].shape[0]} beads, this "
                f"simulation has {self.n_beads}; the files do not belong together"
            )
        self.check_state(state["positions"], initial=True)
        self.positions = state["positions"]
        self.time = state["time"]
        self._engine.restore(self, state)
        self.sync_context()
        return state["counters"]

    # -- physics ------------------------------------------------------------------------
    def forces(self, positions: np.ndarray) -> np.ndarray:
        """Total force on every bead, shape (n_beads, 3), in F0 (from the OpenMM Context)."""
        self._put_positions(positions - positions.mean(axis=0))
        self._context_current = False
        state = self.context.getState(getForces=True)
        forces = state_array(state, "forces", self._n_particles)
        # forces on midpoint sites are already distributed onto their beads by OpenMM
        return forces[: self.n_beads] if self.model.segment_repulsion else forces

    def velocity(self, positions: np.ndarray) -> np.ndarray:
        """Bead velocities ``mu(r) F(r)``, shape (n_beads, 3), in d/tau_d."""
        # imported here: a plugin-engine run never loads numba's kernels (about a second)
        from knotmm.dynamics.mobility import rpy_velocities

        self._engine.n_evaluations += 1
        return rpy_velocities(positions, self.forces(positions), threads=self.mobility_threads)

    def use_integrator(self, integrator) -> bool:
        """Step with a fresh ``integrator`` instead, before the first step, keeping the
        Context (:meth:`knotmm.engine.base.Engine.use_integrator`: both engines can; False
        where the engine cannot, and nothing changed)."""
        if self.currentStep or not self._engine.use_integrator(integrator):
            return False
        self.integrator = integrator
        return True

    def stiffness(self) -> float:
        """Spectral radius of the velocity Jacobian at the current positions, in 1/tau_d.

        RKC's estimate (:meth:`knotmm.dynamics.deterministic.RKC2.spectral_radius`: a power
        iteration by finite differences, times 1.2; with the plugin engine, the plugin's
        rkc2 makes the same estimate: :meth:`knotmm.engine.base.Engine.stiffness`). Its
        evaluations are not counted in :attr:`n_evaluations`.
        """
        return self._engine.stiffness(self)

    def energies(self, positions: np.ndarray | None = None) -> dict[str, float]:
        """Energy of each term (``bond``, ``bend``, ``steric``, ``gravity``) and ``total``.

        In F0 d; gravity is ``g sum z`` with the true (unshifted) heights. Each term is
        evaluated at the positions shifted to their centre of mass, as forces are, by the
        engine (:meth:`knotmm.engine.base.Engine.group_energies`: one ``getState`` per
        group, or with the plugin engine and no ``positions`` one C++ call).
        """
        pos = self.positions if positions is None else positions
        out = self._engine.group_energies(self, positions)
        out["gravity"] += self.model.gravity * pos.mean(axis=0)[2] * self.n_beads
        out["total"] = sum(out.values())
        return out

    def context_energies(self, shifted: np.ndarray) -> dict[str, float]:
        """Energy of each term of :data:`FORCE_GROUPS` at ``shifted``, in F0 d.

        One ``getState`` per force group, with the Context's positions set to ``shifted``
        (shape (n_beads, 3), in d; virtual sites placed from them); the Context then no
        longer holds the run's positions (the next step or report puts them back).
        """
        self._put_positions(shifted)
        self._context_current = False
        out = {}
        for name, group in FORCE_GROUPS.items():
            state = self.context.getState(getEnergy=True, groups={group})
            out[name] = state.getPotentialEnergy().value_in_unit(unit.kilojoule_per_mole)
        return out

    def bond_lengths(self, positions: np.ndarray | None = None) -> np.ndarray:
        """Length of every bond, shape (n_bonds,), in d (bond ``k`` joins the beads of
        ``layout.bonds()[k]``: beads ``k`` and ``k + 1`` of a ring)."""
        pos = self.positions if positions is None else positions
        return np.linalg.norm(pos[self.bonds[:, 1]] - pos[self.bonds[:, 0]], axis=1)

    # -- state checks (the engines' hooks) --------------------------------------------------
    def check_state(self, y: np.ndarray, initial: bool = False, dt: float = 0.0) -> None:
        """Raise :class:`SimulationFault` if ``y`` (the state ``dt`` after the current one) is bad.

        Bad: a non-finite position, or a bond longer than :attr:`max_bond_length`. The
        message names the time and step of the bad state and the last good one (kept).

        Parameters
        ----------
        y : ndarray, shape (n_beads, 3), in d
        initial : bool
            ``y`` is a starting state (positions given, or a checkpoint's).
        dt : float
            How far after :attr:`time` ``y`` is, in tau_d.
        """
        where = "the starting positions" if initial else (
            f"t = {self.time + dt:.6g} tau_d (step {self.currentStep + 1}; the last good state, "
            f"at t = {self.time:.6g} tau_d, is kept)"
        )
        if not np.all(np.isfinite(y)):
            bead = int(np.argwhere(~np.isfinite(y).all(axis=1))[0, 0])
            raise SimulationFault(
                f"positions became non-finite at {where}: first bad bead {bead}. Hint: "
                f"{self._step_hint()}"
            )
        lengths = self.bond_lengths(y)
        worst = int(np.argmax(lengths))
        if lengths[worst] > self.max_bond_length:
            raise SimulationFault(
                f"bond {worst} (beads {self.bonds[worst, 0]}-{self.bonds[worst, 1]}) is "
                f"{lengths[worst]:.4g} d long at {where}, past run.max_bond_length = "
                f"{self.max_bond_length:g}. Hint: the step is too large for the forces "
                f"({self._step_hint()}), or the template overlaps itself"
            )

    def _step_hint(self) -> str:
        """What would survive where this run's steps broke down (for the fault's one line)."""
        integ = self.integrator
        if getattr(integ, "adaptive", False):
            return "lower run.tolerance"
        if getattr(integ, "kT", 0.0) > 0.0:
            return (f'run.integrator = "ito_heun_adaptive" shortens its steps at close '
                    f"contacts and survives where {integ.name} at a fixed "
                    f"{integ.timestep:g} tau_d does not; or lower run.timestep")
        return "lower run.timestep, or use an adaptive run.integrator (rk23, rkc2)"

    def _put_positions(self, beads: np.ndarray) -> None:
        """Set the Context's positions to ``beads`` (shape (n_beads, 3), in d) and any
        bond-midpoint sites placed from them by the layout's bonds
        (:func:`knotmm.model.system.site_positions`, the System's rule): the one place the
        Simulation hands positions to the Context."""
        self.context.setPositions(site_positions(beads, self.model, self.layout))

    def sync_context(self) -> None:
        """Put the current positions, step count and time into the Context (for reporters)."""
        self._put_positions(self.positions)
        self.context.setTime(self.time)
        self.context.setStepCount(self.currentStep)
        self._context_current = True

    @property
    def context_current(self) -> bool:
        """True while the Context holds the current positions (as :meth:`sync_context`
        left them; a translate of them after an engine's steps)."""
        return self._context_current

    # -- stepping ---------------------------------------------------------------------------
    def underflow_fault(self, timestep: float, reason: str) -> SimulationFault:
        """The fault of an adaptive step that fell to ``timestep`` (tau_d) for ``reason``."""
        return SimulationFault(
            f"the adaptive step fell to {timestep:.3g} tau_d (below run.min_timestep) "
            f"at t = {self.time:.6g} tau_d (step {self.currentStep}): {reason}. "
            f"Hint: the forces are too stiff here (beads pressed together?); the last good "
            f"state is kept"
        )

    def set_positions(self, positions) -> None:
        """Replace the positions (forgetting the integrator's cached velocity)."""
        pos = np.array(positions, dtype=np.float64)
        if pos.shape != self.positions.shape:
            raise ConfigError(f"positions: expected shape {self.positions.shape}, got {pos.shape}")
        self.check_state(pos, initial=True)
        self.positions = pos
        self._engine.reset(self)

    def step(self, steps: int) -> None:
        """Take ``steps`` accepted integrator steps (OpenMM's meaning of ``step``)."""
        self._simulate(end_step=self.currentStep + int(steps))

    def run(self, duration: float, write_at_start: bool = True) -> None:
        """Advance the simulated time by ``duration`` tau_d, landing exactly on its end.

        ``write_at_start``: time-scheduled reporters first report the current state when
        they are due now (frame 0 of a new run).
        """
        if not duration > 0:
            raise ConfigError(f"duration={duration!r}: must be > 0 (in tau_d)")
        self._simulate(end_time=self.time + float(duration), write_at_start=write_at_start)

    def _simulate(self, end_step=None, end_time=None, write_at_start=False):
        # The loop is serial by design; BLAS threads (a Cholesky factor per Brownian step)
        # only fight each other and OpenMM on small matrices: 0.4 ms single-threaded against
        # 16-40 ms with oversubscribed threads, measured at N = 90 on 2 cores.
        from threadpoolctl import threadpool_limits

        try:
            with threadpool_limits(limits=1, user_api="blas"):
                self._simulate_loop(end_step, end_time, write_at_start)
        except BaseException:
            try:  # the Context follows the last whole step; the error that stopped us wins
                self.sync_context()
            except Exception:  # noqa: BLE001
                pass
            raise
        self.sync_context()

    def _simulate_loop(self, end_step, end_time, write_at_start):
        end_step = math.inf if end_step is None else end_step
        end_time = math.inf if end_time is None else end_time
        if write_at_start:
            due = [r for r in self.reporters
                   if hasattr(r, "next_report_time")
                   and r.next_report_time(self) <= self.time + landing_slack(self.time)]
            self._report(due)
        while self.currentStep < end_step and self.time < end_time - landing_slack(end_time):
            step_target = end_step
            time_target = end_time
            due_step = {}
            for r in self.reporters:
                if hasattr(r, "next_report_time"):
                    t_next = r.next_report_time(self)
                    if t_next > self.time + landing_slack(self.time):
                        time_target = min(time_target, t_next)
                else:
                    desc = r.describeNextReport(self)
                    steps = desc["steps"] if isinstance(desc, dict) else desc[0]
                    if steps > 0:
                        due_step[id(r)] = self.currentStep + steps
                        step_target = min(step_target, self.currentStep + steps)
            while self.currentStep < step_target:
                remaining = time_target - self.time
                if remaining <= landing_slack(time_target):
                    break
                # Here every report due at the current time has been made: a stop asked
                # for by a signal (knotmm.engine.interrupt) leaves a whole state to checkpoint.
                raise_if_requested()
                if step_target == math.inf:
                    self._engine.advance_to(self, time_target)  # every step to the report
                else:
                    self._engine.advance_one(self, time_target)
                if abs(time_target - self.time) <= landing_slack(time_target):
                    self.time = time_target
                    break
            due = []
            for r in self.reporters:
                if hasattr(r, "next_report_time"):
                    if r.next_report_time(self) <= self.time + landing_slack(self.time):
                        due.append(r)
                elif due_step.get(id(r)) == self.currentStep:
                    due.append(r)
            self._report(due)

    def _report(self, reporters) -> None:
        if not reporters:
            return
        self.sync_context()
        openmm_style = [r for r in reporters if not hasattr(r, "next_report_time")]
        state = None
        if openmm_style:
            includes = set()
            for r in openmm_style:
                desc = r.describeNextReport(self)
                if isinstance(desc, dict):
                    includes.update(desc.get("include", []))
                else:
                    names = ["positions", "velocities", "forces", "energy"]
                    includes.update(n for n, flag in zip(names, desc[1:5], strict=False) if flag)
            if "velocities" in includes:
                self.context.setVelocities(self.velocity(self.positions))
            state = self.context.getState(
                getPositions="positions" in includes,
                getVelocities="velocities" in includes,
                getForces="forces" in includes,
                getEnergy="energy" in includes,
            )
        for r in reporters:
            r.report(self, state)
