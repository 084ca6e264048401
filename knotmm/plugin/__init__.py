"""Compiled RPY integrator: overdamped RPY dynamics inside OpenMM, as a C++ plugin.

:class:`RPYIntegrator` is an ``openmm.Integrator``: give it to ``openmm.Context`` or
``openmm.app.Simulation`` like any OpenMM integrator. Inside a step the plugin asks the Context
for forces in C++, applies the overlap-corrected Rotne-Prager-Yamakawa mobility
(:mod:`knotmm.dynamics.mobility`'s formulas) and moves the beads, so a step never returns to
Python. The methods are those of :mod:`knotmm.dynamics.deterministic`,
:mod:`knotmm.dynamics.brownian` and :mod:`knotmm.dynamics.adaptive_brownian`, formula for
formula (the tests in ``tests/plugin`` hold the plugin to them, and a test in
``tests/dynamics`` holds this table to the registry and to :data:`METHODS`):

======================= ===== ========= ==========================================================
method                  order adaptive  update
======================= ===== ========= ==========================================================
``euler``               1     no        ``y1 = y0 + h v(y0)``
``heun``                2     no        ``y1 = y0 + h/2 (v(y0) + v(y0 + h v(y0)))``
``midpoint``            2     no        ``y1 = y0 + h v(y0 + h/2 v(y0))``
``rk23``                3(2)  yes       Bogacki-Shampine, FSAL, PI step control (the default)
``rkc2``                2     yes       damped Runge-Kutta-Chebyshev, s stages from power iteration
``euler_maruyama``      1     no        ``y1 = y0 + h v(y0) + sqrt(2 kT h) B xi``, ``B B^T = mu``
``ito_heun``            1     no        Heun drift with the same Ito noise ``sqrt(2 kT h) B(y0) xi``
``leimkuhler_matthews`` 1     no        ``p = y0 + h v(y0) + k``, ``k <- sqrt(kT h/2) B(p) xi``,
                                        ``y1 = p + k``: the half kick ``k`` is held for next step
``ito_heun_adaptive``   1     yes       ``ito_heun``'s step, error ``h/2 (v(yE) - v(y0))`` against
                                        Euler-Maruyama's ``yE``, PI control; a rejected try's
                                        noise is kept and split by Brownian bridges
======================= ===== ========= ==========================================================

``v = mu F`` with ``mu`` the 3N x 3N RPY mobility (bead diameter ``d``, single-bead mobility
``mu0``). OpenMM's units are read as knotmm's model units: 1 nm = 1 d, 1 kJ/mol = 1 F0 d,
1 ps = 1 tau_d. Forces are computed with the chain shifted to its centre of mass (as
:class:`knotmm.engine.simulation.Simulation` does); the Context keeps the true positions. Virtual
sites (``ChainModel.segment_repulsion``) are not beads: OpenMM places them and hands their
forces to the beads.

The compiled module may be missing (a source checkout that was never built): importing this
package never fails; :func:`available` says whether the plugin loaded and :func:`load_error`
why not, so callers can fall back to the Python engine. The environment variable
``KNOTMM_NO_PLUGIN=1`` makes it unavailable on purpose (to test or compare the fallback). A
plugin compiled against another OpenMM (major.minor) than the one imported, or from older
sources than these files, is not used either, and :func:`rebuild_needed` says so (every
``knotmm run`` then names it, with :data:`REBUILD_COMMAND`).

The plugin's own tables are the owners of what it has: :data:`METHODS` is built from its
C++ method table (``rpyplugin.methodTable()``), and a failed step raises
:class:`StepFault` (``rpyplugin.StepFault``, an ``openmm.OpenMMException`` with the fault's
``kind``, ``method``, ``time``, ``bead`` and ``error_estimate``).

Noise (``noise``, ``setNoiseMethod``): ``"cholesky"`` (the default) takes ``B`` as the lower
Cholesky factor of the dense mobility; ``"lanczos"`` computes ``mu^(1/2) xi`` by the Krylov
method of :func:`knotmm.dynamics.noise.lanczos_sqrt` (full reorthogonalisation, stop when
successive iterates change by less than ``lanczos_tolerance``, relative), matrix-free with the
RPY pair loop of the velocities; both draw 3N normals per sample. The first stochastic
:class:`RPYIntegrator` made in a process hands the plugin LAPACK's ``dpotrf`` (Cholesky) and
``dstev`` (the Lanczos tridiagonal matrix's eigen-decomposition) from scipy
(:func:`use_lapack_cholesky`: the C function pointers of ``scipy.linalg.cython_lapack``, the
way numba's ``np.linalg.cholesky`` finds LAPACK; no link step, no new dependency); ``dpotrf``
is 2-3x faster than the plugin's built-in unblocked routine at N = 90. Without scipy, or for
the plugin used from C++, the built-in Cholesky-Crout takes its place (same results to
rounding), and Lanczos noise is refused (no ``dstev``). Deterministic runs never
import scipy. The factorisation runs on as many threads as the BLAS library is allowed
(``threadpoolctl``; :class:`knotmm.engine.simulation.Simulation` allows one).
"""

from __future__ import annotations

import importlib
import logging
import math
import os
import sys
from pathlib import Path

import openmm  # loads libOpenMM.so and OpenMM's platforms before the plugin library
import openmm.version

from knotmm.dynamics.registry import (
    DEFAULT_LANCZOS_TOLERANCE,
    DEFAULT_MAX_TIMESTEP,
    DEFAULT_MIN_TIMESTEP,
    DEFAULT_TOLERANCE,
)

__all__ = [
    "RPYIntegrator",
    "PluginUnavailableError",
    "available",
    "load_error",
    "from_python_integrator",
    "KERNEL_NAME",
    "METHODS",
    "REBUILD_COMMAND",
    "StepFault",
    "noise_factor_precision",
    "noise_settings",
    "platform_load_errors",
    "rebuild_needed",
    "use_lapack_cholesky",
]

log = logging.getLogger(__name__)

#: Method name -> (order, adaptive, stochastic), in the plugin's order: the compiled plugin's
#: own table (``rpyplugin.methodTable()``); empty when the plugin is unavailable. The
#: registry (:mod:`knotmm.dynamics.registry`, ``IntegratorInfo.engines``) says which methods
#: have a plugin counterpart; ``tests/plugin/test_plugin_contract.py`` holds the two together.
METHODS: dict[str, tuple[int, bool, bool]] = {}

#: The name under which the plugin's platforms register the integrator's kernel (C++
#: ``IntegrateRPYStepKernel::Name()``): ask a platform ``supportsKernels([KERNEL_NAME])``.
KERNEL_NAME = "IntegrateRPYStep"

#: Platform name -> why the plugin's library for that platform did not load (filled at import).
_platform_load_errors: dict[str, str] = {}


def platform_load_errors() -> dict[str, str]:
    """Why a device platform's plugin library (OpenCL, CUDA) was not loaded, by platform.

    Only platforms that OpenMM has and for which a library was built appear; a platform whose
    library loaded is absent. A copy: changing it changes nothing.
    """
    return dict(_platform_load_errors)


#: The command that rebuilds the plugin against the OpenMM that is installed.
REBUILD_COMMAND = ("pip install -e . --no-build-isolation in the knotmm checkout "
                   "(an installed copy: pip install --force-reinstall --no-deps knotmm)")


class PluginUnavailableError(ImportError):
    """The compiled plugin is not built or could not be loaded (see :func:`load_error`)."""


def _installed_build() -> list[str]:
    """The folder of an installed knotmm's compiled plugin, when this copy has none.

    A source checkout that comes first on ``sys.path`` (``python -m pytest`` run in it, as
    the README says) shadows the installed package, whose ``knotmm/plugin/`` holds the files
    that ``pip install .`` compiled from that checkout; the package then loads them from
    there, so tests in a checkout exercise the build.
    """
    here = Path(__file__).resolve().parent
    if any(here.glob("_rpyplugin*")):
        return []
    for entry in sys.path:
        candidate = (Path(entry or ".") / "knotmm" / "plugin").resolve()
        if (candidate != here and (candidate / "rpyplugin.py").is_file()
                and any(candidate.glob("_rpyplugin*"))):
            return [str(candidate)]
    return []


__path__.extend(_installed_build())  # noqa: F821 - a package's own __path__

_load_error: str | None = None
_rebuild_needed = False  # built, but not usable as it is
_switch = os.environ.get("KNOTMM_NO_PLUGIN", "")
_rpy = None
if _switch not in ("", "0"):
    _load_error = (f"knotmm.plugin: switched off by the environment variable "
                   f"KNOTMM_NO_PLUGIN={_switch} (unset it to use the compiled plugin)")
else:
    try:
        _rpy = importlib.import_module(".rpyplugin", __name__)
    except ImportError as exc:  # not built, or libOpenMM.so / ABI mismatch
        _rebuild_needed = not isinstance(exc, ModuleNotFoundError)  # built, but broken
        _load_error = (
            f"knotmm.plugin: the compiled RPY plugin could not be loaded ({exc}). Build it "
            f"with `pip install .` (or see plugin/README.md); the Python engine still works"
        )
        log.debug(_load_error)
if _rpy is not None:
    _built = _rpy.builtAgainstOpenMMVersion()
    _running = openmm.version.version
    if _built.split(".")[:2] != _running.split(".")[:2]:
        # C++ classes (Integrator, ContextImpl) may differ in layout: do not touch them
        _load_error = (
            f"knotmm.plugin: compiled against OpenMM {_built} but OpenMM {_running} is "
            f"installed; rebuild it: {REBUILD_COMMAND}"
        )
        _rpy, _rebuild_needed = None, True
    elif not (all(hasattr(_rpy, name) for name in ("methodTable", "StepFault"))
              and hasattr(_rpy.RPYIntegrator, "stepToWithin")
              and hasattr(_rpy.RPYIntegrator, "estimateSpectralRadius")):
        _load_error = (
            "knotmm.plugin: the compiled plugin is older than knotmm's Python files (no "
            "methodTable, StepFault, RPYIntegrator.stepToWithin or "
            f"estimateSpectralRadius); rebuild it: "
            f"{REBUILD_COMMAND}"
        )
        _rpy, _rebuild_needed = None, True
if _rpy is not None:
    try:
        _rpy.registerRPYKernelFactories()
    except Exception as exc:  # noqa: BLE001 - any failure means: not usable
        _load_error = f"knotmm.plugin: registering the RPY kernels failed: {exc}"
        _rpy, _rebuild_needed = None, True
#: OpenMM device platform -> the plugin's library that registers the integrator's kernel for it
#: (the device backend of plugin/platforms/common over that platform's ComputeContext), built
#: only where the platform's headers and library were found, beside the compiled module.
_PLATFORM_LIBRARIES = {"OpenCL": "libKnotMMRPYPluginOpenCL.so", "CUDA": "libKnotMMRPYPluginCUDA.so"}


def _load_platform_libraries(folder: Path) -> None:
    """Load the device platforms' libraries in ``folder`` whose OpenMM platform is present.

    ``openmm.Platform.loadPluginLibrary`` opens each and calls its ``registerKernelFactories()``;
    a failure (or a library that registers nothing) is recorded in
    :func:`platform_load_errors`, never raised.
    """
    present = {openmm.Platform.getPlatform(i).getName()
               for i in range(openmm.Platform.getNumPlatforms())}
    for platform, filename in _PLATFORM_LIBRARIES.items():
        path = folder / filename
        if platform not in present or not path.is_file():
            continue
        try:
            openmm.Platform.loadPluginLibrary(str(path))
            if not openmm.Platform.getPlatformByName(platform).supportsKernels([KERNEL_NAME]):
                raise RuntimeError(f"it registered no {KERNEL_NAME} kernel")
        except Exception as exc:  # noqa: BLE001 - recorded, the other platforms still work
            _platform_load_errors[platform] = f"{path}: {exc}"
            log.debug("knotmm.plugin: %s platform library not loaded: %s", platform, exc)


if _rpy is not None:
    try:
        _load_platform_libraries(Path(_rpy.__file__).resolve().parent)
    except Exception as exc:  # noqa: BLE001 - never fail the import over a device platform
        _platform_load_errors["*"] = f"loading the device platforms' libraries failed: {exc}"
if _rpy is not None:
    METHODS.update((str(name), (int(order), bool(adaptive), bool(stochastic)))
                   for name, order, adaptive, stochastic in _rpy.methodTable())
    StepFault = _rpy.StepFault
else:

    class StepFault(openmm.OpenMMException):  # type: ignore[no-redef]
        """A failed plugin step; without the plugin a placeholder that is never raised.

        The plugin's ``rpyplugin.StepFault`` (an ``openmm.OpenMMException``) is raised by
        ``RPYIntegrator.step``/``stepTo`` when a step fails; other
        ``openmm.OpenMMException`` s are not step faults. ``str(exc)`` is the one-line
        message.

        Attributes
        ----------
        kind : str
            ``"non_finite"``, ``"step_underflow"``, ``"not_positive_definite"`` or
            ``"lanczos_not_converged"``.
        method : str
            The integrator's method.
        time : float
            Time of the last good state (which the Context keeps), in ps (= tau_d).
        bead : int
            The bead concerned (``non_finite``: the first non-finite one), or -1.
        error_estimate : float
            ``step_underflow``: the error estimate over the tolerance; nan otherwise.
        """

        kind = method = ""
        time = math.nan
        bead = -1
        error_estimate = math.nan


def available() -> bool:
    """True when the compiled plugin loaded and its kernels are registered."""
    return _rpy is not None


def load_error() -> str | None:
    """Why the plugin is unavailable, or ``None`` when it loaded."""
    return _load_error


def rebuild_needed() -> bool:
    """True when a compiled plugin is there but cannot be used until it is rebuilt.

    Compiled against another OpenMM (major.minor) than the one imported, from older sources
    than these Python files, or failing to load or register its kernels. Not when it was
    never built or is switched off by ``KNOTMM_NO_PLUGIN``: then :func:`available` is False
    by choice. :func:`knotmm.engine.engines.resolve_engine` warns about it on every run.
    """
    return _rebuild_needed


_lapack: bool | None = None  # None: not decided yet


def use_lapack_cholesky() -> bool:
    """Hand the plugin LAPACK's ``dpotrf``, ``spotrf`` and ``dstev`` for its noise, once;
    True if in use.

    Takes the C function pointers that ``scipy.linalg.cython_lapack`` exports (PyCapsules,
    ``void dpotrf(char *uplo, int *n, double *a, int *lda, int *info)``, ``spotrf`` the
    same with ``float *a`` (the single-precision factor: ``RPYIntegrator.setNoisePrecision``)
    and ``void dstev(char *jobz, int *n, double *d, double *e, double *z, int *ldz, double
    *work, int *info)``) and gives their addresses to the plugin (``setCholeskyRoutine``,
    ``setSingleCholeskyRoutine``, ``setTridiagonalEigenRoutine``), which then calls them for
    every noise sample (Cholesky factors; the Lanczos tridiagonal matrix's eigenvectors);
    the module stays loaded (in ``sys.modules``: :func:`_cython_lapack`), so the library
    does. Without scipy (or without the plugin) the plugin keeps its built-in Cholesky,
    cannot draw Lanczos noise, and this returns False. Called by the first stochastic
    :class:`RPYIntegrator`, so that deterministic runs never load LAPACK.
    """
    global _lapack
    if _lapack is None:
        _lapack = False
        if _rpy is not None:
            cython_lapack = _cython_lapack()
            if cython_lapack is None:
                log.debug("knotmm.plugin: no scipy; the plugin's built-in Cholesky is used")
            else:
                capi = cython_lapack.__pyx_capi__
                _rpy.setCholeskyRoutine(_capsule_address(capi["dpotrf"]))
                _rpy.setSingleCholeskyRoutine(_capsule_address(capi["spotrf"]))
                _rpy.setTridiagonalEigenRoutine(_capsule_address(capi["dstev"]))
                _lapack = True
    return _lapack


def _cython_lapack():
    """scipy's ``scipy.linalg.cython_lapack`` extension module, or None without scipy.

    Loaded from its file beside ``scipy/linalg/__init__.py`` without running that package's
    ``__init__`` (0.03-0.05 s against 0.33-0.39 s for ``from scipy.linalg import
    cython_lapack``, measured 2026-12-06: a Brownian run's start), and registered in
    ``sys.modules`` under its own name, which keeps it (and its LAPACK library) loaded and
    gives a later ``import scipy.linalg`` the same module. Where the file is not found or does
    not load (another scipy layout), the package import is used. Called by
    :func:`use_lapack_cholesky` and, to limit the library's threads for a replica set, by
    :mod:`knotmm.engine.copies`; once loaded, the module in ``sys.modules`` is returned.
    """
    import importlib.machinery  # noqa: PLC0415 - only stochastic runs need LAPACK
    import importlib.util  # noqa: PLC0415

    name = "scipy.linalg.cython_lapack"
    if name in sys.modules:
        return sys.modules[name]
    try:
        import scipy  # noqa: PLC0415 - the bare package: 0.03 s
    except ImportError:
        return None
    folder = Path(scipy.__file__).parent / "linalg"
    files = [f for f in (folder / f"cython_lapack{suffix}" for suffix in
                         importlib.machinery.EXTENSION_SUFFIXES) if f.is_file()]
    if files and name not in sys.modules:
        try:
            spec = importlib.util.spec_from_file_location(name, files[0])
            module = importlib.util.module_from_spec(spec)
            sys.modules[name] = module
            spec.loader.exec_module(module)
            module.__pyx_capi__["spotrf"]  # noqa: B018 - fails here, not in the caller
            return module
        except Exception as exc:  # noqa: BLE001 - any failure: the package import
            sys.modules.pop(name, None)
            log.debug("knotmm.plugin: %s did not load (%s); importing scipy.linalg",
                      files[0], exc)
    try:
        from scipy.linalg import cython_lapack  # noqa: PLC0415
    except ImportError:
        return None
    return cython_lapack


def _capsule_address(capsule) -> int:
    """The pointer a PyCapsule holds, as an int (ctypes, as numba reads Cython's capsules)."""
    import ctypes

    api = ctypes.pythonapi
    api.PyCapsule_GetName.restype = ctypes.c_char_p
    api.PyCapsule_GetName.argtypes = [ctypes.py_object]
    api.PyCapsule_GetPointer.restype = ctypes.c_void_p
    api.PyCapsule_GetPointer.argtypes = [ctypes.py_object, ctypes.c_char_p]
    address = api.PyCapsule_GetPointer(capsule, api.PyCapsule_GetName(capsule))
    if not address:
        raise RuntimeError(f"capsule={capsule!r}: holds no pointer")
    return int(address)


if _rpy is not None:

    class RPYIntegrator(_rpy.RPYIntegrator):
        """Overdamped dynamics ``dr/dt = mu(r) F(r)`` (+ Ito noise) with the RPY mobility.

        Parameters
        ----------
        step_size : float or openmm.unit.Quantity
            Fixed step, or the first step of an adaptive method, in ps (= tau_d).
        method : str
            One of :data:`METHODS`; default ``"rk23"``.
        error_tolerance : float
            Adaptive methods: largest per-bead displacement error per step, in nm (= d).
        bead_diameter : float
            ``d`` of the RPY tensor, in nm.
        mobility : float
            Single-bead mobility ``mu0``, in nm / (ps kJ/mol/nm) (1 in model units).
        kT : float
            Thermal energy in kJ/mol (= F0 d, so ``kT = 1 / Pe``); needs a stochastic method.
            0 (the default) is deterministic.
        seed : int
            Seed of the noise stream (0: a fresh one each time, as OpenMM's integrators).
        min_step, max_step : float
            Bounds of the adaptive step, in ps (knotmm's defaults, the registry's). An adaptive
            step below ``min_step`` raises ``openmm.OpenMMException`` and keeps the last state.
        threads : int
            Threads of the RPY pair loop (used from about 256 beads; same result bit for bit).
        noise : {"cholesky", "lanczos"}
            How stochastic methods draw ``B xi``: dense Cholesky factor, or the Lanczos
            approximation of ``mu^(1/2) xi`` (matrix-free; for large N).
        lanczos_tolerance : float
            Lanczos: relative change between successive iterates at which to stop.
        noise_precision : {"auto", "single", "double"}
            Cholesky noise: the precision the mobility is factorised in. ``"auto"`` follows
            the platform's forces: single precision on the CPU platform (and a device
            platform in single or mixed precision), double on Reference (and a device in
            double). A single-precision factor has ``L L^T = mu`` to about 1e-7 of its
            largest entry, far below any sampling error, and costs 0.6x a double one (LAPACK's
            ``spotrf``, N = 90, this CPU; ``benchmarks/README.md``); the products ``L z`` are
            summed in double.

        Notes
        -----
        OpenMM-style methods: ``step(n)`` takes ``n`` accepted steps; ``stepTo(time)`` advances
        to ``time`` (ps) exactly, shortening the last step; ``stepToWithin(time, seconds)``
        takes the same steps but returns between two of them once ``seconds`` of wall-clock
        time are spent (0: after one step), True when ``time`` is reached, so that a caller
        answers signals and checks the state during a long stretch (the steps, and so the
        results, do not depend on where the calls end); ``getStepSize()`` is the next step
        an adaptive method will try. Counters: ``getNumForceEvaluations()``,
        ``getNumAcceptedSteps()``, ``getNumRejectedSteps()``; rkc2 also
        ``getLastStages()`` and ``getSpectralRadius()`` (1/ps). The adaptive state, the
        counters, the cached velocity, the noise stream and leimkuhler_matthews's held half
        kick are part of ``Context.createCheckpoint()``, so a loaded checkpoint continues bit
        for bit. The held kick is dropped when the Context's positions are set to other ones
        (the next step draws a fresh one, as ``LeimkuhlerMatthews.reset()``).
        ``setBeadDiameter``, ``setMobility`` and ``setRandomNumberSeed`` must be called before
        the Context is created. Kinetic energy is reported as 0 (no inertia).
        """

        def __init__(
            self,
            step_size,
            method: str = "rk23",
            error_tolerance: float = DEFAULT_TOLERANCE,
            *,
            bead_diameter: float = 1.0,
            mobility: float = 1.0,
            kT: float = 0.0,
            seed: int = 0,
            min_step: float = DEFAULT_MIN_TIMESTEP,
            max_step: float = DEFAULT_MAX_TIMESTEP,
            threads: int = 1,
            noise: str = "cholesky",
            lanczos_tolerance: float = DEFAULT_LANCZOS_TOLERANCE,
            noise_precision: str = "auto",
        ):
            if method not in METHODS:
                raise ValueError(
                    f"method={method!r}: expected one of {', '.join(METHODS)}"
                )
            if METHODS[method][2]:
                use_lapack_cholesky()
            super().__init__(step_size, method, error_tolerance)
            self.setBeadDiameter(bead_diameter)
            self.setMobility(mobility)
            self.setThermalEnergy(kT)
            self.setRandomNumberSeed(int(seed))
            self.setMinimumStepSize(min_step)
            self.setMaximumStepSize(max_step)
            self.setNumThreads(int(threads))
            self.setNoiseMethod(noise)
            self.setLanczosTolerance(float(lanczos_tolerance))
            self.setNoisePrecision(noise_precision)

        def __repr__(self) -> str:
            return (
                f"RPYIntegrator({self.getStepSize()}, method={self.getMethod()!r}, "
                f"error_tolerance={self.getErrorTolerance():g}, kT={self.getThermalEnergy():g}, "
                f"noise={self.getNoiseMethod()!r})"
            )

    # XmlSerializer.deserialize / clone give this class (rpyplugin casts their result)
    _rpy.cast_class = RPYIntegrator

else:

    class RPYIntegrator:  # type: ignore[no-redef]
        """Placeholder when the plugin is unavailable: constructing it raises."""

        def __init__(self, *args, **kwargs):
            raise PluginUnavailableError(_load_error)



def noise_factor_precision(force_precision: str) -> str:
    """The precision the plugin factorises the mobility in for Cholesky noise, at its default
    ``RPYIntegrator`` noise precision ``"auto"`` (knotmm's runs), as its backends resolve it.

    Parameters
    ----------
    force_precision : {"single", "mixed", "double"}
        The platform's force precision (:class:`knotmm.plan.Placement`).

    Returns
    -------
    str
        ``"single"`` where the forces are single or mixed precision, else ``"double"``.
    """
    return "single" if force_precision in ("single", "mixed") else "double"


def noise_settings(integrator, n_beads: int | None = None) -> tuple[str, float]:
    """The plugin's noise method and Lanczos tolerance for one of knotmm's Brownian integrators.

    Parameters
    ----------
    integrator : knotmm.dynamics.brownian.StochasticIntegrator
        Its ``noise`` (a :class:`knotmm.dynamics.noise.NoiseGenerator`) decides.
    n_beads : int, optional
        The chain's size, which resolves ``noise = "auto"``
        (:meth:`~knotmm.dynamics.noise.NoiseGenerator.method_for`); ``None``: ``"auto"`` is
        taken as ``"cholesky"`` (the plugin's default).

    Returns
    -------
    (str, float)
        ``"cholesky"`` or ``"lanczos"``, and the tolerance. An integrator without a
        :class:`~knotmm.dynamics.noise.NoiseGenerator` (a custom noise callable, which the
        plugin cannot run) gives ``("cholesky", DEFAULT_LANCZOS_TOLERANCE)``.
    """
    noise = getattr(integrator, "noise", None)
    if not hasattr(noise, "method_for"):
        return "cholesky", DEFAULT_LANCZOS_TOLERANCE
    if n_beads is None:
        method = "cholesky" if noise.method == "auto" else noise.method
    else:
        method = noise.method_for(int(n_beads))
    return method, float(noise.tolerance)


def from_python_integrator(integrator, threads: int = 1,
                           n_beads: int | None = None) -> RPYIntegrator:
    """The plugin integrator equivalent to one of knotmm's Python integrators.

    Reads the attributes the Python integrators have (``name``, ``timestep``; adaptive:
    ``tolerance``, ``max_timestep``, ``min_timestep``; Brownian: ``kT``, ``seed``), so it
    does not depend on where those classes live.

    Parameters
    ----------
    integrator : knotmm.dynamics.deterministic.Integrator or
                 knotmm.dynamics.brownian.StochasticIntegrator
    threads : int
        Threads of the plugin's pair loop.
    n_beads : int, optional
        The chain's size: resolves a Brownian integrator's ``noise = "auto"``
        (:func:`noise_settings`; ``None``: Cholesky).

    Returns
    -------
    RPYIntegrator
        Same method, step (in tau_d = ps), tolerance (in d = nm) and step bounds; for a
        Brownian integrator the same ``kT`` (F0 d = kJ/mol), noise method and Lanczos
        tolerance. Deterministic methods then take the same steps as the Python engine; the
        noise stream is the plugin's own (same statistics, other numbers), seeded from
        ``seed`` (``None``: fresh entropy).

    Raises
    ------
    ValueError
        If the integrator's method has no plugin counterpart.
    PluginUnavailableError
        If the plugin is not available.
    """
    if _rpy is None:
        raise PluginUnavailableError(_load_error)
    name = getattr(integrator, "name", None)
    if name not in METHODS:
        raise ValueError(
            f"integrator={integrator!r}: method {name!r} has no plugin counterpart "
            f"(expected one of {', '.join(METHODS)})"
        )
    kwargs = {"threads": threads}
    tolerance = DEFAULT_TOLERANCE
    if METHODS[name][1]:
        tolerance = float(integrator.tolerance)
        kwargs.update(max_step=float(integrator.max_timestep),
                      min_step=float(integrator.min_timestep))
    if METHODS[name][2]:
        seed = getattr(integrator, "seed", None)
        # the plugin takes a nonzero 31-bit seed (0 means fresh entropy, as in OpenMM)
        noise, lanczos_tolerance = noise_settings(integrator, n_beads)
        kwargs.update(kT=float(getattr(integrator, "kT", 0.0)),
                      seed=0 if seed is None else int(seed) % 2147483646 + 1,
                      noise=noise, lanczos_tolerance=lanczos_tolerance)
    return RPYIntegrator(float(integrator.timestep), name, tolerance, **kwargs)
