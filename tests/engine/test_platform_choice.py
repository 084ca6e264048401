"""``run.platform = "auto"``: the CPU, unless a device platform is real and usable (issue 30,
BUG-25).

The audit's case: 5000 beads took OpenCL, OpenMM printed "WARNING: Using an unsupported
OpenCL implementation. Results may be incorrect." (pocl, a CPU), and the run fell to the
Python engine because the plugin has no OpenCL kernel. The decision is tested here with fake
platform lists and fake OpenCL installations: no device is needed.
"""

from __future__ import annotations

import pytest

import knotmm.plugin
from knotmm.config import RunConfig
from knotmm.engine import engines
from knotmm.engine.engines import auto_platform, opencl_device
from knotmm.engine.simulation import Simulation

EVERYTHING = ["Reference", "CPU", "CUDA", "OpenCL"]


def _real(*names):
    """A device probe for which the platforms ``names`` are real (no properties needed)."""
    return lambda name: {} if name in names else None


def _no_probe(name):
    raise AssertionError(f"the {name} platform was probed, but it cannot be taken here")


@pytest.mark.parametrize("beads", [30, 5000])
def test_the_plugin_engine_gets_the_cpu_where_it_has_no_device_kernel(beads):
    host = ("Reference", "CPU")
    assert auto_platform(beads, "plugin", EVERYTHING, _no_probe, kernels=host) == ("CPU", {})


def test_the_plugin_engine_takes_a_real_device_it_has_a_kernel_on():
    kernels = ("Reference", "CPU", "OpenCL")
    # CUDA is real but the plugin has no kernel there; OpenCL is real and has one
    assert auto_platform(5000, "plugin", EVERYTHING, _real("CUDA", "OpenCL"),
                         kernels=kernels) == ("OpenCL", {})
    # the kernel alone does not make a device real (pocl: the probe finds none)
    assert auto_platform(5000, "plugin", EVERYTHING, _real(), kernels=kernels) == ("CPU", {})
    # small chains stay on the CPU without asking the probe
    assert auto_platform(engines.DEVICE_MIN_BEADS - 1, "plugin", EVERYTHING, _no_probe,
                         kernels=kernels) == ("CPU", {})


def test_the_plugin_platforms_are_asked_of_openmm():
    """Each platform of :func:`plugin_platforms` builds a Context with the plugin; every other
    loaded platform refuses one with OpenMM's missing-kernel error."""
    if not knotmm.plugin.available():
        pytest.skip(knotmm.plugin.load_error())
    import numpy as np
    import openmm

    have = engines.plugin_platforms()
    assert {"Reference", "CPU"} <= set(have)
    for name in engines.platform_names():
        system = openmm.System()
        for _ in range(2):
            system.addParticle(1.0)
        try:
            context = openmm.Context(system, knotmm.plugin.RPYIntegrator(0.01),
                                     openmm.Platform.getPlatformByName(name))
        except openmm.OpenMMException as exc:
            assert name not in have, f"{name}: {exc}"
            assert "kernel" in str(exc).lower()
        else:
            context.setPositions(np.array([[0.0, 0, 0], [1.0, 0, 0]]))
            assert name in have, f"{name}: a Context with the plugin builds there"
            del context


def test_an_opencl_that_openmm_calls_unsupported_is_never_taken():
    """The audit's machine: OpenCL is pocl on the CPU; the probe finds no real device."""
    assert auto_platform(5000, "python", ["Reference", "CPU", "OpenCL"], _real()) == ("CPU", {})


def test_the_python_engine_takes_a_real_device_for_a_large_chain():
    assert auto_platform(5000, "python", EVERYTHING, _real("CUDA", "OpenCL")) == ("CUDA", {})
    assert auto_platform(5000, "python", EVERYTHING, _real("OpenCL")) == ("OpenCL", {})
    pinned = {"OpenCLPlatformIndex": "1", "DeviceIndex": "0"}
    probe = {"OpenCL": pinned}.get
    assert auto_platform(5000, "python", EVERYTHING, probe) == ("OpenCL", pinned)
    # below the size where device force kernels pay off, and without a CPU platform
    assert auto_platform(engines.DEVICE_MIN_BEADS - 1, "python", EVERYTHING,
                         _no_probe) == ("CPU", {})
    assert auto_platform(5000, "python", ["Reference", "OpenCL"], _real()) == ("Reference", {})


def test_opencl_device_follows_openmms_own_list_of_supported_implementations():
    """``opencl_device`` reads (vendor, [(is_gpu, has_fp64), ...]) per OpenCL platform."""
    pocl = ("The pocl project", [(False, True)])
    nvidia = ("NVIDIA Corporation", [(True, True)])
    assert opencl_device([]) is None
    assert opencl_device([pocl]) is None
    assert opencl_device([("Portable Computing Language", [(True, True)])]) is None
    assert opencl_device([pocl, nvidia]) == {"OpenCLPlatformIndex": "1", "DeviceIndex": "0"}
    # a supported vendor, but only a CPU device, or a GPU without double precision (mixed)
    assert opencl_device([("Intel(R) Corporation", [(False, True)])]) is None
    assert opencl_device([("Advanced Micro Devices, Inc.", [(True, False)])]) is None
    intel = ("Intel(R) Corporation", [(False, True), (True, True)])
    assert opencl_device([intel]) == {"OpenCLPlatformIndex": "0", "DeviceIndex": "1"}


def test_the_probe_of_a_platform_that_is_not_a_device_is_none():
    assert engines.device_properties("CPU") is None
    assert engines.device_properties("Reference") is None


def test_the_opencl_probe_reads_the_installed_implementations(monkeypatch):
    probe = engines.device_properties.__wrapped__  # not the per-process cache
    pocl = [("The pocl project", [(False, True)])]
    monkeypatch.setattr(engines, "_opencl_platforms", lambda: pocl)
    assert probe("OpenCL") is None
    monkeypatch.setattr(engines, "_opencl_platforms",
                        lambda: pocl + [("NVIDIA Corporation", [(True, True)])])
    assert probe("OpenCL") == {"OpenCLPlatformIndex": "1", "DeviceIndex": "0"}

    def no_library():
        raise OSError("libOpenCL.so.1: cannot open shared object file")

    monkeypatch.setattr(engines, "_opencl_platforms", no_library)
    assert probe("OpenCL") is None


def _fake_machine(monkeypatch, names, probe):
    """OpenMM lists ``names``; ``probe`` says which device platforms are real; 10 beads
    already count as a large chain."""
    monkeypatch.setattr(engines, "platform_names", lambda: list(names))
    monkeypatch.setattr(engines, "device_properties", probe)
    monkeypatch.setattr(engines, "DEVICE_MIN_BEADS", 10)


def test_a_python_engine_run_on_a_machine_with_pocl_runs_on_the_cpu(monkeypatch):
    _fake_machine(monkeypatch, ["Reference", "CPU", "OpenCL"], _real())
    cfg = RunConfig.from_dict({"knot": {"beads": 30},
                               "run": {"engine": "python", "platform": "auto"}})
    sim = Simulation.from_config(cfg)
    assert (sim.platform_name, sim.engine) == ("CPU", "python")


@pytest.mark.skipif(not knotmm.plugin.available(), reason=str(knotmm.plugin.load_error()))
def test_auto_keeps_the_plugin_engine_and_its_cpu_beside_a_gpu_it_has_no_kernel_on(monkeypatch):
    """Before: a device platform was chosen first and took the run to the Python engine."""
    _fake_machine(monkeypatch, ["Reference", "CPU", "CUDA"], _real("CUDA"))
    monkeypatch.setattr(engines, "plugin_platforms", lambda: ("Reference", "CPU"))
    cfg = RunConfig.from_dict({"knot": {"beads": 30}, "run": {"platform": "auto"}})
    sim = Simulation.from_config(cfg)
    assert (sim.platform_name, sim.engine) == ("CPU", "plugin")
