"""Parameters of the bead-spring model (``docs/model.md``, "The chain").

:class:`ChainModel` holds the model's parameters in model units; its defaults are the
study's values. :func:`knotmm.model.system.chain_system` and the force functions of
:mod:`knotmm.model.forces` take one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from knotmm.units import LJ_CUTOFF_FACTOR

__all__ = ["ChainModel", "ELASTO_GRAVITATION_DEFINITION", "elasto_gravitation_number"]

#: The elasto-gravitation number as knotmm states it (docs/model.md, "observables").
ELASTO_GRAVITATION_DEFINITION = (
    "B = N^3 F0 l0 / A: N the chain's beads, F0 the gravity force per bead, l0 the bond "
    "length, A the bending stiffness per joint (0.12 N^3 with the study's values)"
)


def elasto_gravitation_number(n_beads: int, gravity: float, bond_length: float,
                              bending_stiffness: float) -> float:
    """``B = N^3 F0 l0 / A``: gravity against bending for a chain of ``n_beads`` beads.

    The filament literature (Bukowicki and Ekiel-Jezewska 2019, and others) states its
    regimes by this number; with the study's discrete bending (``A`` per joint, in F0 d)
    and ``F0 = 1``, ``l0 = 0.6 d``, ``A = 5 F0 d`` it is ``0.12 N^3``.

    Parameters
    ----------
    n_beads : int
        N, the chain's beads.
    gravity, bond_length, bending_stiffness : float
        F0 (F0), l0 (d), A (F0 d).

    Returns
    -------
    float
        Dimensionless; ``inf`` for ``A = 0`` (no bending stiffness).
    """
    if bending_stiffness == 0:
        return math.inf
    return float(n_beads) ** 3 * float(gravity) * float(bond_length) / float(bending_stiffness)


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

    def elasto_gravitation_number(self, n_beads: int) -> float:
        """:func:`elasto_gravitation_number` of a chain of ``n_beads`` beads of this model."""
        return elasto_gravitation_number(n_beads, self.gravity, self.bond_length,
                                         self.bending_stiffness)

    def elasto_gravitation_facts(self, lengths) -> dict:
        """B of chains of ``lengths`` beads as run.toml's ``[knotmm]`` records it: one chain's
        ``elasto_gravitation_number``, several chains' ``elasto_gravitation_numbers`` (in the
        layout's order); nothing for ``A = 0`` (B infinite)."""
        values = [self.elasto_gravitation_number(n) for n in lengths]
        if not all(math.isfinite(v) for v in values):
            return {}
        if len(values) == 1:
            return {"elasto_gravitation_number": values[0]}
        return {"elasto_gravitation_numbers": values}

    @classmethod
    def from_config(cls, cfg) -> ChainModel:
        """Take the ``[model]`` table of a :class:`knotmm.config.RunConfig`."""
        values = cfg.table("model")
        flags = {"segment_repulsion"}
        kwargs = {k: (bool(v) if k in flags else float(v)) for k, v in values.items()
                  if k in cls.__dataclass_fields__}
        return cls(**kwargs)
