"""build_system(cfg): a run file's start as OpenMM objects, checked against the numpy model."""

from __future__ import annotations

import numpy as np
import openmm
import pytest
import reference_model as rm
from openmm import unit

from knotmm.config import RunConfig
from knotmm.engine.simulation import Simulation
from knotmm.model.system import ChainModel
from knotmm.shapes import build_system, build_template

MODEL = dict(bond_length=0.65, bond_stiffness=70.0, bending_stiffness=3.0, lj_sigma=0.52,
             lj_epsilon=0.4, gravity=1.5)


def _forces(system, positions):
    integrator = openmm.VerletIntegrator(0.001)
    context = openmm.Context(system, integrator, openmm.Platform.getPlatformByName("Reference"))
    context.setPositions(positions)
    state = context.getState(getForces=True)
    return state.getForces(asNumpy=True).value_in_unit(unit.kilojoule_per_mole / unit.nanometer)


@pytest.mark.parametrize(
    "tables",
    [
        {"knot": {"beads": 60}},
        {"knot": {"beads": 70, "perturbation": 0.05, "seed": 4}, "model": MODEL},
        {"knot": {"kind": "knotinfo", "name": "4_1", "beads": 110}},
    ],
)
def test_build_system_forces_are_the_model_and_the_simulation(tables):
    cfg = RunConfig.from_dict(tables)
    topology, system, positions = build_system(cfg)
    n = cfg["knot.beads"]
    assert positions.shape == (n, 3) and positions.dtype == np.float64
    assert topology.getNumAtoms() == system.getNumParticles() == n
    assert sorted(f.getName() for f in system.getForces()) == ["bend", "bond", "gravity", "steric"]
    np.testing.assert_array_equal(positions, build_template(cfg).positions)
    got = _forces(system, positions)
    want = rm.forces(positions, **tables.get("model", {}))["total"]
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9)
    sim = Simulation(positions, ChainModel.from_config(cfg), platform="Reference")
    np.testing.assert_allclose(sim.forces(positions), want, rtol=1e-9, atol=1e-9)


def test_build_system_with_segment_repulsion_lists_the_midpoints():
    cfg = RunConfig.from_dict({"knot": {"beads": 50}, "model": {"segment_repulsion": True}})
    topology, system, positions = build_system(cfg)
    assert topology.getNumAtoms() == 50 and system.getNumParticles() == 100
    x = positions[:50]
    np.testing.assert_allclose(positions[50:], 0.5 * (x + np.roll(x, -1, axis=0)))
    assert all(system.isVirtualSite(i) for i in range(50, 100))


def test_public_name_is_this_builder():
    import knotmm

    assert knotmm.build_system is build_system
