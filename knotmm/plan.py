"""The run plan: a validated run configuration resolved once into every decision of a run.

:func:`prepare` turns a :class:`knotmm.config.RunConfig` into a frozen :class:`RunPlan` and
the objects it decided on: the checked template and the :class:`~knotmm.engine.simulation.
Simulation` on its layout. Each decision is made here once, in this order (an error stops
at the first, as ``knotmm run`` reports it; nothing is written):

1. the typed parts read from the run file: the stepping (:class:`Stepping`: ``run.integrator
   = "auto"`` and the step resolved, the tolerance, the step bounds, kT, the seed), the
   template spec (:class:`TemplateSpec`: its keys, the perturbation's seeds, the longest
   bond), the memory budget (:class:`knotmm.shapes.resources.RunResources`), the topology
   checks (:class:`~knotmm.engine.knot_checks.TopologyChecks`), the output
   (:class:`Output`), the duration, the model and where to compute as asked
   (:class:`Compute`);
2. the integrator, built once from the stepping, which checks it against ``run.peclet``
   before the template is built; ``run.on_topology_change = "stop"`` against topoly; the
   engine (:meth:`Compute.engine_for`), which the memory budget takes;
3. the template, built by :func:`knotmm.shapes.builder.build_template` from the spec and
   the budget (the geometry code gets them as values, never ``run.*`` keys); the noise
   method for the chain's size;
4. the Simulation (:meth:`PlanParts.simulation`: the platform resolved), the precision asked
   of OpenMM (:class:`Placement`);
5. ``run.integrator = "auto"`` at ``Pe = inf``: ONE stiffness probe on that Simulation, which
   is kept whichever integrator the choice takes (:meth:`Simulation.use_integrator`: the
   Python engine takes the Python integrator, the plugin switches its ``RPYIntegrator`` with
   ``setMethod``; one Context either way); an engine that cannot switch is built again;
6. the record: the configuration with every resolved key (one :meth:`RunConfig.replace`,
   which validates only those keys) as ``run.toml`` and the checkpoints write it
   (:attr:`RunPlan.record`), the reasons ``run.toml`` records (``integrator_choice``) and
   the memory need where it lives (:attr:`RunPlan.memory`).

A stopped run is planned again from its ``run.toml`` by :func:`resume_plan` (every choice
recorded there; the checkpoint's positions, chains and engine; no template, no probe).

:func:`knotmm.workflow.run` (and through it replicas and sweep points) and ``sweep
--dry-run`` (:func:`knotmm.workflow.build_run`) start from it, ``--resume``
(:func:`knotmm.workflow.resume`) from :func:`resume_plan`; below it nothing reads the run
file again: the run is driven by the plan's parts (``tests/workflow/test_config_walk.py``
measures it).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from types import MappingProxyType
from typing import Any

from knotmm.config import RunConfig, resolve_stepping, resolve_tolerance
from knotmm.dynamics import registry
from knotmm.dynamics.registry import (
    AUTO,
    AUTO_STIFFNESS,
    DEVICE_PLATFORMS,
    REGISTRY,
    auto_deterministic,
)
from knotmm.engine.engines import resolve_engine, select_platform
from knotmm.engine.knot_checks import TopologyChecks, check_stop_on_change
from knotmm.engine.simulation import Simulation
from knotmm.model.parameters import ChainModel
from knotmm.shapes.resources import MemoryNeed, RunResources
from knotmm.shapes.spec import TemplateSpec
from knotmm.units import thermal_energy

__all__ = [
    "Compute",
    "Output",
    "PlanParts",
    "Placement",
    "PreparedRun",
    "RunPlan",
    "Stepping",
    "TemplateSpec",
    "make_plan",
    "prepare",
    "resume_plan",
]

log = logging.getLogger(__name__)

@dataclass(frozen=True)
class Stepping:
    """How a run steps: every ``[run]`` key of the integrator, resolved.

    Attributes
    ----------
    integrator : str
        The registry name used (never ``"auto"``).
    timestep : float
        The fixed step, or an adaptive integrator's first step, in tau_d.
    tolerance : float
        The local error per step of an adaptive integrator, in d (resolved default).
    max_timestep, min_timestep : float
        An adaptive integrator's step bounds, in tau_d.
    peclet : float
        ``Pe = d F0 / kT`` (``inf``: deterministic).
    kT : float
        ``1 / Pe``, in F0 d (0 at ``Pe = inf``).
    seed : int
        ``run.seed``: the noise stream's seed.
    noise : str
        ``run.noise`` as asked (``"auto"``, ``"cholesky"``, ``"lanczos"``).
    noise_method : str or None
        The noise drawn for this chain's size; None without noise.
    lanczos_tolerance : float
    """

    integrator: str
    timestep: float
    tolerance: float
    max_timestep: float
    min_timestep: float
    peclet: float
    kT: float  # noqa: N815 - the physicist's name
    seed: int
    noise: str
    noise_method: str | None
    lanczos_tolerance: float

    @classmethod
    def of(cls, cfg: RunConfig) -> Stepping:
        """The stepping of ``cfg`` (``run.integrator = "auto"`` resolved by the Peclet number
        alone, :func:`knotmm.config.resolve_stepping`; the stiffness choice comes later)."""
        name, timestep = resolve_stepping(cfg)
        return cls(
            integrator=name,
            timestep=timestep,
            tolerance=resolve_tolerance(cfg, name),
            max_timestep=float(cfg["run.max_timestep"]),
            min_timestep=float(cfg["run.min_timestep"]),
            peclet=float(cfg["run.peclet"]),
            kT=thermal_energy(cfg["run.peclet"]),
            seed=int(cfg["run.seed"]),
            noise=str(cfg["run.noise"]),
            noise_method=None,
            lanczos_tolerance=float(cfg["run.lanczos_tolerance"]),
        )

    @property
    def record(self) -> dict[str, Any]:
        """The resolved ``run.*`` keys as ``run.toml`` records them."""
        return {"run.integrator": self.integrator, "run.timestep": self.timestep,
                "run.tolerance": self.tolerance}

    def make_integrator(self):
        """A fresh integrator of this stepping
        (:func:`knotmm.dynamics.registry.make`, with the arguments
        :func:`~knotmm.dynamics.registry.integrator_from_config` gives it)."""
        return registry.make(
            self.integrator, self.timestep, peclet=self.peclet, seed=self.seed,
            noise=self.noise, lanczos_tolerance=self.lanczos_tolerance,
            tolerance=self.tolerance, max_timestep=self.max_timestep,
            min_timestep=self.min_timestep,
        )


@dataclass(frozen=True)
class Placement:
    """Where a run computes: engine, OpenMM platform and its precision, threads.

    Attributes
    ----------
    engine : {"python", "plugin"}
        ``run.engine`` resolved (:func:`knotmm.engine.engines.resolve_engine`).
    platform : str
        The OpenMM platform the Context runs on (``run.platform = "auto"`` resolved).
    precision : str
        The platform's force precision, asked of OpenMM: its ``Precision`` property where
        it has one (CUDA, OpenCL, HIP), else ``"double"`` or ``"single"`` by
        ``Platform.supportsDoublePrecision`` (Reference: double; CPU: single).
    threads, mobility_threads : int
        ``run.threads`` (the CPU platform's) and ``run.mobility_threads`` (the RPY loop's).
    """

    engine: str
    platform: str
    precision: str
    threads: int
    mobility_threads: int

    @classmethod
    def of(cls, sim: Simulation, asked: Compute) -> Placement:
        """The placement of a built Simulation (asked of its Context)."""
        platform = sim.context.getPlatform()
        if "Precision" in platform.getPropertyNames():
            precision = platform.getPropertyValue(sim.context, "Precision")
        else:
            precision = "double" if platform.supportsDoublePrecision() else "single"
        return cls(engine=sim.engine, platform=sim.platform_name, precision=str(precision),
                   threads=asked.threads, mobility_threads=asked.mobility_threads)

    @property
    def on_device(self) -> bool:
        """Whether the Context runs on a device platform (CUDA, HIP, OpenCL)."""
        return self.platform in DEVICE_PLATFORMS


@dataclass(frozen=True)
class Compute:
    """Where the run file asks a run to compute, as asked (:class:`Placement`: what it got).

    Attributes
    ----------
    engine : {"auto", "python", "plugin"}
        ``run.engine``.
    platform : str
        ``run.platform`` (``"auto"`` or an OpenMM platform's name).
    precision : {"auto", "mixed", "double"}
        ``run.precision``.
    threads, mobility_threads : int
        ``run.threads``, ``run.mobility_threads``.
    """

    engine: str
    platform: str
    precision: str
    threads: int
    mobility_threads: int

    @classmethod
    def of(cls, cfg: RunConfig) -> Compute:
        """What ``cfg`` asks."""
        return cls(engine=str(cfg["run.engine"]), platform=str(cfg["run.platform"]),
                   precision=str(cfg["run.precision"]), threads=int(cfg["run.threads"]),
                   mobility_threads=int(cfg["run.mobility_threads"]))

    def engine_for(self, integrator: str, peclet: float) -> str:
        """The engine a run with ``integrator`` takes
        (:func:`knotmm.engine.engines.resolve_engine`, a named platform first checked by
        :func:`~knotmm.engine.engines.select_platform`; warns once where the asked one
        cannot be used). It does not depend on the chain's size."""
        platform = self.platform
        if platform != "auto":  # a named platform: the size (0 here) does not matter
            platform = select_platform(platform, 0, self.threads)[0].getName()
        return resolve_engine(self.engine, integrator, peclet, platform)


@dataclass(frozen=True)
class Output:
    """What a run writes, and when (in tau_d).

    Attributes
    ----------
    directory : str
        ``output.directory``.
    frame_interval : float
        Between frames of ``trajectory.dcd``.
    observables_interval : float
        Between rows of ``observables.csv`` (``output.observables_interval``, default the
        frame interval).
    checkpoint_interval : float
        Between checkpoints: ``output.checkpoint_interval`` rounded up to a whole number of
        frame intervals (a checkpoint is written at a frame).
    """

    directory: str
    frame_interval: float
    observables_interval: float
    checkpoint_interval: float

    @classmethod
    def of(cls, cfg: RunConfig) -> Output:
        """The output of ``cfg`` (a resumed run's too)."""
        frame = cfg["output.frame_interval"]
        return cls(
            directory=str(cfg["output.directory"]),
            frame_interval=frame,
            observables_interval=cfg["output.observables_interval"] or frame,
            checkpoint_interval=frame * max(1, math.ceil(cfg["output.checkpoint_interval"]
                                                         / frame - 1e-9)),
        )


@dataclass(frozen=True)
class PlanParts:
    """The parts of a plan read from the run file alone (:func:`prepare`'s first step):
    nothing built, nothing checked against a template or a platform. What a saved run's
    orbit takes of its run (:func:`knotmm.orbit.start.start_from_run`).

    Attributes
    ----------
    stepping : Stepping
        ``auto`` resolved by the Peclet number alone (the stiffness choice needs the
        Simulation).
    template : knotmm.shapes.spec.TemplateSpec
    resources : knotmm.shapes.resources.RunResources
    checks : knotmm.engine.knot_checks.TopologyChecks
    output : Output
    duration : float
        ``run.duration``, in tau_d.
    model : ChainModel
    compute : Compute
        Engine, platform, precision and threads as asked.
    """

    stepping: Stepping
    template: TemplateSpec
    resources: RunResources
    checks: TopologyChecks
    output: Output
    duration: float
    model: ChainModel
    compute: Compute

    @classmethod
    def of(cls, cfg: RunConfig) -> PlanParts:
        """The parts of ``cfg``."""
        return cls(stepping=Stepping.of(cfg), template=TemplateSpec.of(cfg),
                   resources=RunResources.of(cfg), checks=TopologyChecks.of(cfg),
                   output=Output.of(cfg), duration=float(cfg["run.duration"]),
                   model=ChainModel.from_config(cfg), compute=Compute.of(cfg))

    def simulation(self, positions, layout, integrator, engine: str | None = None
                   ) -> Simulation:
        """The Simulation of these parts at ``positions`` (shape (n_beads, 3), in d) with
        the chains of ``layout`` and a fresh ``integrator``; ``engine`` (default: the one
        :meth:`Compute.engine_for` takes) as given (a resumed run's is its checkpoint's)."""
        if engine is None:
            engine = self.compute.engine_for(integrator.name, self.stepping.peclet)
        asked = self.compute
        return Simulation(positions, self.model, integrator, platform=asked.platform,
                          threads=asked.threads, max_bond_length=self.template.max_bond_length,
                          mobility_threads=asked.mobility_threads, engine=engine,
                          layout=layout, precision=asked.precision)


@dataclass(frozen=True)
class RunPlan:
    """Every decision made before a run, made once (:func:`prepare`).

    Attributes
    ----------
    config : RunConfig
        The run file as ``run.toml`` records it: every resolved key written back (the
        integrator and step used, not ``"auto"``; the template's keys).
    record : dict
        ``config`` as nested tables (:meth:`RunConfig.to_dict`), made once: what ``run.toml``
        and every checkpoint write.
    template : knotmm.shapes.spec.TemplateSpec
        The start asked for (the seeds and the bond limit the template was built with).
    model : ChainModel
    stepping : Stepping
    placement : Placement
    resources : knotmm.shapes.resources.RunResources
        What the run's memory depends on, its engine resolved (checked against the memory
        available for the chain built).
    memory : knotmm.shapes.resources.MemoryNeed
        The largest allocations of this run where they live: the host's (the dense
        Brownian noise) and the device's (a device platform's state vectors).
    output : Output
    duration : float
        ``run.duration``, in tau_d.
    checks : knotmm.engine.knot_checks.TopologyChecks
        The knot-type and linking-number checks during the run.
    n_beads : int
    reasons : Mapping of str to str
        Why a choice was made, as ``run.toml``'s ``[knotmm]`` records it
        (``integrator_choice`` when ``run.integrator = "auto"``; ``noise_precision`` for
        Cholesky noise on the plugin engine: :func:`knotmm.plugin.noise_factor_precision`).
    """

    config: RunConfig
    record: dict[str, Any]
    template: TemplateSpec
    model: ChainModel
    stepping: Stepping
    placement: Placement
    resources: RunResources
    memory: MemoryNeed
    output: Output
    duration: float
    checks: TopologyChecks
    n_beads: int
    reasons: Mapping[str, str] = field(default_factory=dict)


@dataclass
class PreparedRun:
    """A plan and what it built: the checked template and its Simulation (not yet run)."""

    plan: RunPlan
    template: Any
    simulation: Simulation


def prepare(cfg: RunConfig, identify: str = "now") -> PreparedRun:
    """Resolve ``cfg`` into a :class:`RunPlan` and build what it decided (module docstring).

    Parameters
    ----------
    cfg : RunConfig
        A validated run configuration.
    identify : {"now", "later", "skip"}
        When the template's knot type is identified
        (:func:`knotmm.shapes.builder.build_template`).

    Returns
    -------
    PreparedRun

    Raises
    ------
    ConfigError, TemplateError, TrajectoryFileError
        What ``knotmm run`` refuses before it writes anything.
    """
    from knotmm.shapes.builder import build_template

    # 1. every part read from the run file, once
    parts = PlanParts.of(cfg)
    stepping, spec = parts.stepping, parts.template
    reason = _peclet_reason(cfg, stepping.integrator)
    by_stiffness = cfg["run.integrator"] == AUTO and not math.isfinite(stepping.peclet)
    # 2. built once: checks the integrator against run.peclet before the template; the
    # engine, which decides where the memory goes
    registry.warn_brownian_step(stepping.integrator, stepping.timestep, stepping.peclet)
    integrator = stepping.make_integrator()
    check_stop_on_change(parts.checks)
    engine = parts.compute.engine_for(integrator.name, stepping.peclet)
    resources = replace(parts.resources, engine=engine)
    # 3. the template, from typed values
    template = build_template(cfg, identify=identify, spec=spec, resources=resources)
    n_beads = int(template.positions.shape[0])
    stepping = replace(stepping, noise_method=resources.noise_method(n_beads))
    record = cfg.replace({**stepping.record, **template.resolved})
    # 4. the Simulation
    sim = parts.simulation(template.positions, template.layout, integrator, engine)
    # 5. the stiffness choice, probed once on that Simulation
    if by_stiffness:
        choice, reason = _stiffness_choice(sim)
        if choice != stepping.integrator:
            stepping = replace(stepping, integrator=choice)
            record = record.replace({"run.integrator": choice})
            integrator = stepping.make_integrator()
            if not sim.use_integrator(integrator):  # an engine that cannot switch in place
                # the engine already chosen (and warned about) when the new integrator has it
                engine = sim.engine if sim.engine in REGISTRY[choice].engines else None
                sim = parts.simulation(template.positions, template.layout, integrator,
                                       engine)
    # 6. the record
    plan = _plan(record, parts, stepping, resources, sim,
                 {"integrator_choice": reason} if reason else {})
    return PreparedRun(plan, template, sim)


def resume_plan(cfg: RunConfig, positions, layout, engine: str) -> PreparedRun:
    """The plan of a stopped run and its Simulation, from its ``run.toml`` and checkpoint.

    Every choice was made when the run started and ``run.toml`` records it (the integrator
    and step used, the template's keys): the parts are read again, no template is built and
    no stiffness probed. The Simulation is built at the checkpoint's ``positions`` (shape
    (n_beads, 3), in d) with the chains of ``layout`` and the ``engine`` that wrote the
    checkpoint (a run goes on exactly only with it), after its dense noise is checked against
    the memory available as a new run's is; the caller loads the checkpoint into it.

    Parameters
    ----------
    cfg : RunConfig
        The run's ``run.toml`` (``run.duration`` possibly extended).
    positions : ndarray, shape (n_beads, 3), in d
    layout : knotmm.model.layout.ChainLayout
    engine : {"python", "plugin"}

    Returns
    -------
    PreparedRun
        Its ``template`` is None.
    """
    parts = PlanParts.of(cfg)
    n_beads = int(len(positions))
    resources = replace(parts.resources, engine=engine)
    stepping = replace(parts.stepping, noise_method=resources.noise_method(n_beads))
    registry.warn_brownian_step(stepping.integrator, stepping.timestep, stepping.peclet)
    resources.check(n_beads)
    sim = parts.simulation(positions, layout, stepping.make_integrator(), engine)
    return PreparedRun(_plan(cfg, parts, stepping, resources, sim, {}), None, sim)


def _plan(record: RunConfig, parts: PlanParts, stepping: Stepping, resources: RunResources,
          sim: Simulation, reasons: dict[str, str]) -> RunPlan:
    """The frozen plan of a built Simulation (:func:`prepare`'s last step)."""
    placement = Placement.of(sim, parts.compute)
    if sim.engine == "plugin" and stepping.noise_method == "cholesky":
        from knotmm.plugin import noise_factor_precision

        factor = noise_factor_precision(placement.precision)
        reasons = {**reasons, "noise_precision": (
            f"{factor}: the mobility's Cholesky factor in {factor} precision, as the "
            f"{placement.platform} platform's forces ({placement.precision})")}
    return RunPlan(
        config=record,
        record=record.to_dict(),
        template=parts.template,
        model=sim.model,
        stepping=stepping,
        placement=placement,
        resources=resources,
        memory=resources.need(sim.n_beads, device=placement.on_device),
        output=parts.output,
        duration=parts.duration,
        checks=parts.checks,
        n_beads=sim.n_beads,
        reasons=MappingProxyType(reasons),
    )


def make_plan(cfg: RunConfig) -> RunPlan:
    """The :class:`RunPlan` of ``cfg`` alone (:func:`prepare`, the template's knot type not
    identified); what it built is dropped."""
    return prepare(cfg, identify="skip").plan


def _peclet_reason(cfg: RunConfig, name: str) -> str | None:
    """Why ``run.integrator = "auto"`` took ``name`` at a finite Peclet number (None: named,
    or decided by the stiffness at ``Pe = inf``)."""
    if cfg["run.integrator"] != AUTO or not math.isfinite(cfg["run.peclet"]):
        return None
    return (f"auto at run.peclet = {cfg['run.peclet']:g}: {name}, adaptive Brownian "
            f"steps (fixed steps break down at close steric contacts at Pe <~ 1)")


def _stiffness_choice(sim: Simulation) -> tuple[str, str]:
    """``run.integrator = "auto"`` at ``Pe = inf``: the integrator by the chain's stiffness
    at the start (one probe, :meth:`Simulation.stiffness`), and why."""
    stiffness = sim.stiffness()
    choice = auto_deterministic(stiffness)
    log.info("run.integrator auto: stiffness %.4g / tau_d -> %s", stiffness, choice)
    return choice, (f"auto at run.peclet = inf: {choice}, the chain's stiffness (RKC's "
                    f"spectral radius at the start) is {stiffness:.4g} / tau_d "
                    f"({'above' if choice == 'rkc2' else 'at most'} {AUTO_STIFFNESS:g})")
