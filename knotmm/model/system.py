"""Build the OpenMM ``System`` and ``Topology`` of a closed bead-spring chain.

The chain of ``N`` beads is a ring: bead ``i`` is bonded to ``i + 1`` and bead ``N - 1`` to
bead ``0``. Four named forces, each in its own force group (:data:`FORCE_GROUPS`), make up
the model of ``model.md`` (energies in F0 d, lengths in d, read by OpenMM as kJ/mol and nm):

========== ============================================ =========================
name       energy                                       OpenMM force
========== ============================================ =========================
bond       sum_bonds B/2 (l - l0)^2                     ``HarmonicBondForce``
bend       sum_beads A/2 (phi - pi)^2                   ``CustomAngleForce``
steric     eps ((sigma/r)^12 - (sigma/r)^6), r < rc     ``NonbondedForce``
gravity    sum_beads g z                                ``CustomExternalForce``
========== ============================================ =========================

with ``rc = 2**(1/6) sigma``. The steric term is the published form (no factor 4): it is
an OpenMM Lennard-Jones term with ``epsilon_openmm = eps / 4``, truncated at ``rc``
without a switching function, so its force vanishes exactly at the cutoff (the energy
jumps by ``eps/4``, as in the published model). It acts between every pair of beads that is
not bonded; bonded pairs are exceptions with zero interaction. All charges are zero.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import openmm
import openmm.app

from knotmm.errors import ConfigError
from knotmm.units import LJ_CUTOFF_FACTOR

__all__ = [
    "FORCE_GROUPS",
    "ChainModel",
    "build_system",
    "build_topology",
    "ring_bonds",
]

#: Force name -> force group. Per-term energies are read by group.
FORCE_GROUPS = {"bond": 0, "bend": 1, "steric": 2, "gravity": 3}


@dataclass(frozen=True)
class ChainModel:
    """Parameters of the bead-spring model, in model units. Defaults: the study's values.

    Attributes
    ----------
    bond_length : float
        Equilibrium bond length ``l0``, in d.
    bond_stiffness : float
        ``B``, in F0/d.
    bending_stiffness : float
        ``A``, in F0 d (the equilibrium angle is pi: a straight chain).
    lj_sigma : float
        ``sigma`` of the truncated Lennard-Jones term, in d.
    lj_epsilon : float
        ``eps`` of the truncated Lennard-Jones term (no factor 4), in F0 d.
    gravity : float
        Force on each bead along ``-z``, in F0.
    segment_repulsion : bool
        Off by default (the study's model). When on, every bond carries a massless steric
        site at its midpoint (an OpenMM virtual site) that repels beads and other midpoints
        with the same truncated Lennard-Jones term, so that along the chain a steric site
        sits every ``l0/2``. Two strands crossing at any point then meet sites at most
        about ``0.21 d`` apart, a barrier of thousands of F0 d: strands cannot pass through
        each other. Sites are excluded from their own two beads, their neighbouring beads
        and the neighbouring midpoints, so the local chain mechanics is unchanged.
    """

    bond_length: float = 0.6
    bond_stiffness: float = 50.0
    bending_stiffness: float = 5.0
    lj_sigma: float = 0.5
    lj_epsilon: float = 0.25
    gravity: float = 1.0
    segment_repulsion: bool = False

    @property
    def steric_range(self) -> float:
        """Cutoff ``2**(1/6) sigma`` of the steric term, in d."""
        return LJ_CUTOFF_FACTOR * self.lj_sigma

    @classmethod
    def from_config(cls, cfg) -> ChainModel:
        """Take the ``[model]`` table of a :class:`knotmm.config.RunConfig`."""
        values = cfg.table("model")
        flags = {"segment_repulsion"}
        kwargs = {k: (bool(v) if k in flags else float(v)) for k, v in values.items()
                  if k in cls.__dataclass_fields__}
        return cls(**kwargs)


def ring_bonds(n_beads: int) -> np.ndarray:
    """Bonded pairs of a ring: ``(i, i+1)`` and the closure ``(N-1, 0)``.

    Returns
    -------
    ndarray, shape (n_beads, 2), int
    """
    i = np.arange(n_beads)
    return np.stack([i, (i + 1) % n_beads], axis=1)


def _check_positions(positions) -> np.ndarray:
    pos = np.asarray(positions, dtype=np.float64)
    if pos.ndim != 2 or pos.shape[1] != 3:
        raise ConfigError(f"positions: expected shape (n_beads, 3), got {pos.shape}")
    if pos.shape[0] < 4:
        raise ConfigError(f"positions: a ring needs at least 4 beads, got {pos.shape[0]}")
    if not np.all(np.isfinite(pos)):
        raise ConfigError("positions: contain NaN or infinite values")
    return pos


def bond_force(n_beads: int, model: ChainModel) -> openmm.HarmonicBondForce:
    """Harmonic bonds ``B/2 (l - l0)^2`` around the ring (OpenMM's k is ``B``)."""
    force = openmm.HarmonicBondForce()
    for i, j in ring_bonds(n_beads):
        force.addBond(int(i), int(j), model.bond_length, model.bond_stiffness)
    force.setName("bond")
    return force


def bend_force(n_beads: int, model: ChainModel) -> openmm.CustomAngleForce:
    """Harmonic bending ``A/2 (phi - pi)^2`` at every bead of the ring.

    A ``CustomAngleForce`` with the global parameter ``bending_stiffness`` (= A): on the CPU
    platform it costs about half of what ``HarmonicAngleForce`` costs for the same angles
    (see benchmarks/README.md), and it gives the same forces.
    """
    force = openmm.CustomAngleForce(f"0.5*bending_stiffness*(theta - {np.pi!r})^2")
    force.addGlobalParameter("bending_stiffness", model.bending_stiffness)
    for i in range(n_beads):
        force.addAngle((i - 1) % n_beads, i, (i + 1) % n_beads, [])
    force.setName("bend")
    return force


def steric_force(n_beads: int, model: ChainModel) -> openmm.NonbondedForce:
    """Truncated Lennard-Jones ``eps((sigma/r)^12 - (sigma/r)^6)`` for ``r < 2^(1/6) sigma``.

    Every non-bonded pair interacts (next-nearest neighbours included); bonded pairs are
    zeroed exceptions.
    """
    force = openmm.NonbondedForce()
    force.setNonbondedMethod(openmm.NonbondedForce.CutoffNonPeriodic)
    force.setCutoffDistance(model.steric_range)
    force.setUseSwitchingFunction(False)
    force.setUseDispersionCorrection(False)
    force.setReactionFieldDielectric(1.0)
    n_sites = 2 * n_beads if model.segment_repulsion else n_beads
    for _ in range(n_sites):
        force.addParticle(0.0, model.lj_sigma, model.lj_epsilon / 4.0)
    for i, j in ring_bonds(n_beads):
        force.addException(int(i), int(j), 0.0, model.lj_sigma, 0.0)
    if model.segment_repulsion:
        # midpoint site of bond k is particle n + k; it sits between beads k and k+1
        for k in range(n_beads):
            site = n_beads + k
            for bead in (k - 1, k, k + 1, k + 2):
                force.addException(site, bead % n_beads, 0.0, model.lj_sigma, 0.0)
            force.addException(site, n_beads + (k + 1) % n_beads, 0.0, model.lj_sigma, 0.0)
    force.setName("steric")
    return force


def gravity_force(n_beads: int, model: ChainModel) -> openmm.CustomExternalForce:
    """Constant force ``g`` along ``-z`` on every bead (energy ``g z``)."""
    force = openmm.CustomExternalForce("gravity_force*z")
    force.addGlobalParameter("gravity_force", model.gravity)
    for i in range(n_beads):
        force.addParticle(i, [])
    force.setName("gravity")
    return force


def build_system(positions, model: ChainModel | None = None) -> openmm.System:
    """The OpenMM System of a closed chain.

    Parameters
    ----------
    positions : array_like, shape (n_beads, 3), in d
        Only the number of beads is taken from it (and it is checked to be finite).
    model : ChainModel, optional
        Model parameters; default: the study's.

    Returns
    -------
    openmm.System
        Unit-mass particles and the four named forces, each in its group of
        :data:`FORCE_GROUPS`. With ``model.segment_repulsion`` the System has ``n_beads``
        more particles, the bond midpoints (massless virtual sites), after the beads; see
        :func:`site_positions`.
    """
    pos = _check_positions(positions)
    model = ChainModel() if model is None else model
    n = pos.shape[0]
    system = openmm.System()
    for _ in range(n):
        system.addParticle(1.0)
    if model.segment_repulsion:
        for k in range(n):
            site = system.addParticle(0.0)
            system.setVirtualSite(site, openmm.TwoParticleAverageSite(k, (k + 1) % n, 0.5, 0.5))
    makers = {
        "bond": bond_force,
        "bend": bend_force,
        "steric": steric_force,
        "gravity": gravity_force,
    }
    for name, group in FORCE_GROUPS.items():
        force = makers[name](n, model)
        force.setForceGroup(group)
        system.addForce(force)
    return system


def site_positions(positions: np.ndarray, model: ChainModel) -> np.ndarray:
    """Positions of every particle of the System: the beads, then any bond midpoints.

    Parameters
    ----------
    positions : ndarray, shape (n_beads, 3), in d

    Returns
    -------
    ndarray, shape (n_beads, 3) or (2 n_beads, 3)
    """
    if not model.segment_repulsion:
        return positions
    return np.concatenate([positions, 0.5 * (positions + np.roll(positions, -1, axis=0))])


def build_topology(n_beads: int) -> openmm.app.Topology:
    """OpenMM Topology of the ring: one chain, one residue ``BEA`` per bead, ring bonds."""
    top = openmm.app.Topology()
    chain = top.addChain("A")
    element = openmm.app.Element.getBySymbol("C")
    atoms = []
    for i in range(n_beads):
        res = top.addResidue("BEA", chain, id=str(i + 1))
        atoms.append(top.addAtom("B", element, res))
    for i, j in ring_bonds(n_beads):
        top.addBond(atoms[int(i)], atoms[int(j)])
    return top
