"""The forces of the bead-spring model, one small function per force.

Each function takes the number of beads and a :class:`knotmm.model.parameters.ChainModel` and
returns one named ``openmm.Force`` (``force.getName()``), in model units read by OpenMM as
kJ/mol and nm (``docs/model.md``):

========== ============================================ =========================
name       energy                                       OpenMM force
========== ============================================ =========================
bond       sum_bonds B/2 (l - l0)^2                     ``HarmonicBondForce``
bend       sum_beads A/2 (phi - pi)^2                   ``CustomAngleForce``
steric     eps ((sigma/r)^12 - (sigma/r)^6), r < rc     ``NonbondedForce``
gravity    sum_beads g z                                ``CustomExternalForce``
========== ============================================ =========================

with ``rc = 2**(1/6) sigma``. The steric term is the published form (no factor 4): an OpenMM
Lennard-Jones term with ``epsilon_openmm = eps / 4``, truncated at ``rc`` without a
switching function, so its force vanishes exactly at the cutoff (the energy jumps by
``eps/4``, as in the published model). It acts between every pair of beads that is not
bonded; bonded pairs are exceptions with zero interaction. All charges are zero. With
``segment_repulsion`` the steric force also holds one site per bond midpoint (the System's
virtual sites, :func:`knotmm.model.system.chain_system`). To add a force, see
``docs/architecture.md``.
"""

from __future__ import annotations

import numpy as np
import openmm

from knotmm.model.parameters import ChainModel
from knotmm.model.topology import ring_bonds

__all__ = ["FORCE_GROUPS", "FORCE_MAKERS", "bend_force", "bond_force", "gravity_force",
           "steric_force"]

#: Force name -> force group. Per-term energies are read by group.
FORCE_GROUPS = {"bond": 0, "bend": 1, "steric": 2, "gravity": 3}


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


#: Force name -> the function that makes it (in the order of :data:`FORCE_GROUPS`).
FORCE_MAKERS = {
    "bond": bond_force,
    "bend": bend_force,
    "steric": steric_force,
    "gravity": gravity_force,
}
