"""How the beads of a system form chains: the one owner of bonds, bending angles and chains.

A knotmm system is one or more chains of beads in one fluid. Chain ``c`` holds the beads
``start[c] ... start[c] + length[c] - 1`` (chains one after another in bead order); bead
``i`` of a chain is bonded to bead ``i + 1``, and a closed chain (a ring: a knot or a link
component) also bonds its last bead back to its first. Bending acts at every bead of a
ring and at every bead of an open chain but its two ends. The forces
(:mod:`knotmm.model.forces`), the System's bond-midpoint sites, the Topology
(:mod:`knotmm.model.topology`: one PDB chain per chain), the engine's bond-length check and
the analysis all take their bonds from a :class:`ChainLayout`.

Chains are named without limit: :func:`chain_ids` gives ``"A"`` ... ``"Z"``, ``"a"`` ...
``"z"``, ``"0"`` ... ``"9"`` to the first 62 chains, then ``"AA"``, ``"AB"``, ... (bijective
base 62: each name unique, up to four characters for 15 million chains). The name is the
chain's key in run.toml (linking numbers ``"A-B"``) and its PDB segment name; a PDB chain
identifier is one character, so :attr:`ChainLayout.pdb_chain_ids` repeats them after 62
chains (as OpenMM and mdtraj do), and readers tell chains apart by their bonds (CONECT
records), never by the chain identifier.

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

from knotmm.errors import TrajectoryFileError

__all__ = ["CHAIN_IDS", "ChainLayout", "chain_id", "chain_ids"]

#: PDB chain identifiers, in the order chains are named (one character each, as PDB needs);
#: the names of the first 62 chains, and the digits of the longer names of :func:`chain_ids`.
CHAIN_IDS = string.ascii_uppercase + string.ascii_lowercase + string.digits


def chain_id(index: int) -> str:
    """The name of chain ``index`` (from 0): ``"A"``, ..., ``"9"``, ``"AA"``, ``"AB"``, ...

    Bijective base 62 over :data:`CHAIN_IDS`, so that every index has its own name and the
    first 62 are the one-character PDB chain identifiers.
    """
    base = len(CHAIN_IDS)
    k = int(index) + 1
    digits = []
    while k > 0:
        k, r = divmod(k - 1, base)
        digits.append(CHAIN_IDS[r])
    return "".join(reversed(digits))


def chain_ids(n_chains: int) -> tuple[str, ...]:
    """The names of ``n_chains`` chains, in order (:func:`chain_id`)."""
    return tuple(chain_id(c) for c in range(int(n_chains)))


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
        For no chains, a count that is not an integer or too small, or ``closed`` of another
        length.
    """

    lengths: tuple[int, ...]
    closed: tuple[bool, ...] = ()

    def __post_init__(self):
        lengths = tuple(self.lengths)
        closed = tuple(self.closed) if len(self.closed) else (True,) * len(lengths)
        if not lengths:
            raise ValueError("a system needs at least one chain")
        if len(closed) != len(lengths):
            raise ValueError(
                f"closed has {len(closed)} entries for {len(lengths)} chains: give one per chain"
            )
        checked = []
        for c, (n, ring) in enumerate(zip(lengths, closed, strict=True)):
            if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
                raise ValueError(f"chain {chain_id(c)}: bead count {n!r} is not an integer")
            minimum = 3 if ring else 2
            if n < minimum:
                raise ValueError(
                    f"chain {chain_id(c)}: {n} beads; {'a closed' if ring else 'an open'} chain "
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
    def from_record(cls, record: Mapping[str, Any] | None, n_beads: int, *,
                    expected: ChainLayout | None = None,
                    chains: Sequence[Mapping[str, Any]] | None = None,
                    where: str = "run.toml's [knotmm.layout]") -> ChainLayout:
        """The layout :meth:`to_record` wrote (run.toml), or a ring of ``n_beads`` without one.

        The record is checked, as a file a person may have edited: its types, its bead
        count against ``n_beads`` (the checkpoint's state), and its chains against those the
        run wrote elsewhere: ``expected`` (the chains of its ``topology.pdb``, from the
        CONECT records; :meth:`from_bonds`) or else ``chains`` (run.toml's
        ``[[knotmm.chains]]`` tables, ``beads`` and ``closed`` each).

        Parameters
        ----------
        record : mapping or None
            ``{"lengths": [...], "closed": [...]}`` as read from run.toml.
        n_beads : int
            Beads of the state the layout must describe.
        expected : ChainLayout, optional
            The chains the run's topology file holds.
        chains : sequence of mapping, optional
            The chains run.toml records (used when ``expected`` is not given).
        where : str, optional
            How messages name the record.

        Raises
        ------
        TrajectoryFileError
            One line naming ``where``, what is inconsistent and what to restore: a record
            that is not a table of two lists, an invalid layout, another bead count, or
            chains other than the run's.
        """
        if expected is None and chains:
            expected = _layout_of_chains(chains)
        hint = ("restore it as the run wrote it" if expected is None else
                f"restore {expected.record_text()} (the run's chains)")
        if record is None or (isinstance(record, Mapping) and not record):
            if expected is not None and expected != cls.ring(expected.n_beads):
                raise TrajectoryFileError(
                    f"{where} is missing, but the run holds {expected.describe()}; "
                    f"restore {where} with {expected.record_text()}"
                )
            return cls.ring(n_beads)
        if not isinstance(record, Mapping):
            raise TrajectoryFileError(
                f"{where} = {record!r}: expected a table with lengths = [...] and closed = "
                f"[...]; {hint}"
            )
        lengths, closed = record.get("lengths"), record.get("closed")
        for key, value, kind in (("lengths", lengths, "bead counts"),
                                 ("closed", closed, "true/false, one per chain")):
            if not isinstance(value, (list, tuple)):
                raise TrajectoryFileError(
                    f"{where} {key} = {value!r}: expected a list of {kind}; {hint}"
                )
        if len(closed) != len(lengths):
            raise TrajectoryFileError(
                f"{where}: closed has {len(closed)} entries for {len(lengths)} chains "
                f"(lengths = {list(lengths)!r}); {hint}"
            )
        if not all(isinstance(r, bool) for r in closed):
            raise TrajectoryFileError(
                f"{where} closed = {list(closed)!r}: expected true or false per chain; {hint}"
            )
        try:
            layout = cls(tuple(lengths), tuple(closed))
        except ValueError as exc:
            raise TrajectoryFileError(f"{where}: {exc}; {hint}") from None
        if layout.n_beads != n_beads:
            raise TrajectoryFileError(
                f"{where} lengths = {list(layout.lengths)} hold {layout.n_beads} beads, the "
                f"run's state {n_beads}; {hint}"
            )
        if expected is not None and layout != expected:
            raise TrajectoryFileError(
                f"{where} ({layout.record_text()}) disagrees with the run's chains "
                f"({expected.describe()}): it was edited; {hint}"
            )
        return layout

    @classmethod
    def from_bonds(cls, n_beads: int, bonds) -> ChainLayout | None:
        """The layout whose bonds are exactly ``bonds`` (a topology file's), or ``None``.

        Chains are runs of consecutive beads bonded ``i - (i + 1)``; a chain is closed when
        its last bead is bonded to its first. ``None`` when there are no bonds, or when they
        are not those of any layout (a bond between beads that are not neighbours in a
        chain, a bead bonded to nothing among bonded ones).

        Parameters
        ----------
        n_beads : int
        bonds : array_like, shape (n_bonds, 2), int
            Bonded pairs of bead indices (from 0), in any order.
        """
        pairs = {tuple(sorted((int(a), int(b)))) for a, b in np.asarray(bonds).reshape(-1, 2)}
        if not pairs or n_beads < 2:
            return None
        lengths, closed = [], []
        start = 0
        for i in range(n_beads):
            if i == n_beads - 1 or (i, i + 1) not in pairs:
                count = i + 1 - start
                lengths.append(count)
                closed.append(count >= 3 and (start, i) in pairs)
                start = i + 1
        try:
            layout = cls(tuple(lengths), tuple(closed))
        except ValueError:
            return None
        if {tuple(sorted(map(int, b))) for b in layout.bonds()} != pairs:
            return None
        return layout

    def to_record(self) -> dict[str, list]:
        """``{"lengths": [...], "closed": [...], "ids": [...]}`` for run.toml."""
        return {"lengths": list(self.lengths), "closed": list(self.closed), "ids": list(self.ids)}

    def record_text(self) -> str:
        """The layout as run.toml writes it: ``lengths = [30, 30], closed = [true, true]``."""
        flags = ", ".join("true" if r else "false" for r in self.closed)
        return f"lengths = {list(self.lengths)}, closed = [{flags}]"

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
        """The chains' names: ``"A"``, ``"B"``, ..., ``"AA"``, ... (:func:`chain_ids`; unique,
        the PDB segment names)."""
        return chain_ids(self.n_chains)

    @property
    def pdb_chain_ids(self) -> tuple[str, ...]:
        """The chains' one-character PDB chain identifiers: the names of the first 62
        chains, then again from ``"A"`` (not unique past 62 chains)."""
        return tuple(CHAIN_IDS[c % len(CHAIN_IDS)] for c in range(self.n_chains))

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

    #: Most chains :meth:`describe` names one by one; more are counted by kind and length.
    DESCRIBE_EACH = 6

    def describe(self) -> str:
        """One line, e.g. ``"90 beads, one ring"``, ``"90 beads in 2 chains (A: ring of 60,
        B: open, 30)"``, or, past :attr:`DESCRIBE_EACH` chains, ``"600 beads in 200 chains
        (200 open of 3)"``."""
        if self.n_chains == 1:
            kind = "ring" if self.closed[0] else "open chain"
            return f"{self.n_beads} beads, one {kind}"
        if self.n_chains <= self.DESCRIBE_EACH:
            parts = [
                f"{cid}: {'ring of ' if ring else 'open, '}{n}"
                for cid, n, ring in zip(self.ids, self.lengths, self.closed, strict=True)
            ]
        else:
            kinds: dict[tuple[bool, int], int] = {}
            for n, ring in zip(self.lengths, self.closed, strict=True):
                kinds[(ring, n)] = kinds.get((ring, n), 0) + 1
            parts = [f"{count} {'rings' if ring else 'open'} of {n}" if count > 1
                     else f"1 {'ring' if ring else 'open'} of {n}"
                     for (ring, n), count in kinds.items()]
            if len(kinds) > self.DESCRIBE_EACH:
                rings = sum(self.closed)
                parts = [p for p in (f"{rings} rings" if rings else "",
                                     f"{self.n_chains - rings} open" if rings < self.n_chains
                                     else "") if p]
                parts.append(f"{min(self.lengths)}-{max(self.lengths)} beads each")
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

    def bond_lengths(self, positions) -> np.ndarray:
        """Length of every bond of :meth:`bonds`, in its order, in d.

        Parameters
        ----------
        positions : array_like, shape (n_beads, 3)
            In d.

        Returns
        -------
        ndarray, shape (n_bonds,)
        """
        x = np.asarray(positions, dtype=np.float64)
        pairs = self.bonds()
        return np.linalg.norm(x[pairs[:, 1]] - x[pairs[:, 0]], axis=1)

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


def _layout_of_chains(chains: Sequence[Mapping[str, Any]]) -> ChainLayout | None:
    """The layout of run.toml's ``[[knotmm.chains]]`` tables (``beads``, ``closed``), or
    ``None`` when they do not describe one."""
    try:
        return ChainLayout(tuple(c["beads"] for c in chains),
                           tuple(bool(c["closed"]) for c in chains))
    except (KeyError, TypeError, ValueError):
        return None


def concatenate(parts: Sequence[ChainLayout]) -> ChainLayout:
    """One layout holding the chains of ``parts`` in order."""
    lengths: list[int] = []
    closed: list[bool] = []
    for part in parts:
        lengths.extend(part.lengths)
        closed.extend(part.closed)
    return ChainLayout(tuple(lengths), tuple(closed))
