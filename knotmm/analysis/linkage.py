"""Which chains of a system are linked: the objects the analysis measures.

A system of several chains (:mod:`knotmm.analysis.chains`) holds objects: separate chains,
and links (rings that cannot be pulled apart), each link analysed as one object beside the
chains that are not part of it. Whether two rings are linked is decided at the start (frame
0), pair by pair, from what can be proved:

* **linked**: the run built them as one link (run.toml's ``[knotmm] link`` for a run of one
  link, ``links`` for a link among ``[[chains]]``, matched to its chains through the run
  file's entries and their bead counts), or their linking number is not 0 (a nonzero Gauss
  linking integral cannot be undone without a strand passing through another);
* **not linked**: their linking number is 0 and a plane separates them (their convex hulls
  are disjoint: a linear program, :func:`separated_by_plane`), so they can be moved apart;
* otherwise (linking number 0, no separating plane: a linking number of 0 does not prove two
  rings unlinked, the Whitehead link has 0), where knot identification is on and topoly is
  installed, the pair's HOMFLY-PT polynomial (:func:`knotmm.knots.identify.identify_link`):
  **linked** when it is a link's that is not split (``L5a1``: the Whitehead link), since
  rings a sphere separates have a split link's polynomial;
* **not determined** in every other case (no identification, or the polynomial of a split
  link, ``0_1U0_1``, which some non-split links share): reported with the reason, and the
  pair's rings are analysed as separate chains.

Linked pairs join their rings into groups (connected components); a group of two or more
rings is a link object. Units: d.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from knotmm.model.layout import chain_ids

__all__ = ["LINKED", "NOT_DETERMINED", "NOT_LINKED", "Linkage", "entry_chains", "linkage",
           "separated_by_plane"]

#: Why a pair is linked, not linked or not determined (``system.linked`` in analysis.json).
LINKED = "linked"
NOT_LINKED = "not linked"
NOT_DETERMINED = "not determined"
#: The reason of a pair whose linking is not determined.
UNDETERMINED_REASON = (
    "linking number 0 and no plane separates them: a linking number of 0 does not prove two "
    "rings unlinked (the Whitehead link has 0)")


def separated_by_plane(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether a plane strictly separates two point sets (their convex hulls are disjoint).

    Solved as the feasibility of ``w.a_i - c <= -1`` and ``w.b_j - c >= 1`` (any strict
    separation can be scaled to that) with scipy's HiGHS linear program.

    Parameters
    ----------
    a, b : ndarray, shape (n_a, 3) and (n_b, 3)
        Bead positions, d (centred and scaled to unit size before the solve). Two closed
        polygons separated by a plane are not linked.
    """
    from scipy.optimize import linprog

    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    centre = np.concatenate([a, b]).mean(axis=0)
    scale = max(float(np.abs(np.concatenate([a, b]) - centre).max()), 1e-300)
    a, b = (a - centre) / scale, (b - centre) / scale
    # unknowns (w_x, w_y, w_z, c): a rows  w.a - c <= -1;  b rows  -w.b + c <= -1
    rows = np.vstack([np.c_[a, -np.ones(len(a))], np.c_[-b, np.ones(len(b))]])
    rhs = -np.ones(len(rows))
    res = linprog(np.zeros(4), A_ub=rows, b_ub=rhs, bounds=[(None, None)] * 4, method="highs")
    return bool(res.status == 0)


def entry_chains(entries: Sequence[Mapping[str, Any]] | None,
                 lengths: Sequence[int]) -> list[list[int]] | None:
    """The layout's chains that each ``[[chains]]`` entry built, or None if they do not match.

    An entry of ``beads`` beads built the next chains whose bead counts add up to it (a
    link's components share its beads; every other entry is one chain).
    """
    if not isinstance(entries, list) or not entries:
        return None
    out, k = [], 0
    for entry in entries:
        try:
            want = int(entry.get("beads"))
        except (TypeError, ValueError, AttributeError):
            return None
        mine, total = [], 0
        while k < len(lengths) and total < want:
            mine.append(k)
            total += int(lengths[k])
            k += 1
        if total != want:
            return None
        out.append(mine)
    return out if k == len(lengths) else None


class Linkage:
    """The linking of a system's rings at the start (module docstring).

    Attributes
    ----------
    pairs : dict
        ``{"A-B": {"status": "linked" | "not linked" | "not determined", "reason": str}}``
        for every pair of rings.
    groups : list of list of int
        Chains (indices) of each link object: two or more rings joined by linked pairs.
    names : list of str or None
        Each group's name where the run built it (``"hopf link T(2,2)"``), else None.
    entries : list of int or None
        The ``[[chains]]`` entry that built each group whole, else None.
    """

    def __init__(self, pairs: dict, groups: list[list[int]], names: list, entries: list):
        self.pairs, self.groups, self.names, self.entries = pairs, groups, names, entries

    @property
    def undetermined(self) -> list[str]:
        """The pairs whose linking is not determined (``"A-B"``)."""
        return [p for p, v in self.pairs.items() if v["status"] == NOT_DETERMINED]


def _recorded_groups(data, chains) -> list[tuple[list[int], str, int | None]]:
    """The links the run built: (chains, name, entry index or None)."""
    facts = data.get("knotmm", {}) or {}
    closed = [c for _, c in chains]
    if facts.get("link") and not data.get("chains"):
        return [(list(range(len(chains))), str(facts["link"]), None)] if all(closed) else []
    links = facts.get("links") or []
    built = entry_chains(data.get("chains"), [sl.stop - sl.start for sl, _ in chains])
    if not links or built is None:
        return []
    out = []
    parts = [(e, ks) for e, ks in enumerate(built) if len(ks) > 1 and all(closed[k] for k in ks)]
    for (e, ks), link in zip(parts, links, strict=False):  # links in the entries' order
        name = link.get("link") if isinstance(link, Mapping) else None
        out.append((ks, str(name or "link"), e))
    return out


def _by_polynomial(a: np.ndarray, b: np.ndarray) -> tuple[str, str]:
    """Status and reason of a pair with linking number 0 and no separating plane, from
    topoly's HOMFLY-PT identification of the two rings as a link (module docstring)."""
    from knotmm.knots.identify import UNKNOWN, identify_link

    name = identify_link([a, b])
    if name is None:
        return NOT_DETERMINED, UNDETERMINED_REASON + "; the link was not identified (no topoly)"
    if name == UNKNOWN:
        return NOT_DETERMINED, UNDETERMINED_REASON + "; topoly could not name the link"
    if "U" in name:
        return NOT_DETERMINED, (UNDETERMINED_REASON + f"; their HOMFLY-PT polynomial is a split "
                                f"link's ({name}), which does not prove them apart either")
    return LINKED, (f"linking number 0, but their HOMFLY-PT polynomial is the link {name}'s "
                    "(topoly), not a split link's")


def linkage(data, chains: Sequence[tuple[slice, bool]], linking: Mapping[str, int | None],
            identify: bool = False) -> Linkage:
    """Decide which rings are linked (module docstring).

    Parameters
    ----------
    data : knotmm.io.run_data.RunData
        Its first frame and its run file's facts.
    chains : list of (slice, bool)
        Bead ranges, closed or not.
    linking : mapping
        ``{"A-B": Lk}`` at the start (None for a pair that touches).
    identify : bool
        Ask topoly (in the knot worker) about the pairs nothing else settles.
    """
    ids = chain_ids(len(chains))
    index = {cid: k for k, cid in enumerate(ids)}
    x0 = np.asarray(data.positions[0], dtype=np.float64)
    recorded = _recorded_groups(data, chains)
    in_record = {}
    for g, (ks, _, _) in enumerate(recorded):
        for k in ks:
            in_record[k] = g
    parent = list(range(len(chains)))

    def root(k):
        while parent[k] != k:
            parent[k] = parent[parent[k]]
            k = parent[k]
        return k

    pairs = {}
    rings = [k for k, (_, closed) in enumerate(chains) if closed]
    for n, i in enumerate(rings):
        for j in rings[n + 1:]:
            key = f"{ids[i]}-{ids[j]}"
            lk = linking.get(key)
            if in_record.get(i) is not None and in_record.get(i) == in_record.get(j):
                status, reason = LINKED, f"built as one link: {recorded[in_record[i]][1]}"
            elif lk:
                status, reason = LINKED, f"linking number {lk}"
            elif separated_by_plane(x0[chains[i][0]], x0[chains[j][0]]):
                status, reason = NOT_LINKED, (
                    ("linking number 0; " if lk == 0 else "") + "a plane separates them")
            elif lk is None:
                status, reason = NOT_DETERMINED, "they touch: no linking number"
            elif identify:
                status, reason = _by_polynomial(x0[chains[i][0]], x0[chains[j][0]])
            else:
                status, reason = NOT_DETERMINED, (
                    UNDETERMINED_REASON + "; knot identification off (--knot-samples 0)")
            pairs[key] = {"status": status, "reason": reason}
            if status == LINKED:
                parent[root(index[ids[i]])] = root(index[ids[j]])
    members: dict[int, list[int]] = {}
    for k in rings:
        members.setdefault(root(k), []).append(k)
    groups = sorted((g for g in members.values() if len(g) > 1), key=lambda g: g[0])
    names, entries = [], []
    for g in groups:
        match = [(name, e) for ks, name, e in recorded if ks == g]
        names.append(match[0][0] if match else None)
        entries.append(match[0][1] if match else None)
    return Linkage(pairs, groups, names, entries)
