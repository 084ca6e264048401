"""The OpenMM ``System`` of bead-spring chains.

The study's chain of ``N`` beads is a ring: bead ``i`` is bonded to ``i + 1`` and bead
``N - 1`` to bead ``0``; a system of several chains, or of open ones, is described by a
:class:`knotmm.model.layout.ChainLayout`. :func:`chain_system` makes a System of unit-mass
particles holding the four named forces of :mod:`knotmm.model.forces`, each in its own force
group (:data:`FORCE_GROUPS`); energies in F0 d, lengths in d, read by OpenMM as kJ/mol and
nm (``docs/model.md``). This layer knows nothing of run files: the config-aware
``build_system(cfg)`` (template + System + Topology) is
:func:`knotmm.shapes.builder.build_system`.
"""

from __future__ import annotations

import numpy as np
import openmm

from knotmm.errors import ConfigError
from knotmm.model.forces import FORCE_GROUPS, FORCE_MAKERS
from knotmm.model.layout import ChainLayout
from knotmm.model.parameters import ChainModel

__all__ = ["FORCE_GROUPS", "SITE_WEIGHTS", "ChainModel", "chain_system", "copies_system",
           "site_positions"]

#: Weights of a bond's two beads in its midpoint site (``model.segment_repulsion``): the
#: System's ``TwoParticleAverageSite`` and :func:`site_positions` both take them from here.
SITE_WEIGHTS = (0.5, 0.5)


def _check_positions(positions, layout: ChainLayout | None) -> np.ndarray:
    pos = np.asarray(positions, dtype=np.float64)
    if pos.ndim != 2 or pos.shape[1] != 3:
        raise ConfigError(f"positions: expected shape (n_beads, 3), got {pos.shape}")
    if layout is None and pos.shape[0] < 4:
        raise ConfigError(f"positions: a ring needs at least 4 beads, got {pos.shape[0]}")
    if layout is not None and layout.n_beads != pos.shape[0]:
        raise ConfigError(
            f"positions: {pos.shape[0]} beads, but the chains ({layout.describe()}) hold "
            f"{layout.n_beads}"
        )
    if not np.all(np.isfinite(pos)):
        raise ConfigError("positions: contain NaN or infinite values")
    return pos


def chain_system(
    positions, model: ChainModel | None = None, layout: ChainLayout | None = None
) -> openmm.System:
    """The OpenMM System of a closed chain, or of the chains of ``layout``.

    Parameters
    ----------
    positions : array_like, shape (n_beads, 3), in d
        Only the number of beads is taken from it (and it is checked to be finite).
    model : ChainModel, optional
        Model parameters; default: the study's.
    layout : ChainLayout, optional
        The chains; default: one ring of all the beads.

    Returns
    -------
    openmm.System
        Unit-mass particles and the four named forces, each in its group of
        :data:`FORCE_GROUPS`. With ``model.segment_repulsion`` the System has one more
        particle per bond, the bond midpoints (massless virtual sites, in the order of
        :meth:`ChainLayout.bonds`), after the beads; :func:`site_positions` places them
        outside OpenMM by the same rule.
    """
    pos = _check_positions(positions, layout)
    model = ChainModel() if model is None else model
    layout = ChainLayout.ring(pos.shape[0]) if layout is None else layout
    system = openmm.System()
    for _ in range(layout.n_beads):
        system.addParticle(1.0)
    if model.segment_repulsion:
        for i, j in layout.bonds():
            site = system.addParticle(0.0)
            system.setVirtualSite(site, openmm.TwoParticleAverageSite(int(i), int(j),
                                                                      *SITE_WEIGHTS))
    for name, group in FORCE_GROUPS.items():
        force = FORCE_MAKERS[name](layout, model)
        force.setForceGroup(group)
        system.addForce(force)
    return system


def copies_system(positions, model: ChainModel, layout: ChainLayout, copies: int) -> openmm.System:
    """The System of ``copies`` copies of the chains of ``layout``, all in one place.

    :func:`chain_system` of the chains repeated ``copies`` times, its steric term acting
    within each copy only (:func:`knotmm.model.forces.grouped_steric_force`): copy k's
    beads are beads ``k n`` to ``(k + 1) n - 1``, its bond midpoints (with
    ``model.segment_repulsion``) the sites of its bonds. For
    :meth:`knotmm.plugin.RPYIntegrator.setNumCopies` with ``setCopiesApart(False)``.

    Parameters
    ----------
    positions : array_like, shape (n_beads, 3), in d
        One copy's beads (only their number is used).
    model : ChainModel
    layout : ChainLayout
        One copy's chains.
    copies : int

    Returns
    -------
    openmm.System
    """
    from knotmm.model.forces import grouped_steric_force

    n = layout.n_beads
    repeated = ChainLayout(tuple(layout.lengths) * copies, tuple(layout.closed) * copies)
    system = chain_system(np.vstack([_check_positions(positions, layout)] * copies), model,
                          repeated)
    n_bonds = len(layout.bonds()) if model.segment_repulsion else 0
    groups = [list(range(k * n, (k + 1) * n))
              + list(range(copies * n + k * n_bonds, copies * n + (k + 1) * n_bonds))
              for k in range(copies)]
    names = [system.getForce(i).getName() for i in range(system.getNumForces())]
    index = names.index("steric")
    group = system.getForce(index).getForceGroup()
    system.removeForce(index)
    steric = grouped_steric_force(repeated, model, groups)
    steric.setForceGroup(group)
    system.addForce(steric)
    return system


def site_positions(positions: np.ndarray, model: ChainModel, layout: ChainLayout) -> np.ndarray:
    """Positions of every particle of the System: the beads, then any bond midpoints.

    The one rule that places the sites outside OpenMM: site ``k`` is the weighted average
    (:data:`SITE_WEIGHTS`) of the two beads of bond ``k`` of ``layout.bonds()``, as the
    System's ``TwoParticleAverageSite`` k (:func:`chain_system`) is, and in the same
    floating-point operations as OpenMM's Reference and CPU platforms place it (bit for bit).

    Parameters
    ----------
    positions : ndarray, shape (n_beads, 3), in d
    model : ChainModel
        Sites only with ``model.segment_repulsion``.
    layout : ChainLayout
        The chains whose bonds carry the sites (the System's layout; there is no default:
        a ring's sites are not those of open or several chains).

    Returns
    -------
    ndarray, shape (n_beads, 3) or (n_beads + n_bonds, 3), in d
        ``positions`` itself without sites.

    Raises
    ------
    ConfigError
        ``positions`` do not hold ``layout``'s beads.
    TypeError
        ``layout`` is not a :class:`ChainLayout`.
    """
    if not model.segment_repulsion:
        return positions
    if not isinstance(layout, ChainLayout):
        raise TypeError(f"site_positions: layout must be a ChainLayout, got {layout!r}")
    pos = np.asarray(positions, dtype=np.float64)
    if pos.ndim != 2 or pos.shape != (layout.n_beads, 3):
        raise ConfigError(
            f"positions: shape {pos.shape}, but the chains ({layout.describe()}) hold "
            f"{layout.n_beads} beads"
        )
    bonds = layout.bonds()
    w0, w1 = SITE_WEIGHTS
    return np.concatenate([pos, pos[bonds[:, 0]] * w0 + pos[bonds[:, 1]] * w1])
