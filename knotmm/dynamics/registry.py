"""The one registry of time steppers: names, properties, the ``"auto"`` policy, construction.

Every integrator a run file may name (``run.integrator``) is one :class:`IntegratorInfo` in
:data:`REGISTRY`: where its class lives, its order, whether it is adaptive and whether it
integrates the stochastic (finite Peclet) equation, a one-line description, its default
step, and the engines that have it (``run.engine``: :data:`PYTHON_ENGINE`, the class here;
:data:`PLUGIN_ENGINE`, its C++ counterpart in the compiled plugin, whose own table
``knotmm.plugin.METHODS`` a test holds to this one). :mod:`knotmm.config` validates
``run.integrator`` against :data:`NAMES`; :func:`resolve` turns ``"auto"`` and an unset step
into what a run uses; :func:`make` and :func:`integrator_from_config` build any of them.

It is also the one owner of the integrators' defaults (``DEFAULT_*``: steps, tolerances, step
bounds, Lanczos tolerance), which the run-file schema, the classes' signatures and the
plugin read, and of the OpenMM platforms (:data:`PLATFORMS`, :data:`HOST_PLATFORMS`,
:data:`DEVICE_PLATFORMS`). The help of ``run.integrator``, ``run.timestep`` and
``run.tolerance`` is written from the table (:func:`integrator_help`, :func:`timestep_help`,
:func:`tolerance_help`); ``tests/dynamics/test_one_owner.py`` holds the prose copies (the
README, ``plugin/README.md``, the plugin's docstring and C++ header) to it.

The classes are imported only when one is built (:meth:`IntegratorInfo.load`), so importing
this module (and :mod:`knotmm.config`) costs no numba or scipy start-up.

Adding an integrator: write its class in one module of :mod:`knotmm.dynamics` (a subclass
of :class:`knotmm.dynamics.deterministic.Integrator`, with ``name`` and ``order``), and add
one entry here (``docs/architecture.md``); list :data:`PLUGIN_ENGINE` in its ``engines`` once
the plugin has it too.

Examples
--------
>>> resolve("auto", float("inf"), None)
('rk23', 0.01)
>>> resolve("auto", 2.0, None)
('ito_heun_adaptive', 0.002)
>>> REGISTRY["rkc2"].adaptive
True
"""

from __future__ import annotations

import importlib
import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass

from knotmm.errors import ConfigError
from knotmm.units import thermal_energy

__all__ = [
    "AUTO",
    "AUTO_BROWNIAN",
    "BOTH_ENGINES",
    "BROWNIAN_NAMES",
    "DEFAULT_BROWNIAN_TIMESTEP",
    "DEFAULT_BROWNIAN_TOLERANCE",
    "DEFAULT_LANCZOS_TOLERANCE",
    "DEFAULT_LM_TIMESTEP",
    "DEFAULT_MAX_TIMESTEP",
    "DEFAULT_MIN_TIMESTEP",
    "DEFAULT_TIMESTEP",
    "DEFAULT_TOLERANCE",
    "DEVICE_PLATFORMS",
    "NAMES",
    "PLATFORMS",
    "PLUGIN_ENGINE",
    "HOST_PLATFORMS",
    "PRECISIONS",
    "PYTHON_ENGINE",
    "REGISTRY",
    "IntegratorInfo",
    "integrator_from_config",
    "integrator_help",
    "make",
    "resolve",
    "resolve_tolerance",
    "timestep_help",
    "tolerance_help",
    "warn_brownian_step",
]

log = logging.getLogger(__name__)

#: The ``run.integrator`` value that lets :func:`resolve` choose.
AUTO = "auto"
# The integrators' defaults: the one owner. The schema of ``knotmm.config``, the classes'
# signatures (:mod:`knotmm.dynamics`) and :class:`knotmm.plugin.RPYIntegrator` read them, and
# ``tests/dynamics/test_one_owner.py`` holds the compiled plugin's own defaults to them.
#: Step of deterministic runs when none is given (the first step of an adaptive integrator).
DEFAULT_TIMESTEP = 0.01
#: Step of Brownian integrators at finite Pe when none is given (see
#: :mod:`knotmm.dynamics.brownian`, "Step size").
DEFAULT_BROWNIAN_TIMESTEP = 0.002
#: Step of ``leimkuhler_matthews`` at finite Pe when none is given: Boltzmann bond
#: fluctuations at this step (:class:`knotmm.dynamics.brownian.LeimkuhlerMatthews`).
DEFAULT_LM_TIMESTEP = 0.01
#: ``run.tolerance`` of the deterministic adaptive integrators when none is given, in d.
DEFAULT_TOLERANCE = 1e-4
#: ``run.tolerance`` of ``ito_heun_adaptive`` at Pe = 10 when none is given, in d: no bias
#: against a Metropolis Monte Carlo there (0.05 shortened the bond-length spread by 0.9-1.4 %;
#: ``benchmarks/validate_brownian_equilibrium.py``); :func:`resolve_tolerance` scales it with
#: Pe on either side.
DEFAULT_BROWNIAN_TOLERANCE = 0.02
#: Largest step of the adaptive integrators (``run.max_timestep``), in tau_d.
DEFAULT_MAX_TIMESTEP = 1.0
#: Smallest step of the adaptive integrators (``run.min_timestep``): below it a run stops.
DEFAULT_MIN_TIMESTEP = 1e-7
#: Lanczos noise: relative change between successive iterates at which to stop
#: (``run.lanczos_tolerance``; :class:`knotmm.dynamics.noise.NoiseGenerator`).
DEFAULT_LANCZOS_TOLERANCE = 1e-6
#: What ``"auto"`` is at ``Pe = inf``, and instead for a stiff chain (:func:`auto_deterministic`).
AUTO_DETERMINISTIC = "rk23"
AUTO_STIFF = "rkc2"
#: What ``"auto"`` is at a finite Peclet number: adaptive steps survive the close steric
#: contacts that break fixed steps at Pe <~ 1 (``benchmarks/README.md``, issue 20).
AUTO_BROWNIAN = "ito_heun_adaptive"
#: Above this fixed step (tau_d) a Brownian run warns: stiff bond modes go unstable.
_BROWNIAN_STEP_WARNING = 0.01
#: The engines (``run.engine`` values other than ``"auto"``): the integrator classes of
#: :mod:`knotmm.dynamics` stepped from Python, and the compiled plugin.
PYTHON_ENGINE = "python"
PLUGIN_ENGINE = "plugin"
BOTH_ENGINES = (PYTHON_ENGINE, PLUGIN_ENGINE)
#: The host platforms: double-precision Reference and the CPU platform (single-precision
#: forces). Which platforms the compiled plugin runs on is asked of OpenMM
#: (:func:`knotmm.engine.engines.plugin_platforms`), not listed.
HOST_PLATFORMS = ("Reference", "CPU")
#: The device platforms, best first: ``run.platform = "auto"`` may take one
#: (:func:`knotmm.engine.engines.auto_platform`).
DEVICE_PLATFORMS = ("CUDA", "HIP", "OpenCL")
#: Every OpenMM platform a run may name (``run.platform``, besides ``"auto"``).
PLATFORMS = (*HOST_PLATFORMS, *DEVICE_PLATFORMS)
#: ``run.precision`` on a device platform (OpenMM's ``Precision`` property): ``auto`` is
#: mixed (single-precision forces, double-precision sums and positions); ``double``
#: throughout. Single precision is not offered: a chain far below the origin would sit at
#: float32 resolution (1e-4 d at 1400 d), the integrators' tolerance.
PRECISIONS = ("auto", "mixed", "double")


@dataclass(frozen=True)
class IntegratorInfo:
    """One registered integrator.

    Attributes
    ----------
    name : str
        The ``run.integrator`` value (equal to the class's ``name``).
    module, class_name : str
        Where the class lives (imported by :meth:`load`).
    order : int
        Order of accuracy (Brownian: weak order for the RPY mobility; in the deterministic
        limit ``Pe = inf`` ``euler_maruyama`` is Euler, order 1, and ``ito_heun`` Heun,
        order 2). Equal to the class's ``order``.
    adaptive : bool
        Chooses its own step from an error tolerance (``run.tolerance``).
    brownian : bool
        Integrates the stochastic equation at finite ``run.peclet`` (fixed step).
    description : str
        One line, for help texts.
    default_timestep : float
        ``run.timestep`` when none is given, in tau_d.
    default_tolerance : float
        ``run.tolerance`` when none is given (adaptive integrators), in d.
    engines : tuple of str
        The engines that have it: :data:`PYTHON_ENGINE` (every entry: the class above) and
        :data:`PLUGIN_ENGINE` when the compiled plugin has a C++ counterpart (same name,
        order, adaptive and stochastic flags in its ``methodTable()``).
    """

    name: str
    module: str
    class_name: str
    order: int
    adaptive: bool
    brownian: bool
    description: str
    default_timestep: float
    engines: tuple[str, ...] = (PYTHON_ENGINE,)
    default_tolerance: float = DEFAULT_TOLERANCE

    def load(self) -> type:
        """The integrator class (imports its module)."""
        return getattr(importlib.import_module(self.module), self.class_name)


_DET = "knotmm.dynamics.deterministic"
_BROWN = "knotmm.dynamics.brownian"

#: Every integrator, by ``run.integrator`` name, in the order help texts list them.
REGISTRY: dict[str, IntegratorInfo] = {
    info.name: info
    for info in (
        IntegratorInfo(
            "rk23", _DET, "RK23", 3, True, False,
            "Bogacki-Shampine 3(2), adaptive; the default at Pe = inf", DEFAULT_TIMESTEP,
            engines=BOTH_ENGINES,
        ),
        IntegratorInfo(
            "rkc2", _DET, "RKC2", 2, True, False,
            "Runge-Kutta-Chebyshev, adaptive step and stages, for very stiff chains",
            DEFAULT_TIMESTEP, engines=BOTH_ENGINES,
        ),
        IntegratorInfo(
            "heun", _DET, "Heun", 2, False, False, "explicit trapezoid, fixed step",
            DEFAULT_TIMESTEP, engines=BOTH_ENGINES,
        ),
        IntegratorInfo(
            "midpoint", _DET, "Midpoint", 2, False, False, "explicit midpoint, fixed step",
            DEFAULT_TIMESTEP, engines=BOTH_ENGINES,
        ),
        IntegratorInfo(
            "euler", _DET, "Euler", 1, False, False, "forward Euler, fixed step",
            DEFAULT_TIMESTEP, engines=BOTH_ENGINES,
        ),
        IntegratorInfo(
            "ito_heun", _BROWN, "ItoHeun", 1, False, True,
            "Heun drift with Ito noise, fixed step",
            DEFAULT_BROWNIAN_TIMESTEP, engines=BOTH_ENGINES,
        ),
        IntegratorInfo(
            "leimkuhler_matthews", _BROWN, "LeimkuhlerMatthews", 1, False, True,
            "Leimkuhler-Matthews, fixed step, one velocity a step; Boltzmann bond "
            "fluctuations at 0.01 tau_d; breaks down at close contacts at Pe <~ 1",
            DEFAULT_LM_TIMESTEP, engines=BOTH_ENGINES,
        ),
        IntegratorInfo(
            "euler_maruyama", _BROWN, "EulerMaruyama", 1, False, True,
            "Euler-Maruyama, fixed step (needs h <= 0.001 at Pe ~ 2)",
            DEFAULT_BROWNIAN_TIMESTEP, engines=BOTH_ENGINES,
        ),
        IntegratorInfo(
            "ito_heun_adaptive", "knotmm.dynamics.adaptive_brownian", "AdaptiveItoHeun", 1,
            True, True,
            "Euler-Heun pair, adaptive step (PI control, rejected noise kept by Brownian "
            "bridges); survives close steric contacts at Pe <= 1; the default at finite Pe",
            DEFAULT_BROWNIAN_TIMESTEP, engines=BOTH_ENGINES,
            default_tolerance=DEFAULT_BROWNIAN_TOLERANCE,
        ),
    )
}

#: Registered names, in :data:`REGISTRY`'s order.
NAMES: tuple[str, ...] = tuple(REGISTRY)
#: Names of the integrators of the stochastic equation.
BROWNIAN_NAMES: tuple[str, ...] = tuple(n for n, info in REGISTRY.items() if info.brownian)


def _info(name: str) -> IntegratorInfo:
    try:
        return REGISTRY[name]
    except (KeyError, TypeError):
        raise ConfigError(
            f"run.integrator = {name!r}: expected {AUTO} or one of {', '.join(NAMES)}"
        ) from None


#: ``"auto"`` at ``Pe = inf``: above this stiffness (1/tau_d, RKC's estimate of the spectral
#: radius of the velocity Jacobian at the start) ``rkc2`` replaces ``rk23``. rk23 is held by
#: stability to steps of about 2.5 / stiffness, rkc2 only by accuracy. Force evaluations for
#: 40 tau_d of T(2,3), N = 90 (rk23 / rkc2), by bending stiffness A (stiffness): A = 5 (42):
#: 2011 / 2053; A = 10 (82): 4051 / 2902; A = 20 (163): 8323 / 4185; A = 100 (814): 43546 /
#: 9822. Below the threshold rk23 costs at most ~1.5x rkc2 and keeps its third order.
AUTO_STIFFNESS = 100.0


def auto_deterministic(stiffness: float) -> str:
    """The deterministic integrator ``"auto"`` picks for a chain of this stiffness (1/tau_d)."""
    return AUTO_STIFF if float(stiffness) > AUTO_STIFFNESS else AUTO_DETERMINISTIC


def resolve(integrator: str, peclet: float, timestep: float | None) -> tuple[str, float]:
    """The integrator and step a run uses: ``"auto"`` and an unset step resolved.

    ``"auto"`` is ``rk23`` at ``Pe = inf`` (the run then measures the chain's stiffness and
    may take ``rkc2`` instead: :func:`auto_deterministic`) and ``ito_heun_adaptive`` at a
    finite Peclet number: its steps shrink at close steric contacts, where every fixed step
    of 0.01 tau_d breaks down at Pe <~ 1 (``leimkuhler_matthews`` at 0.01 failed 3 runs of 3
    at Pe = 1, N = 90), and at its default tolerance (:func:`resolve_tolerance`) the bond
    length, bending and 1-3 distance statistics agree with a Metropolis Monte Carlo within
    0.5 % at Pe = 0.5-10 (``benchmarks/README.md``). An
    unset step is the integrator's ``default_timestep`` at finite Pe
    (:data:`DEFAULT_BROWNIAN_TIMESTEP` for the Brownian ones) and :data:`DEFAULT_TIMESTEP`
    at ``Pe = inf`` (where a Brownian integrator has no noise and is its deterministic
    limit). So setting ``run.peclet`` alone gives a sound Brownian run.

    Parameters
    ----------
    integrator : str
        ``"auto"`` or a name in :data:`NAMES`.
    peclet : float
        ``Pe = d F0 / kT`` (``inf``: deterministic).
    timestep : float or None
        The step asked for, in tau_d; ``None``: the default.

    Returns
    -------
    (str, float)
        Integrator name and step in tau_d.

    Raises
    ------
    ConfigError
        For a name that is not registered.
    """
    finite = math.isfinite(float(peclet))
    name = (AUTO_BROWNIAN if finite else AUTO_DETERMINISTIC) if integrator == AUTO else integrator
    info = _info(name)
    if timestep is None:
        timestep = info.default_timestep if finite else DEFAULT_TIMESTEP
    return name, float(timestep)


#: The Peclet number at which the adaptive Brownian default tolerance is ``default_tolerance``:
#: above it the tolerance shrinks as kT^1.5, below it grows as kT^0.5.
BROWNIAN_TOLERANCE_PECLET = 10.0
#: The exponent of that shrinking: tolerance = default (BROWNIAN_TOLERANCE_PECLET / Pe)^this.
BROWNIAN_TOLERANCE_EXPONENT = 1.5
#: The exponent of the growth below BROWNIAN_TOLERANCE_PECLET: with the bonds' thermal spread
#: ``sqrt(kT / B)``, so that the tolerance stays 0.44 of it (0.02 d of 0.045 d at Pe = 10).
BROWNIAN_TOLERANCE_LOW_EXPONENT = 0.5
#: Below this Peclet number the tolerance grows no further: the lowest Pe it was checked at
#: against the Monte Carlo (0.089 d).
BROWNIAN_TOLERANCE_LOWEST_PECLET = 0.5


def resolve_tolerance(name: str, tolerance: float | None, peclet: float = math.inf) -> float:
    """``run.tolerance`` resolved: the value given, or the integrator's default (in d).

    An unset tolerance is :data:`DEFAULT_TOLERANCE` (1e-4 d) for the deterministic adaptive
    integrators. For the adaptive Brownian one, whose error estimate carries the noise
    displacement (``knotmm.dynamics.adaptive_brownian``), it is the entry's
    ``default_tolerance`` (0.02 d) at ``Pe = 10``, ``0.02 (10 / Pe)^0.5`` below (0.045 d at
    Pe = 2, 0.063 d at Pe = 1, 0.089 d from Pe = 0.5 down) and ``0.02 (10 / Pe)^1.5`` above.
    The tolerance has to stay well below the thermal spread of the stiffest bonds,
    ``sqrt(kT / B)`` (0.045 d at Pe = 10, where 0.02 showed no bias against a Monte Carlo and
    0.05 shortened the bond-length spread by 1 %), which grows as ``sqrt(1 / Pe)``: below
    Pe = 10 the tolerance keeps that ratio, and at Pe = 0.5, 1 and 2 it matched the Monte
    Carlo's bond spread, bending and 1-3 distance as 0.02 d did, in half the steps
    (``benchmarks/README.md``). Above Pe = 10 the spread alone (0.0089 d at
    Pe = 50) was not enough for the sedimenting torus: at Pe = 50 (T(2,3), N = 60) it opened the
    torus (Rg_perp +0.17 d) and slowed it by 2.8 % (paired replicas, 4 standard errors), while
    0.002 d agreed with ``ito_heun`` at dt = 0.001 (``benchmarks/README.md``). The exponent 1.5
    puts 0.0018 d at Pe = 50 (not measured above). It never goes below the deterministic
    integrators' :data:`DEFAULT_TOLERANCE` (reached at Pe = 342).
    """
    if tolerance is not None:
        return float(tolerance)
    info = _info(name)
    if info.brownian and info.adaptive and math.isfinite(float(peclet)):
        ratio = BROWNIAN_TOLERANCE_PECLET / max(float(peclet), BROWNIAN_TOLERANCE_LOWEST_PECLET)
        exponent = BROWNIAN_TOLERANCE_EXPONENT if ratio < 1.0 else BROWNIAN_TOLERANCE_LOW_EXPONENT
        return max(info.default_tolerance * ratio**exponent, DEFAULT_TOLERANCE)
    return info.default_tolerance


def _listing(names) -> str:
    """``"a, b and c"``."""
    names = list(names)
    return " and ".join(filter(None, (", ".join(names[:-1]), names[-1])))


def integrator_help() -> str:
    """The help of ``run.integrator`` (:data:`knotmm.config.SCHEMA`), written from the table.

    ``"auto"`` and its policy, then every entry in :data:`REGISTRY`'s order with its
    description (and its default step if it has a fixed one), the deterministic ones first.
    """
    def entry(info: IntegratorInfo) -> str:
        step = "" if info.adaptive else f"; timestep {info.default_timestep:g}"
        return f"{info.name} ({info.description}{step})"

    deterministic = ", ".join(entry(i) for i in REGISTRY.values() if not i.brownian)
    brownian = ", ".join(entry(i) for i in REGISTRY.values() if i.brownian)
    return (f"time stepper: {AUTO} (the default: {AUTO_DETERMINISTIC} at run.peclet = inf, or "
            f"{AUTO_STIFF} when the chain is stiff; {AUTO_BROWNIAN} at finite Pe); "
            f"run.peclet = inf: {deterministic}; finite run.peclet: {brownian}")


def timestep_help() -> str:
    """The help of ``run.timestep``, with the defaults of :func:`resolve`."""
    steps: dict[float, list[str]] = {}
    for info in REGISTRY.values():
        if info.brownian:
            steps.setdefault(info.default_timestep, []).append(info.name)
    finite = ", ".join(f"{h:g} for {_listing(names)}" for h, names in steps.items())
    return ("step in tau_d (fixed-step and Brownian integrators); the first step of an adaptive "
            f"one; default {DEFAULT_TIMESTEP:g} (at finite run.peclet: {finite})")


def tolerance_help() -> str:
    """The help of ``run.tolerance``, with the defaults of :func:`resolve_tolerance`."""
    brownian = "; ".join(
        f"{i.name}: {i.default_tolerance:g} times ({BROWNIAN_TOLERANCE_PECLET:g} / Pe)^"
        f"{BROWNIAN_TOLERANCE_LOW_EXPONENT:g} below Pe = {BROWNIAN_TOLERANCE_PECLET:g} (Pe taken "
        f"as at least {BROWNIAN_TOLERANCE_LOWEST_PECLET:g}) and ^{BROWNIAN_TOLERANCE_EXPONENT:g} "
        f"above, at least {DEFAULT_TOLERANCE:g}"
        for i in REGISTRY.values() if i.adaptive and i.brownian)
    return (f"adaptive integrators: local error per step, in d; default {DEFAULT_TOLERANCE:g} "
            f"({brownian})")


def make(
    name: str,
    timestep: float,
    *,
    peclet: float = math.inf,
    seed: int | None = None,
    noise="auto",
    lanczos_tolerance: float = DEFAULT_LANCZOS_TOLERANCE,
    tolerance: float | None = None,
    max_timestep: float = DEFAULT_MAX_TIMESTEP,
    min_timestep: float = DEFAULT_MIN_TIMESTEP,
):
    """Build a registered integrator by name.

    Parameters
    ----------
    name : str
        A name in :data:`NAMES` (not ``"auto"``: see :func:`resolve`).
    timestep : float
        The step (fixed integrators) or first step (adaptive ones), in tau_d.
    peclet : float
        Brownian integrators: ``Pe = d F0 / kT`` (``inf``: no noise). A deterministic
        integrator needs ``inf``.
    seed : int or None
        Brownian integrators: seed of the noise stream
        (:func:`knotmm.dynamics.noise.noise_rng`).
    noise : {"auto", "cholesky", "lanczos"} or callable
        Brownian integrators: how ``B xi`` is drawn (:class:`knotmm.dynamics.noise.NoiseGenerator`).
    lanczos_tolerance : float
        Brownian integrators: tolerance of the Lanczos noise.
    tolerance : float or None
        Adaptive integrators: local error per step, in d (``None``: the integrator's
        default, :func:`resolve_tolerance`).
    max_timestep, min_timestep : float
        Adaptive integrators: largest step and floor, in tau_d.

    Returns
    -------
    knotmm.dynamics.deterministic.Integrator

    Raises
    ------
    ConfigError
        Naming ``run.integrator``, ``run.timestep``, ``run.peclet``, ``run.noise`` or
        ``run.lanczos_tolerance``.
    """
    info = _info(name)
    cls = info.load()
    if info.brownian:
        if not timestep > 0:
            raise ConfigError(f"run.timestep = {timestep!r}: must be > 0 (in tau_d)")
        adaptive = {}
        if info.adaptive:
            adaptive = dict(tolerance=resolve_tolerance(name, tolerance, peclet),
                            max_timestep=max_timestep, min_timestep=min_timestep)
        return cls(
            timestep, peclet=peclet, seed=seed, noise=noise, lanczos_tolerance=lanczos_tolerance,
            **adaptive,
        )
    if math.isfinite(float(peclet)):
        raise ConfigError(
            f"run.integrator = {name!r} cannot integrate Brownian dynamics (run.peclet = "
            f'{peclet:g}): leave run.integrator unset ("auto" picks {AUTO_BROWNIAN}, step '
            f'{REGISTRY[AUTO_BROWNIAN].default_timestep:g}) or use a Brownian one: '
            f'{", ".join(BROWNIAN_NAMES)}'
        )
    try:
        if info.adaptive:
            return cls(timestep, resolve_tolerance(name, tolerance), max_timestep, min_timestep)
        return cls(timestep)
    except ValueError as exc:
        if isinstance(exc, ConfigError):
            raise
        raise ConfigError(f"run.integrator = {name!r}: {exc}") from None


def warn_brownian_step(name: str, timestep: float, peclet: float) -> None:
    """Warn once per run when a Brownian step is too long for the stiff bond modes."""
    if REGISTRY[name].brownian and math.isfinite(peclet) and timestep > _BROWNIAN_STEP_WARNING:
        log.warning(
            "run.timestep = %g with run.peclet = %g: above ~%g tau_d the stiff bond "
            "modes are unstable or strongly biased (%g is a good step for ito_heun, %g "
            "for leimkuhler_matthews)",
            timestep,
            peclet,
            _BROWNIAN_STEP_WARNING,
            DEFAULT_BROWNIAN_TIMESTEP,
            DEFAULT_LM_TIMESTEP,
        )


def integrator_from_config(cfg: Mapping):
    """The integrator a run file asks for, deterministic or Brownian.

    ``run.integrator`` and ``run.timestep`` are resolved first (:func:`resolve`), then

    * a Brownian integrator (``ito_heun``, ``euler_maruyama``) gets the fixed step,
      ``kT = 1 / run.peclet`` (no noise at ``Pe = inf``), ``run.seed``, ``run.noise`` and
      ``run.lanczos_tolerance``;
    * a deterministic one at ``run.peclet = inf`` gets ``run.timestep``, ``run.tolerance``,
      ``run.max_timestep`` and ``run.min_timestep``;
    * the adaptive Brownian one (``ito_heun_adaptive``) gets both: the noise settings and
      ``run.tolerance`` (:func:`resolve_tolerance`), ``run.max_timestep``, ``run.min_timestep``;
    * a deterministic one at a finite ``run.peclet`` is a :class:`ConfigError` (its error
      control knows nothing of the noise).

    Parameters
    ----------
    cfg : knotmm.config.RunConfig or a mapping with the same dotted keys

    Returns
    -------
    knotmm.dynamics.deterministic.Integrator
    """
    name, timestep = resolve(cfg["run.integrator"], cfg["run.peclet"], cfg["run.timestep"])
    peclet = float(cfg["run.peclet"])
    thermal_energy(peclet)  # checks the range
    warn_brownian_step(name, timestep, peclet)
    return make(
        name,
        timestep,
        peclet=peclet,
        seed=cfg["run.seed"],
        noise=cfg["run.noise"],
        lanczos_tolerance=cfg["run.lanczos_tolerance"],
        tolerance=cfg["run.tolerance"],
        max_timestep=cfg["run.max_timestep"],
        min_timestep=cfg["run.min_timestep"],
    )
