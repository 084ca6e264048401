"""copies_system: K copies of a system in one place, each seeing only itself.

Held to the System of one copy alone (``chain_system``, its steric term OpenMM's own
``NonbondedForce``): every copy's forces and energies are those of that copy alone, however
the copies overlap in space.
"""

from __future__ import annotations

import numpy as np
import openmm
import pytest

from knotmm.model.layout import ChainLayout
from knotmm.model.parameters import ChainModel
from knotmm.model.system import chain_system, copies_system, site_positions
from knotmm.shapes import torus_knot


def _forces(system, x, group=None):
    ctx = openmm.Context(system, openmm.VerletIntegrator(0.001),
                         openmm.Platform.getPlatformByName("Reference"))
    ctx.setPositions(x)
    kwargs = {} if group is None else {"groups": {group}}
    state = ctx.getState(getForces=True, getEnergy=True, **kwargs)
    return (state.getForces(asNumpy=True)._value,
            state.getPotentialEnergy().value_in_unit(openmm.unit.kilojoule_per_mole))


@pytest.mark.parametrize("sites", [False, True])
def test_each_copy_feels_only_itself(sites):
    model = ChainModel(segment_repulsion=sites)
    layout = ChainLayout((30, 16), (True, False))  # a ring and an open chain per copy
    rng = np.random.default_rng(4)
    arc = np.column_stack([np.arange(16.0), np.zeros(16), np.zeros(16)]) - [7.5, 0.0, 0.0]
    base = np.vstack([torus_knot(2, 3, 30), arc + [0.0, 0.0, 0.5]])
    copies = [base + 0.1 * rng.standard_normal(base.shape) for _ in range(3)]  # overlapping
    n, k = layout.n_beads, len(copies)
    big = copies_system(copies[0], model, layout, k)
    beads = np.vstack(copies)
    repeated = ChainLayout(layout.lengths * k, layout.closed * k)
    forces, energy = _forces(big, site_positions(beads, model, repeated))
    alone_energy = 0.0
    for c, x in enumerate(copies):
        f, e = _forces(chain_system(x, model, layout), site_positions(x, model, layout))
        alone_energy += e
        np.testing.assert_allclose(forces[c * n:(c + 1) * n], f[:n], rtol=1e-9, atol=1e-9)
    assert energy == pytest.approx(alone_energy, rel=1e-10)
    # the copies overlap: an ungrouped steric term would make them interact
    plain, _ = _forces(chain_system(beads, model, repeated), site_positions(beads, model,
                                                                          repeated))
    assert np.abs(plain[:n] - forces[:n]).max() > 1.0
