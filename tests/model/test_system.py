"""The OpenMM System is the model of docs/model.md: forces and energies of every term.

Everything is checked against tests/reference_model.py (numpy, written from docs/model.md) and
against central finite differences of the OpenMM energy. The Reference platform computes in
double precision and is checked tightly; the CPU platform (single-precision nonbonded
kernels) is checked with a looser tolerance.
"""

from __future__ import annotations

import numpy as np
import openmm
import pytest
import reference_model as rm
from openmm import unit

from knotmm.config import RunConfig
from knotmm.engine.simulation import Simulation
from knotmm.errors import ConfigError
from knotmm.model.system import FORCE_GROUPS, ChainModel, chain_system

TERMS = ("bond", "bend", "steric", "gravity")
RC = 2.0 ** (1.0 / 6.0)

#: Every parameter changed from the study's value.
OVERRIDES = dict(
    bond_length=0.7,
    bond_stiffness=80.0,
    bending_stiffness=2.5,
    lj_sigma=0.55,
    lj_epsilon=1.7,
    gravity=2.0,
)


def _context(x, model=None, platform="Reference"):
    system = chain_system(x, model)
    integrator = openmm.VerletIntegrator(0.001)
    context = openmm.Context(system, integrator, openmm.Platform.getPlatformByName(platform))
    context.setPositions(np.asarray(x, dtype=np.float64))
    return context, integrator


def _group_forces(context, group):
    state = context.getState(getForces=True, groups={group})
    return state.getForces(asNumpy=True).value_in_unit(unit.kilojoule_per_mole / unit.nanometer)


def _group_energy(context, group):
    state = context.getState(getEnergy=True, groups={group})
    return state.getPotentialEnergy().value_in_unit(unit.kilojoule_per_mole)


def _away_from_cutoff(x, sigma, gap=1e-4):
    """No non-bonded pair within ``gap`` of the steric cutoff (the energy jumps there)."""
    r = rm._nonbonded_distances(np.asarray(x))
    return bool(np.all(np.abs(r - RC * sigma) > gap))


def _configurations():
    rng = np.random.default_rng(7)
    out = {}
    while True:
        x = rm.random_ring(24, rng, noise=0.2)
        if (
            rm.min_nonbonded_distance(x) > 0.45
            and _away_from_cutoff(x, 0.5)
            and _away_from_cutoff(x, OVERRIDES["lj_sigma"])
        ):
            out["random"] = x
            break
    while True:
        x = rm.close_contact_ring(30, rng, contacts=8)
        if _away_from_cutoff(x, 0.5) and _away_from_cutoff(x, OVERRIDES["lj_sigma"]):
            out["close_contact"] = x
            break
    out["nearly_straight"] = rm.nearly_straight_ring(rng)
    return out


CONFIGS = _configurations()


def _model_kwargs(which):
    return {} if which == "study" else OVERRIDES


def test_configurations_are_what_they_claim():
    """Preconditions: the close-contact ring has pairs at 0.45-0.56 d, a 1-3 pair among them;
    the nearly straight ring bends by 1e-3..1e-2 rad at every bead."""
    x = CONFIGS["close_contact"]
    r = rm._nonbonded_distances(x)
    inside = np.argwhere(r < RC * 0.5)
    assert len(inside) >= 8
    assert r[np.isfinite(r)].min() >= 0.45
    assert any(j - i == 2 for i, j in inside), "a 1-3 pair must be inside the steric range"
    dev = rm.bend_deviation(CONFIGS["nearly_straight"])
    assert 1e-3 <= dev.min() and dev.max() <= 1e-2


@pytest.mark.parametrize("which", ["study", "overrides"])
@pytest.mark.parametrize("config", sorted(CONFIGS))
def test_forces_and_energies_per_group_match_numpy(config, which):
    """Reference platform: each force group equals the numpy model within double precision."""
    x = CONFIGS[config]
    kwargs = _model_kwargs(which)
    context, _ = _context(x, ChainModel(**kwargs))
    want_f = rm.forces(x, **kwargs)
    want_e = rm.energies(x, **kwargs)
    for term in TERMS:
        got = _group_forces(context, FORCE_GROUPS[term])
        scale = max(1.0, np.abs(want_f[term]).max())
        np.testing.assert_allclose(got, want_f[term], rtol=0, atol=1e-9 * scale, err_msg=term)
        e = _group_energy(context, FORCE_GROUPS[term])
        assert e == pytest.approx(want_e[term], rel=1e-9, abs=1e-10), term
    total = context.getState(getEnergy=True).getPotentialEnergy()
    assert total.value_in_unit(unit.kilojoule_per_mole) == pytest.approx(
        want_e["total"], rel=1e-9, abs=1e-10
    )
    if config == "close_contact":
        assert np.abs(want_f["steric"]).max() > 1.0  # the steric term is really exercised


@pytest.mark.parametrize("config", sorted(CONFIGS))
def test_forces_are_minus_gradient_of_openmm_energy(config, rng):
    """Central finite differences of each group's OpenMM energy (Reference platform)."""
    x = CONFIGS[config]
    context, _ = _context(x)
    flat = x.reshape(-1)
    coords = np.arange(flat.size) if flat.size <= 120 else rng.choice(flat.size, 60, False)
    h = 1e-6
    for term in TERMS:
        group = FORCE_GROUPS[term]
        forces = _group_forces(context, group).reshape(-1)
        fd = np.empty(len(coords))
        for k, c in enumerate(coords):
            e = {}
            for sign in (1, -1):
                y = flat.copy()
                y[c] += sign * h
                context.setPositions(y.reshape(-1, 3))
                e[sign] = _group_energy(context, group)
            fd[k] = -(e[1] - e[-1]) / (2 * h)
        context.setPositions(x)
        scale = max(1.0, np.abs(forces).max())
        np.testing.assert_allclose(forces[coords], fd, rtol=0, atol=2e-6 * scale, err_msg=term)


@pytest.mark.parametrize("config", sorted(CONFIGS))
def test_cpu_platform_matches_numpy_loosely(config):
    """The CPU platform (single-precision nonbonded) agrees to ~1e-5 of the largest force."""
    x = CONFIGS[config]
    context, _ = _context(x, platform="CPU")
    want_f = rm.forces(x)
    want_e = rm.energies(x)
    for term in TERMS:
        got = _group_forces(context, FORCE_GROUPS[term])
        scale = max(1.0, np.abs(want_f[term]).max())
        np.testing.assert_allclose(got, want_f[term], rtol=0, atol=1e-4 * scale, err_msg=term)
        e = _group_energy(context, FORCE_GROUPS[term])
        assert e == pytest.approx(want_e[term], rel=1e-5, abs=1e-5), term


def test_bend_forces_near_pi_identical_on_cpu_and_reference():
    """The bending force near pi: the CPU platform gives the Reference (double) result."""
    x = CONFIGS["nearly_straight"]
    ref, _ = _context(x, platform="Reference")
    cpu, _ = _context(x, platform="CPU")
    group = FORCE_GROUPS["bend"]
    want = rm.forces(x)["bend"]
    np.testing.assert_allclose(_group_forces(cpu, group), want, rtol=0, atol=1e-7)
    np.testing.assert_allclose(_group_forces(ref, group), want, rtol=0, atol=1e-10)


@pytest.mark.parametrize("platform", ["Reference", "CPU"])
def test_simulation_forces_and_energies_of_a_fallen_chain(trefoil40, platform):
    """Simulation.forces/energies see the true positions far from the origin (the Context
    is fed centred positions): forces are translation invariant, gravity energy is g sum z."""
    x = trefoil40 + np.array([3.0, -2.0, -4000.0])
    sim = Simulation(x, ChainModel(**OVERRIDES), platform=platform)
    want_f = rm.forces(x, **OVERRIDES)["total"]
    tol = 1e-9 if platform == "Reference" else 1e-4
    np.testing.assert_allclose(sim.forces(x), want_f, rtol=0, atol=tol * np.abs(want_f).max())
    got = sim.energies(x)
    want = rm.energies(x, **OVERRIDES)
    for term in (*TERMS, "total"):
        assert got[term] == pytest.approx(
            want[term], rel=1e-6 if platform == "CPU" else 1e-10, abs=1e-6
        ), term
    assert got["gravity"] == pytest.approx(2.0 * x[:, 2].sum(), rel=1e-12)


# -- the steric cutoff ----------------------------------------------------------------------
def _pair_ring(r, far=5.0):
    """Four beads: 0 and 2 at distance r along x (a non-bonded pair); 1 and 3 far away."""
    return np.array([[0.0, 0.0, 0.0], [r / 2, far, 0.0], [r, 0.0, 0.0], [r / 2, -far, 0.0]])


@pytest.mark.parametrize("sigma,eps", [(0.5, 0.25), (0.8, 1.7), (0.3, 4.0)])
def test_steric_cut_exactly_at_two_to_the_sixth_sigma(sigma, eps):
    model = ChainModel(lj_sigma=sigma, lj_epsilon=eps)
    rc = RC * sigma
    group = FORCE_GROUPS["steric"]
    # just inside: non-zero and equal to the published formula (no factor 4)
    for r in (rc * (1 - 1e-4), rc * (1 - 1e-2), 0.9 * sigma, sigma, 1.05 * sigma):
        context, _ = _context(_pair_ring(r), model)
        f = _group_forces(context, group)
        want = rm.steric_pair_force(r, sigma, eps)
        assert want > 0
        assert f[0, 0] == pytest.approx(-want, rel=1e-7)  # bead 0 pushed along -x
        assert f[2, 0] == pytest.approx(want, rel=1e-7)
        assert np.all(f[[1, 3]] == 0) and np.all(f[:, 1:] == 0)
        e = _group_energy(context, group)
        assert e == pytest.approx(eps * ((sigma / r) ** 12 - (sigma / r) ** 6), rel=1e-9)
    # the energy just inside is the published -eps/4, not a shifted 0
    context, _ = _context(_pair_ring(rc * (1 - 1e-9)), model)
    assert _group_energy(context, group) == pytest.approx(-eps / 4, rel=1e-6)
    # just outside: exactly zero
    for r in (np.nextafter(rc, np.inf), rc * (1 + 1e-9), rc * (1 + 1e-4), 2 * rc):
        context, _ = _context(_pair_ring(r), model)
        assert np.all(_group_forces(context, group) == 0.0), r
        assert _group_energy(context, group) == 0.0, r


def test_steric_force_curve_on_a_grid():
    """Across the whole range 0.4 d .. 0.7 d, bead 0's steric force is the formula."""
    group = FORCE_GROUPS["steric"]
    for r in np.linspace(0.4, 0.7, 61):
        context, _ = _context(_pair_ring(r))
        got = -_group_forces(context, group)[0, 0]
        assert got == pytest.approx(rm.steric_pair_force(r), rel=1e-9, abs=1e-12), r


def test_bonded_pairs_feel_no_steric_force():
    """A bond squeezed to 0.4 d (deep inside the steric range) gives no steric force."""
    x = np.array([[0.0, 0.0, 0.0], [0.4, 0.0, 0.0], [0.4, 3.0, 0.0], [0.0, 3.0, 0.0]])
    context, _ = _context(x)
    assert np.all(_group_forces(context, FORCE_GROUPS["steric"]) == 0.0)
    assert _group_energy(context, FORCE_GROUPS["steric"]) == 0.0
    assert _group_energy(context, FORCE_GROUPS["bond"]) == pytest.approx(
        2 * 25.0 * 0.2**2 + 2 * 25.0 * 2.4**2
    )


def test_next_nearest_neighbours_interact():
    """The 1-3 pair (i, i+2) is not excluded: fold bead 1 so that 0 and 2 are 0.5 d apart."""
    half = 0.25
    height = np.sqrt(0.6**2 - half**2)
    x = np.array(
        [[-half, 0.0, 0.0], [0.0, height, 0.0], [half, 0.0, 0.0], [0.0, -3.0, 0.0], [-2, -2, 0]]
    )
    context, _ = _context(x)
    f = _group_forces(context, FORCE_GROUPS["steric"])
    assert f[2, 0] == pytest.approx(rm.steric_pair_force(0.5), rel=1e-9)
    assert f[0, 0] == pytest.approx(-rm.steric_pair_force(0.5), rel=1e-9)


# -- parameters, names, topology ----------------------------------------------------------------
def test_every_override_from_a_run_file_reaches_the_system(rng):
    cfg = RunConfig.from_dict({"model": OVERRIDES})
    model = ChainModel.from_config(cfg)
    x = CONFIGS["close_contact"]
    context, _ = _context(x, model)
    want = rm.energies(x, **OVERRIDES)
    study = rm.energies(x)
    for term in TERMS:
        got = _group_energy(context, FORCE_GROUPS[term])
        assert got == pytest.approx(want[term], rel=1e-9, abs=1e-12), term
        assert got != pytest.approx(study[term], rel=1e-3), f"{term} ignores its override"


def test_gravity_override_scales_the_force(trefoil40):
    for g in (0.0, 1.0, 3.5):
        context, _ = _context(trefoil40, ChainModel(gravity=g))
        f = _group_forces(context, FORCE_GROUPS["gravity"])
        np.testing.assert_array_equal(f[:, :2], 0.0)
        np.testing.assert_allclose(f[:, 2], -g, rtol=1e-15)


def test_forces_are_named_and_grouped():
    system = chain_system(np.zeros((6, 3)) + np.arange(6)[:, None])
    named = {f.getName(): f for f in system.getForces()}
    assert set(named) == set(TERMS)
    assert len(system.getForces()) == 4
    assert isinstance(named["bond"], openmm.HarmonicBondForce)
    assert isinstance(named["bend"], openmm.CustomAngleForce)
    assert isinstance(named["steric"], openmm.NonbondedForce)
    assert isinstance(named["gravity"], openmm.CustomExternalForce)
    groups = {name: f.getForceGroup() for name, f in named.items()}
    assert groups == dict(FORCE_GROUPS)
    assert len(set(groups.values())) == 4
    assert named["bond"].getNumBonds() == 6
    assert named["bend"].getNumAngles() == 6
    assert system.getNumParticles() == 6


@pytest.mark.parametrize(
    "bad,match",
    [
        (np.zeros((3, 3)), "at least 4"),
        (np.zeros((5, 2)), "shape"),
        (np.full((5, 3), np.nan), "NaN"),
    ],
)
def test_chain_system_rejects_bad_positions(bad, match):
    with pytest.raises(ConfigError, match=match):
        chain_system(bad)
