"""How the beads of a system form chains: the one owner of bonds, bending angles and chains.

A knotmm system is one or more chains of beads in one fluid. Chain ``c`` holds the beads
``start[c] ... start[c] + length[c] - 1`` (chains one after another in bead order); bead
``i`` of a chain is bonded to bead ``i + 1``, and a closed chain (a ring: a knot or a link
component) also bonds its last bead back to its first. Bending acts at every bead of a
ring and at every bead of an open chain but its two ends. The forces
(:mod:`knotmm.model.forces`), the System's bond-midpoint sites, the Topology
(:mod:`knotmm.model.topology`: one PDB chain per chain), the engine's bond-length check and
the analysis all take their bonds from a :class:`ChainLayout`.

>>> layout = ChainLayout((4, 3), (True, False))
>>> layout.bonds().tolist()
[[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6]]
>>> layout.angles().tolist()
[[3, 0, 1], [0, 1, 2], [1, 2, 3], [2, 3, 0], [4, 5, 6]]
"""

from __future__ import annotations

import string
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["CHAIN_IDS", "ChainLayout"]

#: PDB chain identifiers, in the order chains are named (one character each, as PDB needs).
CHAIN_IDS = string.ascii_uppercase + string.ascii_lowercase + string.digits


@dataclass(frozen=True)
class ChainLayout:
    """The chains of a system: their bead counts and whether each is closed.

    Parameters
    ----------
    lengths : sequence of int
        Beads of each chain, in bead order; at least 3 for a closed chain, 2 for an open one.
    closed : sequence of bool, optional
        Whether each chain is a ring; default: every chain.

    Raises
    ------
    ValueError
        For no chains, a count that is not an integer or too small, more chains than
        :data:`CHAIN_IDS` names, or ``closed`` of another length.
    """

    lengths: tuple[int, ...]
    closed: tuple[bool, ...] = ()

    def __post_init__(self):
        lengths = tuple(self.lengths)
        closed = tuple(self.closed) if len(self.closed) else (True,) * len(lengths)
        if not lengths:
            raise ValueError("a system needs at least one chain")
        if len(lengths) > len(CHAIN_IDS):
            raise ValueError(f"{len(lengths)} chains: at most {len(CHAIN_IDS)} are supported")
        if len(closed) != len(lengths):
            raise ValueError(
                f"closed has {len(closed)} entries for {len(lengths)} chains: give one per chain"
            )
        checked = []
        for c, (n, ring) in enumerate(zip(lengths, closed, strict=True)):
            if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
                raise ValueError(f"chain {CHAIN_IDS[c]}: bead count {n!r} is not an integer")
            minimum = 3 if ring else 2
            if n < minimum:
                raise ValueError(
                    f"chain {CHAIN_IDS[c]}: {n} beads; {'a closed' if ring else 'an open'} chain "
                    f"needs at least {minimum}"
                )
            checked.append(int(n))
        object.__setattr__(self, "lengths", tuple(checked))
        object.__setattr__(self, "closed", tuple(bool(r) for r in closed))

    # -- construction ---------------------------------------------------------------------
    @classmethod
    def ring(cls, n_beads: int) -> ChainLayout:
        """One closed chain of ``n_beads`` beads (the study's system)."""
        return cls((n_beads,), (True,))

    @classmethod
    def of(cls, layout: ChainLayout | int) -> ChainLayout:
        """``layout`` itself, or a ring of that many beads for an integer."""
        return layout if isinstance(layout, ChainLayout) else cls.ring(layout)

    @classmethod
    def from_record(cls, record: Mapping[str, Any] | None, n_beads: int) -> ChainLayout:
        """The layout :meth:`to_record` wrote (run.toml), or a ring of ``n_beads`` without one."""
        if not record:
            return cls.ring(n_beads)
        layout = cls(tuple(record["lengths"]), tuple(record["closed"]))
        if layout.n_beads != n_beads:
            raise ValueError(
                f"the recorded chains hold {layout.n_beads} beads, the state {n_beads}"
            )
        return layout

    def to_record(self) -> dict[str, list]:
        """``{"lengths": [...], "closed": [...], "ids": [...]}`` for run.toml."""
        return {"lengths": list(self.lengths), "closed": list(self.closed), "ids": list(self.ids)}

    # -- description ----------------------------------------------------------------------
    @property
    def n_beads(self) -> int:
        return int(sum(self.lengths))

    @property
    def n_chains(self) -> int:
        return len(self.lengths)

    @property
    def is_single_ring(self) -> bool:
        """One closed chain: the system every torus-knot analysis is written for."""
        return self.n_chains == 1 and self.closed[0]

    @property
    def ids(self) -> tuple[str, ...]:
        """The chains' PDB identifiers: ``"A"``, ``"B"``, ..."""
        return tuple(CHAIN_IDS[: self.n_chains])

    @property
    def starts(self) -> np.ndarray:
        """First bead of each chain, shape (n_chains,)."""
        return np.concatenate([[0], np.cumsum(self.lengths)[:-1]]).astype(np.int64)

    def slices(self) -> list[slice]:
        """The beads of each chain as slices of the bead axis."""
        return [slice(int(s), int(s) + n) for s, n in zip(self.starts, self.lengths, strict=True)]

    def chain_of_bead(self) -> np.ndarray:
        """Chain index of every bead, shape (n_beads,), int."""
        return np.repeat(np.arange(self.n_chains), self.lengths)

    def split(self, positions: np.ndarray) -> list[np.ndarray]:
        """``positions`` (..., n_beads, 3) cut into one array per chain (views)."""
        return [positions[..., s, :] for s in self.slices()]

    def describe(self) -> str:
        """E.g. ``"90 beads, 1 ring"`` or ``"2 chains (A: ring of 60, B: open, 30)"``."""
        if self.n_chains == 1:
            kind = "ring" if self.closed[0] else "open chain"
            return f"{self.n_beads} beads, one {kind}"
        parts = [
            f"{cid}: {'ring of ' if ring else 'open, '}{n}"
            for cid, n, ring in zip(self.ids, self.lengths, self.closed, strict=True)
        ]
        return f"{self.n_beads} beads in {self.n_chains} chains ({', '.join(parts)})"

    # -- connectivity ---------------------------------------------------------------------
    def bonds(self) -> np.ndarray:
        """Bonded pairs, chain by chain: ``(i, i+1)``, then a ring's closure ``(last, first)``.

        Returns
        -------
        ndarray, shape (n_bonds, 2), int
            ``n_bonds`` is ``sum(lengths)`` less one per open chain. For a single ring the
            order is that of bond ``k`` joining beads ``k`` and ``k + 1 (mod N)``.
        """
        parts = []
        for start, n, ring in zip(self.starts, self.lengths, self.closed, strict=True):
            i = np.arange(n if ring else n - 1)
            parts.append(start + np.stack([i, (i + 1) % n], axis=1))
        return np.concatenate(parts).astype(np.int64)

    def angles(self) -> np.ndarray:
        """Bending triples ``(previous, bead, next)``: every bead of a ring, the inner beads
        of an open chain.

        Returns
        -------
        ndarray, shape (n_angles, 3), int
        """
        parts = []
        for start, n, ring in zip(self.starts, self.lengths, self.closed, strict=True):
            i = np.arange(n) if ring else np.arange(1, n - 1)
            parts.append(start + np.stack([(i - 1) % n, i, (i + 1) % n], axis=1))
        parts = [p for p in parts if p.size]
        return np.concatenate(parts).astype(np.int64) if parts else np.zeros((0, 3), np.int64)

    def adjacent_bonds(self) -> list[tuple[int | None, int | None]]:
        """For every bond of :meth:`bonds`, the index of the bond before it and after it
        along its chain (``None`` at an open chain's ends)."""
        out: list[tuple[int | None, int | None]] = []
        first = 0
        for n, ring in zip(self.lengths, self.closed, strict=True):
            m = n if ring else n - 1
            for k in range(m):
                before = first + (k - 1) % m if (ring or k > 0) else None
                after = first + (k + 1) % m if (ring or k < m - 1) else None
                out.append((before, after))
            first += m
        return out


def concatenate(parts: Sequence[ChainLayout]) -> ChainLayout:
    """One layout holding the chains of ``parts`` in order."""
    lengths: list[int] = []
    closed: list[bool] = []
    for part in parts:
        lengths.extend(part.lengths)
        closed.extend(part.closed)
    return ChainLayout(tuple(lengths), tuple(closed))
