"""What a figure of a run draws and says: its chains, their bonds and colours, its title.

The one owner for the analysis plots (:mod:`knotmm.analysis.plots`) and the movie
(:mod:`knotmm.movie`): a figure draws only the bonds of the run's layout (none between
chains, none across an open chain's ends), colours beads as ``view.vmd`` does (along the
beads for one chain, one colour per chain for several) and names the system from what
run.toml and the analysis record.
"""

from __future__ import annotations

import numpy as np

from knotmm.analysis.shape import OPEN_KINDS, chains_of
from knotmm.model.layout import ChainLayout

__all__ = ["run_layout", "drawn_bonds", "bead_colors", "system_title"]


def run_layout(data) -> ChainLayout | None:
    """The chains of a loaded run (:func:`knotmm.analysis.shape.chains_of`) as a layout.

    Its bonds are the ones drawn: none between chains, none across an open chain's ends.
    None when the bonds make no layout (a lone bead): then no bond is drawn.
    """
    chains = chains_of(data)
    try:
        return ChainLayout(tuple(s.stop - s.start for s, _ in chains),
                           tuple(c for _, c in chains))
    except ValueError:
        return None


def drawn_bonds(layout: ChainLayout | None) -> np.ndarray:
    """The bonds drawn: the layout's, or none without a layout."""
    return layout.bonds() if layout is not None else np.zeros((0, 2), dtype=np.int64)


def bead_colors(layout: ChainLayout | None, n_beads: int) -> np.ndarray:
    """RGBA colour of every bead, shape (n_beads, 4): as ``view.vmd`` colours them.

    One chain is coloured along its beads (viridis); several chains one colour each
    (tab10, repeating after ten chains).
    """
    import matplotlib

    if layout is None or layout.n_chains == 1:
        return matplotlib.colormaps["viridis"](np.linspace(0.0, 1.0, n_beads, endpoint=False))
    palette = matplotlib.colormaps["tab10"]
    return np.array([palette(c % 10) for c in layout.chain_of_bead()])


def _chain_name(data, index: int) -> str | None:
    """What run.toml says chain ``index`` is (a knot type or template kind), if anything."""
    entries = data.get("knotmm.chains") or []
    entry = entries[index] if index < len(entries) and isinstance(entries[index], dict) else {}
    chains = data.get("chains") or []
    spec = chains[index] if index < len(chains) and isinstance(chains[index], dict) else {}
    kind = spec.get("kind")
    if kind == "torus" and spec.get("p") is not None:
        kind = f"T({spec['p']},{spec.get('q')})"
    return entry.get("knot_type") or entry.get("template_knot_type") or kind


def system_title(data, analysis: dict | None = None) -> str:
    """A title naming the system of a run: ``"T(2,3), N = 90"``, ``"open filament, N = 60"``,
    ``"hopf link, 2 chains (A: 30 beads, ring; B: 30 beads, ring)"``.

    Taken from what run.toml records (and, given the analysis's ``to_dict()``, each chain's
    knot type at the start); a chain whose type is not recorded is named by its beads and
    whether it is a ring.
    """
    layout = run_layout(data)
    n = data.n_beads
    if layout is None or layout.n_chains == 1:
        if layout is not None and not layout.closed[0]:
            kind = data.get("knot.kind")
            shape = f" ({kind})" if kind in OPEN_KINDS else ""
            return f"open filament{shape}, N = {n}"
        kind = data.get("knot.kind")
        if kind == "torus":
            knot = f"T({data.get('knot.p')},{data.get('knot.q')})"
            if data.get("knot.mirror"):
                knot += " mirrored"
        else:
            knot = data.get("knot.name") or kind or "ring"
        return f"{knot}, N = {n}"
    per_chain = (analysis or {}).get("chains") or []
    parts = []
    for c, (cid, count, ring) in enumerate(zip(layout.ids, layout.lengths, layout.closed,
                                               strict=True)):
        found = per_chain[c].get("knot_type_start") if c < len(per_chain) else None
        name = found or _chain_name(data, c)
        named = f"{name}, " if name else ""
        parts.append(f"{cid}: {named}{count} beads, {'ring' if ring else 'open'}")
    link = data.get("knotmm.link")
    prefix = f"{link} link, " if link and "link" not in str(link) else (f"{link}, " if link
                                                                         else "")
    return f"{prefix}{layout.n_chains} chains ({'; '.join(parts)})"
