"""Parameters of the bead-spring model (``docs/model.md``, "The chain").

:class:`ChainModel` holds the model's parameters in model units; its defaults are the
study's values. :func:`knotmm.model.system.chain_system` and the force functions of
:mod:`knotmm.model.forces` take one.
"""

from __future__ import annotations

from dataclasses import dataclass

from knotmm.units import LJ_CUTOFF_FACTOR

__all__ = ["ChainModel"]


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
