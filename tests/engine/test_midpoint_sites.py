"""Bond-midpoint sites (``model.segment_repulsion``) of any layout, not only of one ring (issue 31).

The Context's sites are checked against midpoints computed here from the chain lengths alone
(bead ``start + i`` bonded to ``start + i + 1``, and a ring's last bead to its first), and the
steric energy of a small open chain with sites against a pair-by-pair sum written here from
the truncated Lennard-Jones form of ``docs/model.md``.
"""

from __future__ import annotations

import numpy as np
import pytest
from engine_platforms import ENGINE_PLATFORMS, placement

from knotmm.dynamics.deterministic import Heun
from knotmm.engine.simulation import Simulation
from knotmm.model.layout import ChainLayout
from knotmm.model.system import ChainModel


def naive_bonds(chains) -> list[tuple[int, int]]:
    """Bonded bead pairs of ``chains`` ((beads, closed) per chain), chain by chain."""
    out, start = [], 0
    for n, closed in chains:
        out += [(start + i, start + i + 1) for i in range(n - 1)]
        if closed:
            out.append((start + n - 1, start))
        start += n
    return out


def context_positions(sim) -> np.ndarray:
    state = sim.context.getState(getPositions=True)
    return np.asarray(state.getPositions(asNumpy=True)._value, dtype=np.float64)


def assert_sites_are_midpoints(sim, chains) -> None:
    """Every site the Context holds is the midpoint of its bond (in the bonds' order)."""
    held = context_positions(sim)
    bonds = naive_bonds(chains)
    n = sum(c[0] for c in chains)
    assert held.shape == (n + len(bonds), 3)
    beads = held[:n]
    want = np.array([0.5 * (beads[i] + beads[j]) for i, j in bonds])
    np.testing.assert_allclose(held[n:], want, rtol=0, atol=1e-12)


def open_rod(n: int, rng) -> np.ndarray:
    """An open, slightly bent rod of ``n`` beads 0.6 d apart (no steric contacts)."""
    x = np.c_[0.6 * np.arange(n), 0.05 * np.sin(np.arange(n)), np.zeros(n)]
    return x + rng.normal(scale=0.01, size=x.shape)


def two_rings(rng) -> np.ndarray:
    """Two rings of 10 beads side by side, 3 d apart (bonds about 0.6 d)."""
    phi = 2 * np.pi * np.arange(10) / 10
    ring = np.c_[np.cos(phi), np.sin(phi), np.zeros(10)]
    x = np.vstack([ring, ring + [3.0, 0.0, 0.0]])
    return x + rng.normal(scale=0.01, size=x.shape)


@pytest.mark.parametrize(("engine", "platform"), ENGINE_PLATFORMS)
def test_an_open_filament_with_sites_runs(engine, platform, rng):
    chains = [(8, False)]
    layout = ChainLayout((8,), (False,))
    sim = Simulation(open_rod(8, rng), ChainModel(segment_repulsion=True), Heun(0.01),
                     engine=engine, layout=layout, **placement(platform))
    assert sim.system.getNumParticles() == 8 + 7
    assert_sites_are_midpoints(sim, chains)
    sim.run(0.2)
    assert sim.currentStep >= 19 and np.all(np.isfinite(sim.positions))
    sim.sync_context()
    assert_sites_are_midpoints(sim, chains)
    assert np.isfinite(sim.energies()["steric"])


@pytest.mark.parametrize(("engine", "platform"), ENGINE_PLATFORMS)
def test_sites_of_two_rings_after_sync(engine, platform, rng):
    """The sites of the second ring sat on the first ring's beads (site 19 was 10 d off)."""
    chains = [(10, True), (10, True)]
    layout = ChainLayout((10, 10))
    sim = Simulation(two_rings(rng), ChainModel(segment_repulsion=True), Heun(0.01),
                     engine=engine, layout=layout, **placement(platform))
    assert_sites_are_midpoints(sim, chains)
    sim.run(0.05)
    sim.sync_context()
    assert_sites_are_midpoints(sim, chains)
    held = context_positions(sim)
    # the second ring's closing bond (beads 19-10) has its site at particle 20 + 19
    np.testing.assert_allclose(held[39], 0.5 * (held[19] + held[10]), atol=1e-12)


def _wca(r: float, eps: float = 0.25, sig: float = 0.5) -> float:
    if r >= 2 ** (1 / 6) * sig:
        return 0.0
    return eps * ((sig / r) ** 12 - (sig / r) ** 6)


def naive_open_steric(x: np.ndarray) -> tuple[float, int]:
    """Steric energy of one open chain with bond-midpoint sites, pair by pair.

    Beads ``i`` (0..n-1) and sites ``k`` (0..n-2, the midpoint of beads ``k``, ``k + 1``).
    Excluded: bonded beads; a site and the beads ``k - 1 .. k + 2``; neighbouring sites.
    Returns the energy and the number of pairs inside the range.
    """
    n = len(x)
    sites = [0.5 * (x[k] + x[k + 1]) for k in range(n - 1)]
    energy, felt = 0.0, 0
    pairs = []
    for i in range(n):
        for j in range(i + 2, n):
            pairs.append((x[i], x[j]))
    for k in range(n - 1):
        for i in range(n):
            if not k - 1 <= i <= k + 2:
                pairs.append((sites[k], x[i]))
        for m in range(k + 2, n - 1):
            pairs.append((sites[k], sites[m]))
    for a, b in pairs:
        e = _wca(float(np.linalg.norm(a - b)))
        energy += e
        felt += e != 0.0
    return energy, felt


def test_steric_energy_of_an_open_chain_with_sites_is_the_naive_sum(rng):
    """A hairpin: two strands of 4 beads 0.53 d apart, so beads, sites, and beads and sites
    of the two strands are inside each other's range."""
    top = np.c_[np.arange(4.0), np.zeros(4), np.zeros(4)]
    bottom = np.c_[np.arange(3.0, -1.0, -1.0), np.full(4, 0.53), np.zeros(4)]
    x = np.vstack([top, bottom]) + rng.normal(scale=0.01, size=(8, 3))
    want, felt = naive_open_steric(x)
    assert felt == 6 and want != 0.0  # 3 bead pairs, 3 site pairs
    sim = Simulation(x, ChainModel(segment_repulsion=True), Heun(0.01), platform="Reference",
                     engine="python", layout=ChainLayout((8,), (False,)))
    assert sim.energies()["steric"] == pytest.approx(want, rel=1e-10, abs=1e-12)
    plain = Simulation(x, ChainModel(), Heun(0.01), platform="Reference", engine="python",
                       layout=ChainLayout((8,), (False,)))
    assert plain.energies()["steric"] != pytest.approx(want, rel=1e-3)  # the sites count
