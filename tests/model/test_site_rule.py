"""The bond-midpoint sites' one rule (issue 31): ``site_positions`` places them as OpenMM does.

``site_positions`` used to default to the sites of one ring, and ``Simulation.sync_context``
called it without the layout: an open chain got one site too many, a second ring the first
ring's closure. Now the layout is required, and its sites are those OpenMM computes from the
System's ``TwoParticleAverageSite`` definitions, bit for bit, for any mix of chains.
"""

from __future__ import annotations

import numpy as np
import openmm
import pytest

from knotmm.model.layout import ChainLayout
from knotmm.model.system import ChainModel, chain_system, site_positions

MIXED = ChainLayout((7, 5, 6), (True, False, True))


@pytest.mark.parametrize("platform", ["Reference", "CPU"])
def test_site_positions_are_openmm_virtual_sites_bit_for_bit(platform, rng):
    model = ChainModel(segment_repulsion=True)
    x = rng.normal(scale=3.0, size=(MIXED.n_beads, 3))
    system = chain_system(x, model, MIXED)
    n_bonds = 7 + 4 + 6
    assert system.getNumParticles() == MIXED.n_beads + n_bonds
    context = openmm.Context(system, openmm.VerletIntegrator(1e-3),
                             openmm.Platform.getPlatformByName(platform))
    context.setPositions(np.vstack([x, np.zeros((n_bonds, 3))]))
    context.computeVirtualSites()
    held = context.getState(getPositions=True).getPositions(asNumpy=True)._value
    placed = site_positions(x, model, MIXED)
    assert placed.shape == held.shape
    if platform == "Reference":  # double precision throughout: the same bits
        assert np.array_equal(placed, np.asarray(held))
    else:
        np.testing.assert_allclose(placed, held, rtol=0, atol=1e-5)


def test_the_sites_of_each_chain_are_its_own(rng):
    """Naively from the chain lengths: the open chain has no closing site."""
    x = rng.normal(size=(MIXED.n_beads, 3))
    sites = site_positions(x, ChainModel(segment_repulsion=True), MIXED)[MIXED.n_beads:]
    want = [0.5 * (x[i] + x[(i + 1) % 7]) for i in range(7)]
    want += [0.5 * (x[7 + i] + x[8 + i]) for i in range(4)]
    want += [0.5 * (x[12 + i] + x[12 + (i + 1) % 6]) for i in range(6)]
    np.testing.assert_allclose(sites, np.array(want), rtol=0, atol=1e-14)


def test_no_ring_is_assumed_without_a_layout(rng):
    x = rng.normal(size=(6, 3))
    model = ChainModel(segment_repulsion=True)
    with pytest.raises(TypeError):
        site_positions(x, model)  # type: ignore[call-arg]
    with pytest.raises(ValueError, match="hold 4 beads"):
        site_positions(x, model, ChainLayout((4,)))
    assert site_positions(x, ChainModel(), ChainLayout((3, 3))) is x  # no sites: no copy
