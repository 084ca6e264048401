"""Which engine integrates a run, and making it: the compiled plugin or the Python integrators.

``run.engine`` (``docs/architecture.md``, "The engine in one loop"):

* ``"python"``: the integrators of :mod:`knotmm.dynamics`, stepped from Python
  (:class:`knotmm.engine.python_engine.PythonEngine`: the readable reference);
* ``"plugin"``: :class:`knotmm.plugin.RPYIntegrator`, which takes every step in C++ up to the
  next report time (:class:`knotmm.engine.plugin_engine.PluginEngine`); if the plugin is not
  built, cannot load or is switched off (``KNOTMM_NO_PLUGIN=1``), one warning names
  :func:`knotmm.plugin.load_error` and the run uses the Python engine;
* ``"auto"`` (the default): the plugin when it is available, the Python engine otherwise, and
  for GPU platforms, where the plugin has no kernel. Brownian runs take the
  plugin too (its Cholesky is LAPACK's, as the Python engine's, and its step has no Python
  round trips: T(2,3), N = 90, Pe = 2, CPU time per step 1.12 against 1.68 ms with ito_heun
  at dt = 0.002 and 0.96 against 1.69 ms with leimkuhler_matthews at 0.01,
  ``benchmarks/bench_steps.py brownian``), whether the noise is Cholesky's or Lanczos's
  (``run.noise``; ``"auto"`` is Lanczos above 300 beads): the plugin has both.

A plugin that was built but cannot be used as it is (compiled against another OpenMM than the
one imported, or from older sources: :func:`knotmm.plugin.rebuild_needed`) is worth a warning
whatever ``run.engine`` says: :func:`resolve_engine` logs one line with the command that
rebuilds it (``knotmm run`` prints it). A plugin that was never built, or was switched off,
is silent unless ``run.engine = "plugin"`` asked for it.

Which methods each engine has is :mod:`knotmm.dynamics.registry`'s
(:attr:`~knotmm.dynamics.registry.IntegratorInfo.engines`), checked against the loaded
plugin's own table (:data:`knotmm.plugin.METHODS`).

Both engines take the same steps for deterministic methods (positions equal to 1e-10 d over
1 tau_d on the Reference platform); the Brownian methods use different noise streams with
the same statistics.

``run.platform = "auto"`` (:func:`auto_platform`) is decided after the engine, for it: the CPU
platform (Reference where OpenMM has no CPU platform), unless the engine can use a device
platform (the Python engine can use any; the plugin those on which it has its kernel,
:func:`plugin_platforms`, which asks OpenMM), the chain has at least :data:`DEVICE_MIN_BEADS`
beads, and a device platform is real
(:func:`device_properties`): CUDA or HIP with a device, or an OpenCL implementation that
OpenMM supports (NVIDIA, AMD, Apple, Intel: the vendors OpenMM itself does not warn about)
with a GPU that has double precision, which the run is then pinned to. A CPU implementation
such as pocl, which OpenMM runs with "WARNING: Using an unsupported OpenCL implementation",
is never taken (issue 30).
"""

from __future__ import annotations

import ctypes
import functools
import importlib
import logging
import math

from knotmm.dynamics import registry
from knotmm.errors import ConfigError

__all__ = [
    "DEVICE_MIN_BEADS",
    "DEVICE_PLATFORMS",
    "ENGINES",
    "PLUGIN",
    "PYTHON",
    "auto_platform",
    "device_properties",
    "make_engine",
    "opencl_device",
    "platform_names",
    "plugin_platforms",
    "resolve_engine",
    "select_platform",
]

log = logging.getLogger(__name__)

PLUGIN = registry.PLUGIN_ENGINE
PYTHON = registry.PYTHON_ENGINE
#: The ``run.engine`` values.
ENGINES = ("auto", PLUGIN, PYTHON)
#: The device platforms ``run.platform = "auto"`` may take, best first: the registry's (the
#: one owner). Which platforms the plugin runs on is OpenMM's to say (:func:`plugin_platforms`).
DEVICE_PLATFORMS = registry.DEVICE_PLATFORMS
#: Beads from which ``run.platform = "auto"`` considers a device platform.
DEVICE_MIN_BEADS = 2000
#: OpenCL platform vendors OpenMM supports (``OpenCLContext``'s ``isSupported``: any other
#: makes it print "WARNING: Using an unsupported OpenCL implementation").
OPENCL_VENDORS = ("NVIDIA", "Advanced Micro Devices", "Apple", "Intel")
#: Engine name -> (module, class) of its :class:`knotmm.engine.base.Engine`.
_ENGINE_CLASSES = {
    PYTHON: ("knotmm.engine.python_engine", "PythonEngine"),
    PLUGIN: ("knotmm.engine.plugin_engine", "PluginEngine"),
}


def make_engine(name: str, integrator, threads: int = 1, n_beads: int | None = None):
    """The engine called ``name`` for ``integrator`` (a :class:`knotmm.engine.base.Engine`).

    Parameters
    ----------
    name : {"python", "plugin"}
        A resolved engine (:func:`resolve_engine`), not ``"auto"``.
    integrator : knotmm.dynamics.deterministic.Integrator
        The run's integrator.
    threads : int
        Threads of the plugin's RPY pair loop (the Python engine's are the Simulation's).
    n_beads : int, optional
        The chain's size (the plugin resolves ``run.noise = "auto"`` with it).

    Raises
    ------
    ConfigError
        For another ``name``.
    """
    if name not in _ENGINE_CLASSES:
        raise ConfigError(f"engine = {name!r}: expected {PYTHON!r} or {PLUGIN!r}")
    module, cls = _ENGINE_CLASSES[name]
    engine = getattr(importlib.import_module(module), cls)
    if name == PLUGIN:
        return engine(integrator, threads=threads, n_beads=n_beads)
    return engine(integrator)


def resolve_engine(requested: str, integrator: str, peclet: float = math.inf,
                   platform: str = "CPU", noise_method: str = "cholesky") -> str:
    """The engine a run uses: ``"plugin"`` or ``"python"``.

    Parameters
    ----------
    requested : {"auto", "plugin", "python"}
        ``run.engine``.
    integrator : str
        The resolved ``run.integrator`` (a registry name, not ``"auto"``).
    peclet : float
        ``run.peclet``. The plugin runs Brownian and deterministic runs alike, so it does
        not change the choice; kept so callers can pass it.
    platform : str
        The OpenMM platform's name, or ``"auto"``, which :func:`auto_platform` resolves for
        the engine chosen here (the CPU for the plugin).
    noise_method : {"cholesky", "lanczos"}
        How a Brownian run's noise is drawn (``run.noise`` resolved for the chain's size,
        :meth:`knotmm.dynamics.noise.NoiseGenerator.method_for`). Both engines draw either
        kind, so it does not change the choice; kept so callers can pass it.

    Returns
    -------
    str
        ``"plugin"`` or ``"python"``. When ``"plugin"`` was asked for and cannot be used, or
        the plugin needs a rebuild (:func:`knotmm.plugin.rebuild_needed`; whatever was
        asked for), one warning (logged, so ``knotmm run`` prints it) says why.
    """
    if requested not in ENGINES:
        raise ConfigError(f"run.engine = {requested!r}: expected one of {', '.join(ENGINES)}")
    import knotmm.plugin as plugin

    if not plugin.available():
        if requested == PLUGIN:
            log.warning("run.engine = \"plugin\": %s; using the Python engine",
                        plugin.load_error())
        elif plugin.rebuild_needed():  # built, but not usable: say so whatever was asked
            log.warning("%s; using the Python engine", plugin.load_error())
        return PYTHON
    if requested == PYTHON:
        return PYTHON
    has_method = _plugin_has(plugin, integrator)
    if requested == PLUGIN:
        if not has_method:
            log.warning("run.engine = \"plugin\": run.integrator = %r has no plugin "
                        "counterpart; using the Python engine", integrator)
            return PYTHON
        if platform != "auto" and platform not in plugin_platforms():
            log.warning("run.engine = \"plugin\": the plugin has no kernel for the %s platform "
                        "(it has one for %s%s); using the Python engine", platform,
                        " and ".join(plugin_platforms()), _missing_library(platform))
            return PYTHON
        return PLUGIN
    if not has_method or (platform != "auto" and platform not in plugin_platforms()):
        return PYTHON
    return PLUGIN


def select_platform(name: str, n_beads: int, threads: int = 1, engine: str = PYTHON,
                    precision: str = "auto"):
    """Resolve a platform name to ``(openmm.Platform, properties)``.

    ``"auto"`` (:func:`knotmm.engine.engines.auto_platform`) takes the CPU platform with
    ``threads`` threads (1 by default: for the chain sizes of the study the force kernels are
    too small to gain from threads); only for ``n_beads >= 2000`` a device platform (CUDA,
    HIP, OpenCL) with a real device that OpenMM supports (and, for the plugin ``engine``, on
    which the plugin has its kernel). A device platform runs in ``precision``
    (``run.precision``: ``"auto"`` is mixed, or ``"double"``).

    Raises
    ------
    ConfigError
        A platform this OpenMM does not have, or ``precision = "double"`` on the CPU
        platform (its forces are single precision).
    """
    import openmm

    available = platform_names()
    pinned = {}
    if name == "auto":
        name, pinned = auto_platform(n_beads, engine, available)
    if name not in available:
        raise ConfigError(
            f"run.platform = {name!r}: not available in this OpenMM installation "
            f"(available: {', '.join(available)}); use run.platform = \"auto\""
        )
    if precision == "double" and name == "CPU":
        raise ConfigError(
            'run.precision = "double": the CPU platform computes forces in single precision; '
            'use run.platform = "Reference" (double, one thread) or a device platform, or '
            'run.precision = "auto"')
    platform = openmm.Platform.getPlatformByName(name)
    properties = {}
    if name == "CPU":
        properties["Threads"] = str(int(threads))
    elif name in DEVICE_PLATFORMS:
        properties["Precision"] = "mixed" if precision == "auto" else precision
    properties.update(pinned)
    return platform, properties


def platform_names() -> list[str]:
    """The names of the OpenMM platforms that loaded in this process."""
    import openmm

    return [openmm.Platform.getPlatform(i).getName()
            for i in range(openmm.Platform.getNumPlatforms())]


def plugin_platforms() -> tuple[str, ...]:
    """The loaded OpenMM platforms on which the compiled plugin has its kernel, in OpenMM's order.

    Asked of OpenMM (``Platform.supportsKernels``) after :mod:`knotmm.plugin` has registered
    its kernel factories: the Reference and CPU platforms from the plugin library itself, a
    device platform (OpenCL, CUDA) where its own factory library was built and loaded
    (:func:`knotmm.plugin.platform_load_errors` says why one was not). Empty without the plugin.
    """
    import knotmm.plugin as plugin

    if not plugin.available():
        return ()
    import openmm

    return tuple(name for name in platform_names()
                 if openmm.Platform.getPlatformByName(name).supportsKernels([plugin.KERNEL_NAME]))


def _missing_library(platform: str) -> str:
    """Why the plugin has no kernel on ``platform``, as a clause (empty when not known)."""
    import knotmm.plugin as plugin

    why = plugin.platform_load_errors().get(platform)
    return f"; its {platform} library did not load: {why}" if why else ""


def auto_platform(n_beads: int, engine: str, available: list[str] | None = None,
                  probe=None, kernels: tuple[str, ...] | None = None) -> tuple[str, dict[str, str]]:
    """The platform ``run.platform = "auto"`` takes for a run of ``n_beads`` on ``engine``.

    The CPU platform (Reference where there is none), unless ``n_beads >= DEVICE_MIN_BEADS``
    and one of :data:`DEVICE_PLATFORMS` is available, real by ``probe`` and, for the plugin,
    one it has its kernel on: then the first such, with the properties that pin it to its
    device.

    Parameters
    ----------
    n_beads : int
        The run's beads.
    engine : {"plugin", "python"}
        The engine chosen (:func:`resolve_engine`).
    available : list of str, optional
        OpenMM's platform names; default :func:`platform_names`.
    probe : callable, optional
        ``probe(name)``: the properties that pin a real device of platform ``name``, or None
        when it has none that OpenMM supports; default :func:`device_properties`.
    kernels : tuple of str, optional
        The platforms the plugin has its kernel on; default :func:`plugin_platforms`.

    Returns
    -------
    tuple of (str, dict)
        The platform's name and the properties it needs (empty for the CPU).
    """
    available = platform_names() if available is None else available
    probe = device_properties if probe is None else probe
    cpu = "CPU" if "CPU" in available else "Reference"
    if n_beads < DEVICE_MIN_BEADS:
        return cpu, {}
    usable = available
    if engine != PYTHON:
        usable = plugin_platforms() if kernels is None else kernels
    for name in DEVICE_PLATFORMS:
        if name in available and name in usable:
            properties = probe(name)
            if properties is not None:
                return name, dict(properties)
    return cpu, {}


@functools.cache
def device_properties(name: str) -> dict[str, str] | None:
    """Whether the device platform ``name`` has a device OpenMM supports, and how to pin it.

    ``"CUDA"``, ``"HIP"``: ``{}`` when the driver (``libcuda``, ``libamdhip64``) counts at
    least one device. ``"OpenCL"``: the ``OpenCLPlatformIndex`` and ``DeviceIndex`` of
    :func:`opencl_device` on the installed implementations. None otherwise (another name, a
    library that does not load, no device, only an unsupported OpenCL such as pocl). Asked
    once per process.
    """
    try:
        if name == "OpenCL":
            return opencl_device(_opencl_platforms())
        if name == "CUDA":
            lib = ctypes.CDLL("libcuda.so.1")
            count = ctypes.c_int(0)
            ok = lib.cuInit(0) == 0 and lib.cuDeviceGetCount(ctypes.byref(count)) == 0
            return {} if ok and count.value > 0 else None
        if name == "HIP":
            lib = ctypes.CDLL("libamdhip64.so")
            count = ctypes.c_int(0)
            ok = lib.hipGetDeviceCount(ctypes.byref(count)) == 0
            return {} if ok and count.value > 0 else None
    except (OSError, AttributeError):  # no such library or function: no device
        return None
    return None


def opencl_device(platforms) -> dict[str, str] | None:
    """The OpenCL device ``run.platform = "auto"`` may take, as OpenMM platform properties.

    Parameters
    ----------
    platforms : sequence of (str, sequence of (bool, bool))
        Per OpenCL platform, in OpenCL's order: its vendor and, per device (in the order of
        ``CL_DEVICE_TYPE_ALL``, OpenMM's ``DeviceIndex``), whether it is a GPU and whether it
        has double precision (``cl_khr_fp64``: the mixed precision knotmm asks for).

    Returns
    -------
    dict or None
        ``{"OpenCLPlatformIndex": j, "DeviceIndex": i}`` (strings) of the first GPU with
        double precision on a platform of a vendor OpenMM supports (:data:`OPENCL_VENDORS`);
        None if there is none (e.g. only pocl, a CPU implementation).
    """
    for j, (vendor, devices) in enumerate(platforms):
        if not str(vendor).startswith(OPENCL_VENDORS):
            continue
        for i, (gpu, fp64) in enumerate(devices):
            if gpu and fp64:
                return {"OpenCLPlatformIndex": str(j), "DeviceIndex": str(i)}
    return None


def _opencl_platforms() -> list[tuple[str, list[tuple[bool, bool]]]]:
    """The installed OpenCL platforms for :func:`opencl_device`, read through ``libOpenCL``."""
    cl = ctypes.CDLL("libOpenCL.so.1")
    u32, size, ptr = ctypes.c_uint32, ctypes.c_size_t, ctypes.c_void_p
    cl.clGetPlatformIDs.argtypes = [u32, ctypes.POINTER(ptr), ctypes.POINTER(u32)]
    cl.clGetPlatformInfo.argtypes = [ptr, u32, size, ptr, ctypes.POINTER(size)]
    cl.clGetDeviceIDs.argtypes = [ptr, ctypes.c_uint64, u32, ctypes.POINTER(ptr),
                                  ctypes.POINTER(u32)]
    cl.clGetDeviceInfo.argtypes = [ptr, u32, size, ptr, ctypes.POINTER(size)]

    def text(get, handle, key) -> str:
        length = size(0)
        if get(handle, key, 0, None, ctypes.byref(length)) != 0:
            return ""
        buffer = ctypes.create_string_buffer(length.value)
        if get(handle, key, length, ctypes.cast(buffer, ptr), None) != 0:
            return ""
        return buffer.value.decode("utf-8", "replace")

    count = u32(0)
    if cl.clGetPlatformIDs(0, None, ctypes.byref(count)) != 0 or count.value == 0:
        return []
    ids = (ptr * count.value)()
    if cl.clGetPlatformIDs(count.value, ids, None) != 0:
        return []
    out = []
    for platform in ids:
        n = u32(0)
        devices = []
        if cl.clGetDeviceIDs(platform, _CL_ALL, 0, None, ctypes.byref(n)) == 0 and n.value:
            handles = (ptr * n.value)()
            if cl.clGetDeviceIDs(platform, _CL_ALL, n.value, handles, None) == 0:
                for device in handles:
                    kind = ctypes.c_uint64(0)
                    cl.clGetDeviceInfo(device, _CL_DEVICE_TYPE, ctypes.sizeof(kind),
                                       ctypes.cast(ctypes.byref(kind), ptr), None)
                    fp64 = "cl_khr_fp64" in text(cl.clGetDeviceInfo, device, _CL_EXTENSIONS)
                    devices.append((bool(kind.value & _CL_GPU), fp64))
        out.append((text(cl.clGetPlatformInfo, platform, _CL_PLATFORM_VENDOR), devices))
    return out


# OpenCL constants (cl.h): CL_DEVICE_TYPE_ALL, CL_DEVICE_TYPE_GPU, CL_PLATFORM_VENDOR,
# CL_DEVICE_TYPE, CL_DEVICE_EXTENSIONS
_CL_ALL, _CL_GPU = 0xFFFFFFFF, 1 << 2
_CL_PLATFORM_VENDOR, _CL_DEVICE_TYPE, _CL_EXTENSIONS = 0x0903, 0x1000, 0x1030


def _plugin_has(plugin, integrator: str) -> bool:
    """The registry gives ``integrator`` a plugin counterpart, and the loaded plugin has it."""
    info = registry.REGISTRY.get(integrator)
    return info is not None and PLUGIN in info.engines and integrator in plugin.METHODS
