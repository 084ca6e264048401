"""Several chains in one fluid (rings and an open filament) against the naive model of
tests/reference_model.py: energies and forces per term, velocities of both engines, a 4 tau_d
trajectory against a naive Heun integration written here, and the symmetry of a mirrored pair.
"""

from __future__ import annotations

import numpy as np
import pytest
import reference_model as rm
from engine_platforms import ENGINE_PLATFORMS, engine_velocity, placement, trajectory_tolerance

from knotmm.dynamics.deterministic import Heun
from knotmm.engine.simulation import Simulation
from knotmm.model.layout import ChainLayout
from knotmm.model.system import FORCE_GROUPS, ChainModel, chain_system

CHAINS = [(12, True), (10, True), (8, False)]
LAYOUT = ChainLayout(tuple(n for n, _ in CHAINS), tuple(c for _, c in CHAINS))


def three_chains(rng) -> np.ndarray:
    """A ring of 12, a ring of 10 and an open rod of 8, close enough that beads of different
    chains are inside the steric range (0.561 d) of each other."""
    a = rm.circle(12)  # radius 1.16 d
    b = rm.circle(10) + [2.1, 0.0, 0.35]  # radius 0.97 d: its bead 5 is 0.44 d from a's 0
    rod = np.c_[np.zeros(8), 0.6 * np.arange(8) - 2.1, np.full(8, -0.45)]  # under a
    x = np.vstack([a, b, rod]) + rng.normal(scale=0.03, size=(30, 3))
    return x


def inter_chain_contacts(x) -> int:
    owner = LAYOUT.chain_of_bead()
    r = np.linalg.norm(x[:, None] - x[None], axis=-1)
    other = owner[:, None] != owner[None, :]
    return int(np.sum((r < 2 ** (1 / 6) * 0.5) & other) // 2)


def test_layout_bonds_and_angles_are_the_naive_topology():
    bonds, triples = rm.chain_topology(CHAINS)
    assert sorted(map(tuple, LAYOUT.bonds().tolist())) == sorted(bonds)
    assert sorted(map(tuple, LAYOUT.angles().tolist())) == sorted(triples)
    assert ChainLayout.from_record(LAYOUT.to_record(), 30) == LAYOUT


def _group_energy(context, group) -> float:
    return context.getState(getEnergy=True, groups={group}).getPotentialEnergy()._value


def test_energies_and_forces_per_term_match_the_naive_model(rng):
    import openmm

    x = three_chains(rng)
    assert inter_chain_contacts(x) >= 2
    system = chain_system(x, ChainModel(), LAYOUT)
    context = openmm.Context(system, openmm.VerletIntegrator(1e-3),
                             openmm.Platform.getPlatformByName("Reference"))
    context.setPositions(x - x.mean(axis=0))
    y = x - x.mean(axis=0)
    want_e = rm.energies(y, CHAINS)
    want_f = rm.forces(y, CHAINS)
    for term in ("bond", "bend", "steric"):
        group = FORCE_GROUPS[term]
        assert _group_energy(context, group) == pytest.approx(want_e[term], rel=1e-10, abs=1e-12)
        f = context.getState(getForces=True, groups={group}).getForces(asNumpy=True)._value
        np.testing.assert_allclose(f, want_f[term], rtol=0,
                                   atol=1e-9 * max(1.0, np.abs(want_f[term]).max()))
    assert want_e["steric"] > 0  # the contacts between chains are felt


@pytest.mark.parametrize(("engine", "platform"), ENGINE_PLATFORMS)
def test_velocities_are_naive_rpy_times_the_forces_of_all_chains(rng, engine, platform):
    x = three_chains(rng)
    want = rm.rpy_velocities(x, rm.forces(x, CHAINS)["total"])
    got, rel = engine_velocity(x, engine, platform, layout=LAYOUT, max_bond_length=100.0)
    np.testing.assert_allclose(got, want, rtol=0, atol=rel * np.abs(want).max())


def rpy_all_pairs(x, f):
    """``v = M F`` with the RPY tensor of docs/model.md (d = mu0 = 1) for all pairs at once:
    the two branches (r >= d, r < d) written out with numpy broadcasting."""
    r = x[:, None, :] - x[None, :, :]
    dist = np.linalg.norm(r, axis=-1)
    np.fill_diagonal(dist, 1.0)
    rr = r[..., :, None] * r[..., None, :] / dist[..., None, None] ** 2
    eye = np.eye(3)
    far = 3 / (8 * dist)[..., None, None] * ((1 + 1 / (6 * dist**2))[..., None, None] * eye
                                             + (1 - 1 / (2 * dist**2))[..., None, None] * rr)
    near = (1 - 9 * dist / 16)[..., None, None] * eye + (3 * dist / 16)[..., None, None] * rr
    m = np.where((dist >= 1.0)[..., None, None], far, near)
    m[np.arange(len(x)), np.arange(len(x))] = eye
    return np.einsum("ijab,jb->ia", m, f)


def test_the_all_pairs_rpy_is_the_reference_double_loop(rng):
    x, f = three_chains(rng), rng.normal(size=(30, 3))
    np.testing.assert_allclose(rpy_all_pairs(x, f), rm.rpy_velocities(x, f), rtol=1e-12,
                               atol=1e-12)


def naive_heun(x, h, steps, chains):
    def v(y):
        return rpy_all_pairs(y, rm.forces(y, chains)["total"])

    for _ in range(steps):
        k1 = v(x)
        k2 = v(x + h * k1)
        x = x + 0.5 * h * (k1 + k2)
    return x


@pytest.fixture(scope="module")
def naive_four_tau_d():
    """The start and the naive Heun integration (h = 0.01, 400 steps), computed once."""
    x = three_chains(np.random.default_rng(7))
    return x, naive_heun(x, 0.01, 400, CHAINS)


@pytest.mark.parametrize(("engine", "platform"), ENGINE_PLATFORMS)
def test_four_tau_d_of_two_rings_and_a_rod_follow_a_naive_heun_integration(
        naive_four_tau_d, engine, platform):
    x, want = naive_four_tau_d
    h, steps = 0.01, 400
    sim = Simulation(x, engine=engine, integrator=Heun(h), layout=LAYOUT, **placement(platform))
    assert (sim.engine, sim.platform_name) == (engine, platform)
    sim.step(steps)
    assert sim.time == pytest.approx(4.0)
    np.testing.assert_allclose(sim.positions, want, rtol=0,
                               atol=trajectory_tolerance(platform))
    assert np.abs(want - x).max() > 1.0  # it fell and moved: not a trivial comparison


def test_a_mirrored_pair_keeps_its_symmetry_and_falls_faster_than_one_ring(trefoil40):
    """Ring B is ring A mirrored through the plane x = 0: gravity and the model are
    symmetric under x -> -x, so B stays A's mirror image. Two rings side by side drag fluid
    along for each other: the pair falls faster than one ring alone."""
    a = trefoil40 + [-3.2, 0.0, 0.0]
    b = a * [-1.0, 1.0, 1.0]
    pair = ChainLayout((40, 40))
    sim = Simulation(np.vstack([a, b]), platform="Reference", integrator=Heun(0.01),
                     layout=pair)
    v0 = sim.velocity(sim.positions)[:, 2].mean()
    alone = Simulation(trefoil40, platform="Reference", integrator=Heun(0.01))
    v_alone = alone.velocity(trefoil40)[:, 2].mean()
    assert v0 < v_alone < 0 and v0 / v_alone > 1.1  # measured 1.26, the rings 2.67 d apart
    z0 = sim.positions[:, 2].mean()
    sim.step(200)
    alone.step(200)
    ya, yb = sim.positions[:40], sim.positions[40:]
    np.testing.assert_allclose(yb, ya * [-1.0, 1.0, 1.0], rtol=0, atol=1e-9)
    fall_pair = z0 - sim.positions[:, 2].mean()
    fall_alone = trefoil40[:, 2].mean() - alone.positions[:, 2].mean()
    assert fall_pair > 1.1 * fall_alone > 0
