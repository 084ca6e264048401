"""The plugin inside openmm.app.Simulation with OpenMM's own reporters, and on the CPU platform."""

from __future__ import annotations

import csv

import mdtraj
import numpy as np
import openmm
import openmm.app as app
import pytest
from plugin_helpers import plugin_context, positions_of

from knotmm.model.system import chain_system as build_system
from knotmm.model.topology import bead_topology as build_topology
from knotmm.plugin import RPYIntegrator
from knotmm.shapes import torus_knot


@pytest.fixture(scope="module")
def chain():
    return torus_knot(2, 3, 40)


def test_app_simulation_with_reporters(chain, tmp_path):
    system = build_system(chain)
    topology = build_topology(len(chain))
    integ = RPYIntegrator(0.01, "heun")
    sim = app.Simulation(topology, system, integ, openmm.Platform.getPlatformByName("Reference"))
    sim.context.setPositions(chain)
    log, dcd, chk = tmp_path / "log.csv", tmp_path / "traj.dcd", tmp_path / "run.chk"
    sim.reporters.append(app.StateDataReporter(str(log), 10, step=True, time=True,
                                               potentialEnergy=True))
    sim.reporters.append(app.DCDReporter(str(dcd), 10))
    sim.reporters.append(app.CheckpointReporter(str(chk), 25))
    sim.step(50)

    assert sim.currentStep == 50
    with open(log) as fh:
        rows = list(csv.reader(fh))[1:]
    assert [int(r[0]) for r in rows] == [10, 20, 30, 40, 50]
    np.testing.assert_allclose([float(r[1]) for r in rows], [0.1, 0.2, 0.3, 0.4, 0.5],
                               rtol=1e-12)
    # the last frame of the DCD (written in Angstrom, read back in nm) is the Context's state
    traj = mdtraj.load_dcd(str(dcd), top=mdtraj.Topology.from_openmm(topology))
    assert traj.n_frames == 5
    final = positions_of(sim.context)
    np.testing.assert_allclose(traj.xyz[-1], final, atol=1e-4)
    assert np.abs(final - chain).max() > 1.0

    # the CheckpointReporter's file (step 50) continues like the live run
    sim.step(10)
    live = positions_of(sim.context)
    sim.loadCheckpoint(str(chk))
    assert sim.context.getState().getStepCount() == 50
    sim.reporters.clear()
    sim.step(10)
    np.testing.assert_array_equal(positions_of(sim.context), live)


def test_app_simulation_adaptive_save_and_load_checkpoint(chain, tmp_path):
    system = build_system(chain)
    sim = app.Simulation(build_topology(len(chain)), system, RPYIntegrator(0.01, "rk23"),
                         openmm.Platform.getPlatformByName("Reference"))
    sim.context.setPositions(chain)
    sim.step(10)
    sim.saveCheckpoint(str(tmp_path / "a.chk"))
    sim.step(10)
    live, live_time = positions_of(sim.context), sim.context.getState().getTime()
    sim.loadCheckpoint(str(tmp_path / "a.chk"))
    sim.step(10)
    np.testing.assert_array_equal(positions_of(sim.context), live)
    assert sim.context.getState().getTime() == live_time


@pytest.mark.parametrize("method", ["heun", "rk23"])
def test_cpu_platform_follows_reference(method):
    """The CPU platform's steric forces are single precision; the runs agree to 1e-5 d.

    A thin torus (minor radius 0.25 d) puts strands 0.5 d apart, inside the steric range, so
    the CPU platform's float nonbonded kernel takes part (measured differences 1e-8 to 2e-7 d).
    """
    chain = torus_knot(2, 3, 40, minor_radius=0.25)
    out = {}
    for platform in ("Reference", "CPU"):
        integ = RPYIntegrator(0.01, method)
        ctx = plugin_context(build_system(chain), chain, integ, platform)
        assert ctx.getPlatform().getName() == platform
        integ.stepTo(1.0)
        out[platform] = positions_of(ctx)
    diff = np.abs(out["CPU"] - out["Reference"]).max()
    assert diff < 1e-5, diff
    assert np.abs(out["Reference"] - chain).max() > 1.0


def test_default_platform_is_one_with_the_kernel(chain):
    """Without a platform OpenMM picks the fastest one that has the plugin's kernel (on a
    machine with OpenCL, the OpenCL platform once the plugin runs there, as OpenMM does for
    its own integrators)."""
    from knotmm.engine.engines import plugin_platforms

    sim = app.Simulation(build_topology(len(chain)), build_system(chain), RPYIntegrator(0.01))
    fastest = max((openmm.Platform.getPlatformByName(n) for n in plugin_platforms()),
                  key=lambda p: p.getSpeed())
    assert sim.context.getPlatform().getName() == fastest.getName()
    sim.context.setPositions(chain)
    sim.step(3)
    assert sim.currentStep == 3


def test_xml_serialization_round_trip(chain, tmp_path):
    """XmlSerializer keeps the settings; app.Simulation accepts the integrator as a file."""
    original = RPYIntegrator(0.02, "rk23", 1e-5, max_step=0.05)
    xml = openmm.XmlSerializer.serialize(original)
    assert 'method="rk23"' in xml
    path = tmp_path / "integrator.xml"
    path.write_text(xml)
    runs = []
    for integ in (original, str(path)):
        sim = app.Simulation(build_topology(len(chain)), build_system(chain), integ,
                             openmm.Platform.getPlatformByName("Reference"))
        sim.context.setPositions(chain)
        sim.step(20)
        runs.append(positions_of(sim.context))
    # the deserialised object is an openmm.Integrator (OpenMM's Python layer knows no
    # subclass of ours), but it drives the same C++ integrator
    np.testing.assert_array_equal(runs[0], runs[1])
