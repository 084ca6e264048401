"""A run of several chains analysed: each chain as a run of its own, and the system.

:func:`analyze_system` (called by :func:`knotmm.analysis.core.analyze` for a trajectory of
two or more chains, :func:`knotmm.analysis.shape.chains_of`), in the terms of
:mod:`knotmm.analysis.objects`:

* **each chain** is analysed as a one-chain run (its beads, its bonds, its ``[[chains]]``
  entry as the ``[knot]`` table, its ``[knotmm.chains]`` facts): a ring its V, rho0, tau_sed,
  Rg, ACN, knot type and, where it swirls, its swirl and rotation periods (the vortex-knot
  fit for a torus knot); an open chain its V, Rg, shape and end-to-end vector, no knot type
  and no torus quantities; every chain its elasto-gravitation number B (``chains`` in
  analysis.json, one table per chain with its ``id`` and its ``not_applicable``);
* **the system**: the speed of the centre of mass of all beads (the top-level
  ``sedimentation_velocity``), and per pair of chains (``system.pairs``) the distance of
  their centres of mass, the angle of the line joining them to the vertical (0: one above
  the other, 90: side by side) and the angle between their axes (a ring's axis is the normal
  of its best plane, the smallest principal axis of its gyration tensor; an open chain's is
  its long axis, the largest; an angle in 0-90 degrees) at the start, at the end and over the
  window; the linking numbers of the closed chains at the start and at the end, with every
  change seen in ``samples`` frames (``system.linking_numbers``,
  ``system.linking_number_changes``); ``system.kind``: ``"link"`` or ``"separate chains"``.
* **a link** (every chain a ring, joined by nonzero linking numbers or built as a link) is
  one object besides: its rho0, tau_sed, Rg, ACN, writhe, swirl and rotation are measured
  on all its beads, with the torus formulas and the vortex-knot fit for a torus link T(p, q)
  (:func:`knotmm.analysis.knot_types.torus_link`); where its own swirl is not measured but
  every ring's is, and they agree within 5 %, ``tau_swirl`` is their mean
  (``tau_swirl_source``: ``"chains"``). **Separate chains** are no one structure: the
  system's rho0, tau_sed, Rg, ACN, swirl and rotation are n/a, each chain's own in
  ``chains``.

Units: d, tau_d, degrees.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from knotmm.analysis.linkage import NOT_DETERMINED, entry_chains, linkage
from knotmm.analysis.objects import END_TO_END_KEYS, RING_KEYS, SEPARATE, STRUCTURE_KEYS
from knotmm.io.run_data import RunData
from knotmm.model.layout import chain_ids

__all__ = ["analyze_system", "axis_angles", "centre_distances", "linking_series",
           "separation_angles"]

#: Per-chain analysis.json keys kept in the system's ``chains`` tables.
CHAIN_KEYS = (
    "sedimentation_velocity", "sedimentation_velocity_uncertainty", "major_radius",
    "major_radius_std", "major_radius_geometric", "tau_sed", "tau_sed_uncertainty",
    "radius_of_gyration", "radius_of_gyration_perp", "asphericity", "average_crossing_number",
    "writhe", "handedness", "knot_description", "knot_type", "knot_type_start",
    "knot_type_end", "knot_type_changes", "torus_knot", "p", "q", "tau_swirl",
    "tau_swirl_uncertainty", "tau_rot", "tau_rot_uncertainty", "tau_swirl_over_tau_sed",
    "tau_rot_over_tau_sed", "swirl_amplitude", "swirl_detected", "rotation_sense",
    "torus_fraction", "window", *END_TO_END_KEYS, "elasto_gravitation_number",
    "not_applicable",
)
#: Why the system has no elasto-gravitation number or end-to-end vector of its own.
PER_CHAIN = "per chain: see 'chains'"
#: Why a link has no one knot type.
LINK_KNOT = "a link: each ring's knot type in 'chains', the linking numbers in 'system'"
#: Centres of mass closer than this (d, a fifth of the steric range) share their place: the
#: line joining them has no direction to report (a torus link's congruent rings share their
#: centre up to rounding), the angle of that line is n/a.
COINCIDENT = 0.1
#: Relative difference of the rings' swirl periods within which they are one link's swirl.
SWIRL_AGREEMENT = 0.05


def centre_distances(positions: np.ndarray, a: slice, b: slice) -> np.ndarray:
    """Distance of the centres of mass of two chains in every frame, shape (n_frames,), d."""
    return np.linalg.norm(positions[:, a].mean(axis=1) - positions[:, b].mean(axis=1), axis=1)


def _axes(x: np.ndarray, closed: bool = True) -> np.ndarray:
    """A chain's axis per frame, (n_frames, 3) unit vectors: a ring's best-plane normal (the
    smallest principal axis of the gyration tensor), an open chain's long axis (the largest)."""
    c = x - x.mean(axis=1, keepdims=True)
    gyration = np.einsum("fni,fnj->fij", c, c) / x.shape[1]
    _, vectors = np.linalg.eigh(gyration)
    return vectors[:, :, 0 if closed else -1]


def axis_angles(positions: np.ndarray, a: slice, b: slice,
                closed: tuple[bool, bool] = (True, True)) -> np.ndarray:
    """Angle between the axes of two chains per frame (:func:`_axes`), degrees, 0-90."""
    cos = np.abs(np.einsum("fi,fi->f", _axes(positions[:, a], closed[0]),
                           _axes(positions[:, b], closed[1])))
    return np.degrees(np.arccos(np.clip(cos, 0.0, 1.0)))


def separation_angles(positions: np.ndarray, a: slice, b: slice) -> np.ndarray:
    """Angle between the line joining two chains' centres of mass and the vertical, per
    frame, degrees, 0-90: 0 when one is above the other, 90 when side by side."""
    e = positions[:, b].mean(axis=1) - positions[:, a].mean(axis=1)
    length = np.linalg.norm(e, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        angle = np.degrees(np.arccos(np.clip(np.abs(e[:, 2]) / length, 0.0, 1.0)))
    return np.where(length > COINCIDENT, angle, np.nan)  # one centre on the other: no line


def linking_series(times, positions, rings: list[tuple[str, slice]], samples: int = 40):
    """Linking numbers of every pair of closed chains in ``samples`` frames (and the last).

    Returns
    -------
    start, end : dict
        ``{"A-B": Lk}`` at the first and the last frame (None for a pair that touches).
    changes : list of dict
        ``{"time", "chains", "from", "to"}`` for every change between sampled frames.
    """
    from knotmm.knots.linking import linking_number

    n = len(times)
    frames = sorted({*np.linspace(0, n - 1, min(n, max(2, samples))).round().astype(int)})
    pairs = [(i, j) for i in range(len(rings)) for j in range(i + 1, len(rings))]
    series = []
    for f in frames:
        row = {}
        for i, j in pairs:
            try:
                row[f"{rings[i][0]}-{rings[j][0]}"] = linking_number(positions[f, rings[i][1]],
                                                                     positions[f, rings[j][1]])
            except ValueError:
                row[f"{rings[i][0]}-{rings[j][0]}"] = None
        series.append(row)
    changes = []
    for f, before, after in zip(frames[1:], series[:-1], series[1:], strict=True):
        for pair, lk in after.items():
            if lk is not None and before.get(pair) is not None and lk != before[pair]:
                changes.append({"time": float(times[f]), "chains": pair,
                                "from": before[pair], "to": lk})
    return series[0], series[-1], changes


def _chain_data(data: RunData, k: int, sl: slice, closed: bool) -> RunData:
    """Chain ``k`` of ``data`` as a run of its own (its run-file entry and facts)."""
    return _subset(data, [k], [sl], {"kind": "component", "closed": closed})


def _subset(data: RunData, ks: list[int], slices: list[slice], default_knot: dict,
            extra_facts: dict | None = None) -> RunData:
    """Chains ``ks`` (bead ranges ``slices``, consecutive) of ``data`` as a run of their own.

    The ``[knot]`` table is the ``[[chains]]`` entry that built exactly these chains (a chain
    of its own, or a link entry's components together), else ``default_knot``; ``[knotmm]``
    keeps the run's facts but those of the whole system, with one chain's own facts
    (``[[knotmm.chains]]``) for one chain, ``extra_facts`` for several.
    """
    config = copy.deepcopy(data.config)
    entries = config.pop("chains", None)
    chain_facts = (config.get("knotmm", {}) or {}).get("chains") or []
    lengths = [s.stop - s.start for s, _ in _all_chains(data)]
    built = entry_chains(entries, lengths) if lengths else None
    if built is None and isinstance(entries, list) and len(entries) == len(lengths):
        built = [[k] for k in range(len(lengths))]  # entries without their bead counts
    knot = dict(default_knot)
    if built is not None and ks in built:
        entry = entries[built.index(ks)]
        knot = {key: v for key, v in entry.items() if key not in ("offset", "rotation")}
        knot["closed"] = default_knot.get("closed", True)
    config["knot"] = knot
    facts = dict(config.get("knotmm", {}) or {})
    for key in ("chains", "layout", "knot_type_changes", "knot_type", "knot_type_start",
                "linking_numbers", "linking_numbers_now", "linking_number_changes", "link",
                "links", "elasto_gravitation_numbers"):
        facts.pop(key, None)
    if len(ks) == 1:
        mine = chain_facts[ks[0]] if ks[0] < len(chain_facts) else {}
        facts.update({key: v for key, v in dict(mine).items()
                      if key not in ("id", "beads", "closed")})
    facts.update(extra_facts or {})
    config["knotmm"] = facts
    start, stop = slices[0].start, slices[-1].stop
    bonds = np.asarray(data.bonds).reshape(-1, 2)
    inside = (bonds >= start).all(axis=1) & (bonds < stop).all(axis=1)
    return RunData(
        data.times, np.ascontiguousarray(data.positions[:, start:stop]), bonds[inside] - start,
        config, data.frame_interval, data.trajectory, data.topology, data.run_file,
        data.directory, [],
    )


def _all_chains(data: RunData) -> list[tuple[slice, bool]]:
    from knotmm.analysis.shape import chains_of

    return chains_of(data)


def _pair_row(positions, sel, a, b, ids) -> dict[str, Any]:
    """``a``, ``b``: ``(slice, closed)`` of two chains; ``ids`` their names."""
    d = centre_distances(positions, a[0], b[0])
    angle = axis_angles(positions, a[0], b[0], (a[1], b[1]))
    vertical = separation_angles(positions, a[0], b[0])
    return {
        "chains": f"{ids[0]}-{ids[1]}",
        "distance_start": float(d[0]), "distance_end": float(d[-1]),
        "distance_window_mean": float(d[sel].mean()), "distance_min": float(d.min()),
        "separation_angle_to_vertical_start_deg": float(vertical[0]),
        "separation_angle_to_vertical_end_deg": float(vertical[-1]),
        "separation_angle_to_vertical_window_mean_deg": _mean(vertical[sel]),
        "axis_angle_start_deg": float(angle[0]), "axis_angle_end_deg": float(angle[-1]),
        "axis_angle_window_mean_deg": float(angle[sel].mean()),
        "axes": "-".join("normal" if closed else "long axis" for closed in (a[1], b[1])),
    }


def _mean(values: np.ndarray) -> float:
    """Mean of the finite values, NaN (null) when there are none."""
    finite = values[np.isfinite(values)]
    return float(finite.mean()) if finite.size else float("nan")


def one_link(chains: list[tuple[slice, bool]], links) -> str | None:
    """The link's name when the whole system is one link (every chain a ring, all of them in
    one group of :func:`knotmm.analysis.linkage.linkage`), else None."""
    if len(chains) < 2 or len(links.groups) != 1 or len(links.groups[0]) != len(chains):
        return None
    return links.names[0] or "linked rings"


def _swirl_from_chains(system, per_chain: list[dict]) -> None:
    """A link's tau_swirl: its own, checked against its rings', or else theirs (docstring)."""
    own = system.tau_swirl
    theirs = [c.get("tau_swirl") for c in per_chain]
    measured = [t for t in theirs if t is not None]
    if np.isfinite(own):
        system.extra["tau_swirl_source"] = "the link's beads"
        off = [f"{c['id']} {t:.4g}" for c, t in zip(per_chain, theirs, strict=True)
               if t is not None and abs(t - own) > SWIRL_AGREEMENT * own]
        if off:
            system.notes.append(
                f"the link's tau_swirl ({own:.4g} tau_d) and its rings' differ by more than "
                f"{SWIRL_AGREEMENT:.0%}: {', '.join(off)} tau_d")
        return
    if len(measured) == len(per_chain) and np.ptp(measured) <= SWIRL_AGREEMENT * min(measured):
        system.tau_swirl = float(np.mean(measured))
        errors = [c.get("tau_swirl_uncertainty") for c in per_chain]
        errors = [e for e in errors if e is not None]
        system.tau_swirl_uncertainty = (float(np.sqrt(np.mean(np.square(errors))))
                                        if errors else float("nan"))
        system.extra["tau_swirl_source"] = "chains"
        system.notes.append(
            f"tau_swirl of the link = {system.tau_swirl:.4g} tau_d, the mean of its rings' "
            f"({', '.join(f'{t:.4g}' for t in measured)}; within {SWIRL_AGREEMENT:.0%}): the "
            "swirl of all its beads was not measured")
    else:
        system.extra["tau_swirl_source"] = None


def analyze_system(data: RunData, chains: list[tuple[slice, bool]], analyze_one: Callable,
                   t_from=None, t_to=None, knot_samples: int = 40, fit: bool = True):
    """Analyse a trajectory of several chains (module docstring).

    Parameters
    ----------
    data : RunData
    chains : list of (slice, bool)
        The chains' bead ranges and whether each is closed.
    analyze_one : callable
        The one-chain analysis (:func:`knotmm.analysis.core._analyze_one`), called as
        ``analyze_one(data, t_from=, t_to=, knot_samples=, fit=, part_of=)``.

    Returns
    -------
    AnalysisResult
        The system's (V of all beads; a link's structure), with ``extra["chains"]`` and
        ``extra["system"]``.
    """
    ids = chain_ids(len(chains))
    what = f"{len(chains)}-chain system"
    per_chain = []
    for k, (sl, closed) in enumerate(chains):
        result = analyze_one(_chain_data(data, k, sl, closed), t_from=t_from, t_to=t_to,
                             knot_samples=knot_samples if closed else 0, fit=fit, part_of=what)
        row = {key: v for key, v in result.to_dict().items() if key in CHAIN_KEYS}
        per_chain.append({"id": ids[k], "beads": sl.stop - sl.start, "closed": closed, **row,
                          "notes": list(result.notes)})
    rings = [(ids[k], sl) for k, (sl, closed) in enumerate(chains) if closed]
    record: dict[str, Any] = {"n_chains": len(chains)}
    start = {}
    if len(rings) > 1:
        start, end, changes = linking_series(data.times, data.positions, rings)
        record.update(linking_numbers=start, linking_numbers_end=end,
                      linking_number_changes=changes)
    links = linkage(data, chains, start, identify=knot_samples > 0)
    if links.pairs:
        record["linked"] = links.pairs
    link = one_link(chains, links)
    objects = _link_objects(data, chains, links, analyze_one, t_from, t_to, fit) if (
        link is None) else []
    record["kind"] = _kind(link, objects, links)
    if objects:
        record["links"] = objects
    whole_config = copy.deepcopy(data.config)
    if link is None:
        whole_config["knot"] = {"kind": "system", "closed": True}
    whole = replace(data, config=whole_config, notes=list(data.notes))
    system = analyze_one(whole, t_from=t_from, t_to=t_to, knot_samples=0,
                         fit=fit and link is not None, part_of=what)
    sel = system.window.frames
    record["pairs"] = [
        _pair_row(data.positions, sel, chains[i], chains[j], (ids[i], ids[j]))
        for i in range(len(chains)) for j in range(i + 1, len(chains))]
    system.not_applicable.update(dict.fromkeys(
        (*END_TO_END_KEYS, "elasto_gravitation_number"), PER_CHAIN))
    system.notes = [n for n in system.notes
                    if "knot identification skipped" not in n and "elasto-gravitation" not in n]
    if link is None:
        system.notes = [n for n in system.notes if not _about_one_chain(n)]
        why = _why_no_structure(record["kind"], objects, links)
        system.not_applicable.update(dict.fromkeys(STRUCTURE_KEYS, why))
        system.notes.insert(0, (
            f"a system of {len(chains)} chains ({record['kind']}): V here is the speed of the "
            "centre of mass of all beads; rho0, tau_sed, Rg, ACN, swirl and rotation belong to "
            "each chain ('chains')" + (", each link's to that link ('system.links')"
                                        if objects else "")
            + ", the pairs' distances and orientations and the linking numbers to 'system'"))
        for pair in links.undetermined:
            system.notes.append(f"chains {pair}: linked or not is not determined "
                                f"({links.pairs[pair]['reason']}); analysed as separate chains")
    else:
        knot_keys = [k for k in RING_KEYS if k.startswith("knot_type")]
        system.not_applicable.update(dict.fromkeys(knot_keys, LINK_KNOT))
        _swirl_from_chains(system, per_chain)
        torus = (f"the torus link T({system.p},{system.q}): the vortex-knot formulas apply"
                 if system.p is not None else "not a torus link: no torus formulas")
        system.notes.insert(0, (
            f"a link ({link}) of {len(chains)} rings, analysed as one object: V, rho0, "
            f"tau_sed, Rg, ACN, swirl and rotation here are measured on all its beads, "
            f"{torus}; each ring's own in 'chains'"))
    system.extra["chains"] = per_chain
    system.extra["system"] = record
    return system


#: analysis.json keys of a link object among other chains (``system.links``).
LINK_KEYS = tuple(k for k in CHAIN_KEYS if k not in END_TO_END_KEYS) + (
    "tau_swirl_source", "p_source", "q_source")


def _link_objects(data, chains, links, analyze_one, t_from, t_to, fit) -> list[dict]:
    """Each link among other chains analysed as one object: its rings' beads as a run of
    their own (the link's ``[[chains]]`` entry as its ``[knot]`` table), through this same
    analysis, so that it equals those beads analysed alone."""
    from knotmm.analysis.shape import chains_of

    ids = chain_ids(len(chains))
    objects = []
    for group, name in zip(links.groups, links.names, strict=True):
        slices = [chains[k][0] for k in group]
        if any(a.stop != b.start for a, b in zip(slices[:-1], slices[1:], strict=False)):
            continue  # the rings of a link found by its linking numbers, apart in bead order
        facts = {"link": name or "linked rings"}  # found linked here: one link alone too
        alone = _subset(data, group, slices, {"kind": "link", "closed": True}, facts)
        result = analyze_system(alone, chains_of(alone), analyze_one, t_from=t_from,
                                t_to=t_to, knot_samples=0, fit=fit)
        d = result.to_dict()
        objects.append({"chains": [ids[k] for k in group], "link": name or "linked rings",
                        **{key: d.get(key) for key in LINK_KEYS}, "notes": list(result.notes)})
    return objects


def _kind(link, objects, links) -> str:
    """``system.kind``: what the system is, in words."""
    if link is not None:
        return "link"
    if links.undetermined:
        return "chains whose linking is " + NOT_DETERMINED
    if links.groups:
        return "links and separate chains"
    return "separate chains"


def _why_no_structure(kind: str, objects, links) -> str:
    """Why the system as a whole has no rho0, Rg, swirl, ... (``not_applicable``)."""
    if links.undetermined:
        return f"{kind} ({', '.join(links.undetermined)}): each chain's own in 'chains'"
    if links.groups:
        return ("links and separate chains: each link's own in 'system.links', each chain's "
                "in 'chains'")
    return SEPARATE


def _about_one_chain(note: str) -> bool:
    """Notes of the whole-system pass that speak of one chain's swirl, torus or knot."""
    words = ("swirl", "torus", "vortex", "rotation", "knot type", "ring bonds", "p =", "q =",
             "knot identification")
    return any(w in note for w in words)
