"""A run of several chains analysed: each chain as a run of its own, and the system.

:func:`analyze_system` (called by :func:`knotmm.analysis.core.analyze` for a trajectory of
two or more chains, :func:`knotmm.analysis.shape.chains_of`):

* **each chain** is analysed as a one-chain run (its beads, its bonds, its ``[[chains]]``
  entry as the ``[knot]`` table, its ``[knotmm.chains]`` facts): its V, rho0, Rg, ACN, knot
  type and, where it is a torus knot in a toroidal window, the swirl and rotation periods and
  the vortex-knot fit (``chains`` in analysis.json, one table per chain with its ``id``);
* **the system**: the speed of the centre of mass of all beads (the top-level
  ``sedimentation_velocity``, as for one chain), the whole system's Rg and shape, and per
  pair of chains (``system.pairs``) the distance of their centres of mass and the angle
  between their axes (the normals of their best planes: the smallest principal axis of the
  gyration tensor, an angle in 0-90 degrees) at the start, at the end and over the window;
  the linking numbers of the closed chains at the start and at the end, with every change
  seen in ``samples`` frames (``system.linking_numbers``, ``system.linking_number_changes``).
  The swirl and rotation of a system are its chains': the system's own are not reported.

Units: d, tau_d, degrees.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from knotmm.io.run_data import RunData
from knotmm.model.layout import chain_ids

__all__ = ["analyze_system", "axis_angles", "centre_distances", "linking_series"]

#: Per-chain analysis.json keys kept in the system's ``chains`` tables.
CHAIN_KEYS = (
    "sedimentation_velocity", "sedimentation_velocity_uncertainty", "major_radius",
    "radius_of_gyration", "radius_of_gyration_perp", "asphericity", "average_crossing_number",
    "writhe", "handedness", "knot_type", "knot_type_start", "knot_type_end", "p", "q",
    "tau_swirl", "tau_swirl_uncertainty", "tau_rot", "tau_rot_uncertainty", "swirl_amplitude",
    "swirl_detected", "rotation_sense", "torus_fraction", "window",
)


def centre_distances(positions: np.ndarray, a: slice, b: slice) -> np.ndarray:
    """Distance of the centres of mass of two chains in every frame, shape (n_frames,), d."""
    return np.linalg.norm(positions[:, a].mean(axis=1) - positions[:, b].mean(axis=1), axis=1)


def _normals(x: np.ndarray) -> np.ndarray:
    """Smallest principal axis of each frame's gyration tensor, (n_frames, 3) unit vectors."""
    c = x - x.mean(axis=1, keepdims=True)
    gyration = np.einsum("fni,fnj->fij", c, c) / x.shape[1]
    _, vectors = np.linalg.eigh(gyration)
    return vectors[:, :, 0]


def axis_angles(positions: np.ndarray, a: slice, b: slice) -> np.ndarray:
    """Angle between the axes (best-plane normals) of two chains per frame, degrees, 0-90."""
    cos = np.abs(np.einsum("fi,fi->f", _normals(positions[:, a]), _normals(positions[:, b])))
    return np.degrees(np.arccos(np.clip(cos, 0.0, 1.0)))


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
    config = copy.deepcopy(data.config)
    entries = config.pop("chains", None)
    n_chains_facts = (config.get("knotmm", {}) or {}).get("chains") or []
    knot = {"kind": "component", "closed": closed}
    if isinstance(entries, list) and k < len(entries) and len(entries) == len(n_chains_facts):
        knot = {key: v for key, v in entries[k].items() if key not in ("offset", "rotation")}
        knot["closed"] = closed
    config["knot"] = knot
    facts = dict(config.get("knotmm", {}) or {})
    mine = n_chains_facts[k] if k < len(n_chains_facts) else {}
    for key in ("chains", "layout", "knot_type_changes", "knot_type", "knot_type_start",
                "linking_numbers", "linking_numbers_now", "linking_number_changes"):
        facts.pop(key, None)
    facts.update({key: v for key, v in dict(mine).items() if key not in ("id", "beads", "closed")})
    config["knotmm"] = facts
    start = sl.start
    bonds = np.asarray(data.bonds).reshape(-1, 2)
    inside = (bonds >= start).all(axis=1) & (bonds < sl.stop).all(axis=1)
    return RunData(
        data.times, np.ascontiguousarray(data.positions[:, sl]), bonds[inside] - start, config,
        data.frame_interval, data.trajectory, data.topology, data.run_file, data.directory,
        [],
    )


def _pair_row(positions, sel, a, b, ids) -> dict[str, Any]:
    d = centre_distances(positions, a[1], b[1])
    angle = axis_angles(positions, a[1], b[1])
    return {
        "chains": f"{ids[0]}-{ids[1]}",
        "distance_start": float(d[0]), "distance_end": float(d[-1]),
        "distance_window_mean": float(d[sel].mean()), "distance_min": float(d.min()),
        "axis_angle_start_deg": float(angle[0]), "axis_angle_end_deg": float(angle[-1]),
        "axis_angle_window_mean_deg": float(angle[sel].mean()),
    }


def analyze_system(data: RunData, chains: list[tuple[slice, bool]], analyze_one: Callable,
                   t_from=None, t_to=None, knot_samples: int = 40, fit: bool = True):
    """Analyse a trajectory of several chains (module docstring).

    Parameters
    ----------
    data : RunData
    chains : list of (slice, bool)
        The chains' bead ranges and whether each is closed.
    analyze_one : callable
        The one-chain analysis (:func:`knotmm.analysis.core.analyze` of a single chain),
        called as ``analyze_one(data, t_from=, t_to=, knot_samples=, fit=)``.

    Returns
    -------
    AnalysisResult
        The system's (V of all beads, its shape), with ``extra["chains"]`` and
        ``extra["system"]``.
    """
    ids = chain_ids(len(chains))
    per_chain = []
    for k, (sl, closed) in enumerate(chains):
        result = analyze_one(_chain_data(data, k, sl, closed), t_from=t_from, t_to=t_to,
                             knot_samples=knot_samples if closed else 0, fit=fit)
        row = {key: v for key, v in result.to_dict().items() if key in CHAIN_KEYS}
        per_chain.append({"id": ids[k], "beads": sl.stop - sl.start, "closed": closed, **row,
                          "notes": list(result.notes)})
    whole_config = copy.deepcopy(data.config)
    whole_config["knot"] = {"kind": "system", "closed": True}
    whole = replace(data, config=whole_config, notes=list(data.notes))
    system = analyze_one(whole, t_from=t_from, t_to=t_to, knot_samples=0, fit=False)
    sel = system.window.frames
    pairs = [_pair_row(data.positions, sel, (ids[i], chains[i][0]), (ids[j], chains[j][0]),
                       (ids[i], ids[j]))
             for i in range(len(chains)) for j in range(i + 1, len(chains))]
    rings = [(ids[k], sl) for k, (sl, closed) in enumerate(chains) if closed]
    record: dict[str, Any] = {"n_chains": len(chains), "pairs": pairs}
    if len(rings) > 1:
        start, end, changes = linking_series(data.times, data.positions, rings)
        record.update(linking_numbers=start, linking_numbers_end=end,
                      linking_number_changes=changes)
    nan = float("nan")
    system.tau_swirl = system.tau_swirl_uncertainty = nan
    system.tau_rot = system.tau_rot_uncertainty = system.swirl_amplitude = nan
    system.rotation_sense = None
    system.swirl_detected = False
    system.p = system.q = None
    system.notes = [n for n in system.notes if not _about_one_chain(n)]
    system.notes.insert(0, f"a system of {len(chains)} chains: V, Rg and shape here are the "
                           f"whole system's; each chain's own analysis (its V, knot type, "
                           f"swirl and rotation) is in 'chains', the pairs' distances and "
                           f"angles in 'system'")
    system.extra["chains"] = per_chain
    system.extra["system"] = record
    return system


def _about_one_chain(note: str) -> bool:
    """Notes of the whole-system pass that speak of one chain's swirl, torus or knot."""
    words = ("swirl", "torus", "vortex", "rotation", "knot type", "ring bonds", "p =", "q =",
             "knot identification")
    return any(w in note for w in words)

