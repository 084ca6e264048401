"""The forces of the bead-spring model, one small function per force.

Each function takes the system's chains (a :class:`knotmm.model.layout.ChainLayout`, or a
bead count for one ring) and a :class:`knotmm.model.parameters.ChainModel` and returns one
named ``openmm.Force`` (``force.getName()``), in model units read by OpenMM as
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
bonded (beads of different chains always interact); bonded pairs are exceptions with zero
interaction. All charges are zero. With ``segment_repulsion`` the steric force also holds one
site per bond midpoint (the System's virtual sites, :func:`knotmm.model.system.chain_system`),
in the order of :meth:`ChainLayout.bonds`. To add a force, see
``docs/architecture.md``.
"""

from __future__ import annotations

import numpy as np
import openmm

from knotmm.model.layout import ChainLayout
from knotmm.model.parameters import ChainModel

__all__ = ["FORCE_GROUPS", "FORCE_MAKERS", "bend_force", "bond_force", "gravity_force",
           "grouped_steric_force", "steric_force"]

#: Force name -> force group. Per-term energies are read by group.
FORCE_GROUPS = {"bond": 0, "bend": 1, "steric": 2, "gravity": 3}


def bond_force(layout: ChainLayout | int, model: ChainModel) -> openmm.HarmonicBondForce:
    """Harmonic bonds ``B/2 (l - l0)^2`` along every chain (OpenMM's k is ``B``)."""
    force = openmm.HarmonicBondForce()
    for i, j in ChainLayout.of(layout).bonds():
        force.addBond(int(i), int(j), model.bond_length, model.bond_stiffness)
    force.setName("bond")
    return force


def bend_force(layout: ChainLayout | int, model: ChainModel) -> openmm.CustomAngleForce:
    """Harmonic bending ``A/2 (phi - pi)^2`` at every bead of a ring, at the inner beads of an
    open chain.

    A ``CustomAngleForce`` with the global parameter ``bending_stiffness`` (= A): on the CPU
    platform it costs about half of what ``HarmonicAngleForce`` costs for the same angles
    (see benchmarks/README.md), and it gives the same forces.
    """
    force = openmm.CustomAngleForce(f"0.5*bending_stiffness*(theta - {np.pi!r})^2")
    force.addGlobalParameter("bending_stiffness", model.bending_stiffness)
    for h, i, j in ChainLayout.of(layout).angles():
        force.addAngle(int(h), int(i), int(j), [])
    force.setName("bend")
    return force


def steric_force(layout: ChainLayout | int, model: ChainModel) -> openmm.NonbondedForce:
    """Truncated Lennard-Jones ``eps((sigma/r)^12 - (sigma/r)^6)`` for ``r < 2^(1/6) sigma``.

    Every non-bonded pair interacts (next-nearest neighbours included, beads of different
    chains always); bonded pairs are zeroed exceptions. A bond-midpoint site does not see the
    beads of its bond and of the bonds next to it along its chain, nor their sites.
    """
    layout = ChainLayout.of(layout)
    n_beads = layout.n_beads
    bonds = layout.bonds()
    force = openmm.NonbondedForce()
    force.setNonbondedMethod(openmm.NonbondedForce.CutoffNonPeriodic)
    force.setCutoffDistance(model.steric_range)
    force.setUseSwitchingFunction(False)
    force.setUseDispersionCorrection(False)
    force.setReactionFieldDielectric(1.0)
    n_sites = n_beads + len(bonds) if model.segment_repulsion else n_beads
    for _ in range(n_sites):
        force.addParticle(0.0, model.lj_sigma, model.lj_epsilon / 4.0)
    for i, j in bonds:
        force.addException(int(i), int(j), 0.0, model.lj_sigma, 0.0)
    if model.segment_repulsion:
        # the midpoint site of bond k is particle n_beads + k, between that bond's beads
        for k, (before, after) in enumerate(layout.adjacent_bonds()):
            site = n_beads + k
            near = [] if before is None else [int(bonds[before][0])]
            near += [int(bonds[k][0]), int(bonds[k][1])]
            near += [] if after is None else [int(bonds[after][1])]
            for bead in dict.fromkeys(near):
                force.addException(site, bead, 0.0, model.lj_sigma, 0.0)
            if after is not None and after != k:
                force.addException(site, n_beads + after, 0.0, model.lj_sigma, 0.0)
    force.setName("steric")
    return force


def grouped_steric_force(layout: ChainLayout, model: ChainModel,
                         groups) -> openmm.CustomNonbondedForce:
    """:func:`steric_force`'s term acting only within each group of particles.

    The same truncated Lennard-Jones energy and cutoff, as a ``CustomNonbondedForce`` with
    one interaction group per entry of ``groups`` and :func:`steric_force`'s exceptions as
    exclusions: a System holding several copies of one system in one place
    (:mod:`knotmm.engine.copies`), where each copy must see only itself.

    Parameters
    ----------
    layout : ChainLayout
        The chains of all the copies (and the sites with ``model.segment_repulsion``).
    model : ChainModel
    groups : sequence of sequences of int
        The particles of each copy.
    """
    plain = steric_force(layout, model)
    # constants, not global parameters: the Context's parameters stay those of one copy
    # alone (the plugin's cached velocity is kept only while they are the same)
    eps, sigma = float(model.lj_epsilon), float(model.lj_sigma)
    force = openmm.CustomNonbondedForce(f"{eps!r}*(({sigma!r}/r)^12 - ({sigma!r}/r)^6)")
    force.setNonbondedMethod(openmm.CustomNonbondedForce.CutoffNonPeriodic)
    force.setCutoffDistance(model.steric_range)
    force.setUseSwitchingFunction(False)
    force.setUseLongRangeCorrection(False)
    for _ in range(plain.getNumParticles()):
        force.addParticle([])
    for e in range(plain.getNumExceptions()):  # every exception is a zeroed pair
        i, j, *_ = plain.getExceptionParameters(e)
        force.addExclusion(i, j)
    for group in groups:
        members = {int(i) for i in group}
        force.addInteractionGroup(members, members)
    force.setName("steric")
    return force


def gravity_force(layout: ChainLayout | int, model: ChainModel) -> openmm.CustomExternalForce:
    """Constant force ``g`` along ``-z`` on every bead (energy ``g z``)."""
    force = openmm.CustomExternalForce("gravity_force*z")
    force.addGlobalParameter("gravity_force", model.gravity)
    for i in range(ChainLayout.of(layout).n_beads):
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
