"""What each object of a run is measured as: a ring, an open chain, a link, separate chains.

A system is more than one ring (``docs/model.md``, "Several chains, links, open
filaments"), and every quantity the analysis reports belongs to one kind of object:

=====================  ======================================================================
a ring (closed chain)  its knot type; the torus quantities (rho0, tau_sed, C, tau_swirl,
                       tau_rot and their ratios, rotation and swirl senses, the torus axis,
                       the vortex-knot fit for a torus knot)
an open chain          its shape: Rg, asphericity, ACN, the **end-to-end vector** (length, angle
                       to the vertical: 90 degrees is horizontal, broadside); its speed. No
                       knot type (closing it with a straight bond would invent one, and its
                       "changes" would cut the window) and no torus quantities: n/a, with the
                       reason (:data:`OPEN_CHAIN`)
several chains         each chain as a run of its own (:mod:`knotmm.analysis.chains`); the
                       system: its centre of mass speed, the pairs' distances and
                       orientations, the linking numbers. A **link** (rings that cannot be
                       separated) is also one object: its rho0, tau_sed, swirl and rotation
                       measured on all its beads, the torus formulas for a torus link T(p, q);
                       **separate chains** have no one rho0, tau_sed, Rg, ACN or swirl: n/a
                       (:data:`SEPARATE`), each chain's own in ``chains``
every chain            the elasto-gravitation number ``B = N^3 F0 l0 / A``
                       (:func:`knotmm.model.parameters.elasto_gravitation_number`)
=====================  ======================================================================

A quantity that does not apply is ``None`` in analysis.json, named with its reason in
``not_applicable`` (``{key: reason}``), and "n/a (reason)" in the table.

Units: d, tau_d, degrees.
"""

from __future__ import annotations

import math

import numpy as np

from knotmm.analysis.bootstrap import block_bootstrap_mean
from knotmm.analysis.geometry import cylindrical
from knotmm.analysis.knot_types import KnotTypes, handedness, run_knot
from knotmm.analysis.regime_report import TIME_AXIS
from knotmm.analysis.result import AnalysisResult
from knotmm.analysis.shape import shape_series
from knotmm.analysis.spectra import rotation_spectrum, swirl_spectrum
from knotmm.analysis.window import steady_window
from knotmm.errors import ConfigError
from knotmm.model.parameters import ELASTO_GRAVITATION_DEFINITION, elasto_gravitation_number

__all__ = [
    "END_TO_END_KEYS",
    "OPEN_CHAIN",
    "RING_KEYS",
    "SEPARATE",
    "STRUCTURE_KEYS",
    "analyze_open_chain",
    "bond_length_of",
    "elasto_gravitation",
    "elasto_keys",
    "end_to_end",
    "fall_speed",
]

#: The reason an open chain has no ring quantities (``not_applicable``).
OPEN_CHAIN = "an open chain"
#: The reason a ring (or a link) has no end-to-end vector.
RING = "a ring has no ends"
#: The reason a system of separate chains has no one structure.
SEPARATE = "separate chains: each chain's own in 'chains'"

#: analysis.json keys of a ring's knot and toroidal state: n/a for an open chain.
RING_KEYS = (
    "major_radius", "major_radius_std", "major_radius_geometric", "swirl_amplitude",
    "tau_sed", "tau_sed_uncertainty", "tau_swirl", "tau_swirl_uncertainty", "tau_rot",
    "tau_rot_uncertainty", "tau_swirl_over_tau_sed", "tau_swirl_over_tau_sed_uncertainty",
    "tau_rot_over_tau_sed", "tau_rot_over_tau_sed_uncertainty", "rotation_sense",
    "rotation_frequency", "swirl_sense", "swirl_detected", "knot_type", "knot_type_source",
    "knot_type_changes", "knot_type_initial", "knot_type_start", "knot_type_end",
    "knot_type_changed_at", "p", "q", "p_detected", "q_detected", "fit_quality", "fit",
    "spectra", "tilt", "swirl_detection", "tau_swirl_body", "tau_swirl_body_uncertainty",
    "tau_rot_body", "tau_rot_body_uncertainty", "rotation_frequency_body",
    "swirl_amplitude_rho", "swirl_amplitude_z", "torus_fraction", "torus_fraction_window",
    "toroidal_window", "body_frame",
)
#: Keys of one structure's size and shape: n/a for separate chains (besides RING_KEYS).
STRUCTURE_KEYS = RING_KEYS + (
    "radius_of_gyration", "radius_of_gyration_perp", "asphericity", "average_crossing_number",
    "writhe", "writhe_std", "handedness", "shape_series",
)
#: The end-to-end vector of an open chain (window mean, first and last frame).
END_TO_END_KEYS = (
    "end_to_end_length", "end_to_end_length_start", "end_to_end_length_end",
    "end_to_end_angle_to_vertical_deg", "end_to_end_angle_to_vertical_start_deg",
    "end_to_end_angle_to_vertical_end_deg",
)

_OPEN_NOTE = (
    "an open chain: no knot type (a ring's knot type needs a closed curve; closing the chain "
    "with a straight bond would invent one) and no torus quantities (rho0, tau_sed, C, "
    "tau_swirl, tau_rot, their ratios, rotation and swirl senses, the torus axis, the "
    "vortex-knot fit): measured are its speed, Rg, shape, ACN, writhe of the open curve and "
    "its end-to-end vector"
)


def fall_speed(times: np.ndarray, z_com: np.ndarray) -> tuple[float, float]:
    """Falling speed (positive down, d/tau_d) from a line fit, and its standard error."""
    s = times - times.mean()
    slope = float((s * (z_com - z_com.mean())).sum() / (s * s).sum())
    resid = z_com - z_com.mean() - slope * s
    err = math.sqrt(float((resid**2).sum()) / max(len(s) - 2, 1) / float((s * s).sum()))
    return -slope, err


def bond_length_of(data, notes: list) -> float:
    """``model.bond_length`` of the run file, else the median bond at t = 0 (with a note)."""
    bond = data.get("model.bond_length")
    if bond is None:
        x0 = data.positions[0]
        pairs = np.asarray(data.bonds)
        bond = float(np.median(np.linalg.norm(x0[pairs[:, 1]] - x0[pairs[:, 0]], axis=1)))
        notes.append(f"no model.bond_length in a run file: l0 = {bond:.4g} d measured at t = 0")
    return float(bond)


def elasto_gravitation(data, n_beads: int) -> tuple[float | None, str | None]:
    """The chain's ``B = N^3 F0 l0 / A`` from the run file's ``[model]``, or None and why.

    Returns
    -------
    value : float or None
    reason : str or None
        Why there is no value: a key the run file lacks (a bare DCD), or ``A = 0``.
    """
    keys = ("model.gravity", "model.bond_length", "model.bending_stiffness")
    values = [data.get(k) for k in keys]
    missing = [k for k, v in zip(keys, values, strict=True) if v is None]
    if missing:
        return None, f"no {', '.join(missing)} in a run file"
    value = elasto_gravitation_number(n_beads, *values)
    if not math.isfinite(value):
        return None, "model.bending_stiffness = 0: no bending stiffness, B is infinite"
    return value, None


def end_to_end(positions: np.ndarray, chain: slice, frames: slice) -> dict[str, float]:
    """Length and orientation of an open chain's end-to-end vector (last bead - first).

    Parameters
    ----------
    positions : ndarray, shape (n_frames, n_beads, 3)
        In d.
    chain : slice
        The chain's beads.
    frames : slice
        The window (its mean); the first and last frames of the trajectory give
        ``_start`` and ``_end``.

    Returns
    -------
    dict
        :data:`END_TO_END_KEYS`: lengths in d; the angle between the vector and the vertical
        (gravity) in degrees, 0-90: 0 for a vertical chain, 90 for a horizontal one.
    """
    x = np.asarray(positions, dtype=np.float64)[:, chain]
    e = x[:, -1] - x[:, 0]
    length = np.linalg.norm(e, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        angle = np.degrees(np.arccos(np.clip(np.abs(e[:, 2]) / length, 0.0, 1.0)))
    return {
        "end_to_end_length": float(length[frames].mean()),
        "end_to_end_length_start": float(length[0]),
        "end_to_end_length_end": float(length[-1]),
        "end_to_end_angle_to_vertical_deg": float(np.nanmean(angle[frames])),
        "end_to_end_angle_to_vertical_start_deg": float(angle[0]),
        "end_to_end_angle_to_vertical_end_deg": float(angle[-1]),
    }


def elasto_keys(data, n_beads: int, notes: list) -> dict:
    """``elasto_gravitation_number`` and its definition, for analysis.json (a note if none)."""
    value, why = elasto_gravitation(data, n_beads)
    if why is not None:
        notes.append(f"elasto-gravitation number B not known: {why}")
    return {"elasto_gravitation_number": value,
            "elasto_gravitation_definition": ELASTO_GRAVITATION_DEFINITION}


def analyze_open_chain(data, chains, t_from=None, t_to=None, p=None, q=None) -> AnalysisResult:
    """The analysis of one open chain (module docstring): speed, shape, end-to-end vector.

    The window is :func:`knotmm.analysis.window.steady_window`'s on the open chain's own
    signals (speed, Rg, end-to-end length and angle; ``--from``/``--to`` replace its ends);
    no knot type is identified and no torus radius looked at, so neither cuts it.

    Raises
    ------
    ConfigError
        For ``--p``/``--q``: an open chain is no torus knot.
    """
    if p is not None or q is not None:
        raise ConfigError("--p/--q: this run is an open chain, which has no knot type and no "
                          "torus; leave them out")
    notes = [n for n in data.notes if "no bond closing the ring" not in n]
    times, positions = data.times, data.positions
    window = steady_window(times, positions, t_from=t_from, t_to=t_to, open_chain=True)
    notes += window.notes
    sel = window.frames
    coords = cylindrical(positions)
    velocity, velocity_err = fall_speed(times[sel], coords.com[sel, 2])
    bond = bond_length_of(data, notes)
    shape = shape_series(times, positions, chains, sel)
    nan = float("nan")
    extra = dict(end_to_end(positions, chains[0][0], sel))
    extra.update(elasto_keys(data, data.n_beads, notes))
    uncertainties = {name: {k: v for k, v in stats.items() if k != "std"}
                     for name, stats in shape.stats.items()}
    if len(times) > 2:
        speeds = -np.diff(coords.com[sel, 2]) / np.diff(times[sel])
        mean, err, block, tau = block_bootstrap_mean(speeds)
        uncertainties["sedimentation_velocity"] = {
            "value": mean, "std_error": err, "block_frames": block,
            "autocorrelation_frames": tau}
    extra.update(uncertainties=uncertainties, time_axis=TIME_AXIS)
    notes.append(_OPEN_NOTE)
    wr = shape.value("writhe")
    result = AnalysisResult(
        sedimentation_velocity=velocity, sedimentation_velocity_uncertainty=velocity_err,
        major_radius=nan, major_radius_std=nan, major_radius_geometric=nan,
        swirl_amplitude=nan, tau_swirl=nan, tau_swirl_uncertainty=nan, tau_rot=nan,
        tau_rot_uncertainty=nan, rotation_frequency=nan, rotation_sense=None,
        writhe=wr, writhe_std=shape.stats["writhe"]["std"], handedness=handedness(wr),
        window=window, p=None, q=None, p_detected=None, q_detected=None,
        p_source=OPEN_CHAIN, q_source=OPEN_CHAIN, bond_length=bond,
        # the spectra are kept for the plotting functions; analysis.json reports none
        swirl_spectrum=swirl_spectrum(times[sel], coords.rho[sel], coords.z[sel]),
        rotation_spectrum=rotation_spectrum(times[sel], coords.alpha[sel]),
        fit=None, knots=KnotTypes(None, None, None), notes=notes, tilt=None,
        swirl_detected=False, extra=extra, data=data, coords=coords,
        knot=run_knot(data, chains), shape=shape,
    )
    result.not_applicable = dict.fromkeys(RING_KEYS, OPEN_CHAIN)
    return result
