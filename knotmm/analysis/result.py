"""The analysis result: every reported quantity, its JSON form and a short table."""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from knotmm.analysis.fit import VortexFit
from knotmm.analysis.geometry import Cylindrical
from knotmm.analysis.knot_types import KnotTypes, RunKnot, describe_changes
from knotmm.analysis.regime_report import tilt_row
from knotmm.analysis.shape import SHAPE_FILE, ShapeSeries
from knotmm.analysis.spectra import Spectrum
from knotmm.analysis.window import Window
from knotmm.io.run_data import RunData

__all__ = ["AnalysisResult", "format_table"]


def _clean(value: Any) -> Any:
    """JSON-safe copy: numpy scalars to Python, non-finite floats to None."""
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if isinstance(value, np.ndarray):
        return _clean(value.tolist())
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    return value


def _ratio(num: float, den: float, num_err: float, den_err: float) -> tuple[float, float]:
    if not (den and math.isfinite(den)):
        return float("nan"), float("nan")
    value = num / den
    rel = math.hypot(num_err / num if num else 0.0, den_err / den)
    return value, abs(value) * rel


@dataclass(repr=False)
class AnalysisResult:
    """Everything ``knotmm analyze`` measures on one trajectory, in model units.

    Lengths are in d, times in tau_d, speeds in d/tau_d. ``to_dict()`` is exactly the content
    of ``analysis.json``. The array fields (``data``, ``coords``, the spectra, the fit's
    per-bead phases) are kept for plotting and are not part of the JSON.

    Attributes
    ----------
    sedimentation_velocity, sedimentation_velocity_uncertainty : float
        V, the falling speed of the centre of mass over the window (linear fit of its
        height), positive when falling, and the fit's standard error.
    major_radius, major_radius_std : float
        rho0, the mean bead distance from the vertical axis through the centre of mass over
        the window, and the standard deviation of its per-frame value.
    major_radius_geometric : float
        ``N l0 / (2 pi p)``; NaN (null) unless a torus knot in a flat-torus window.
    p, q : int or None
        The torus knot T(p, q) of the formulas; None for any other knot, a link or an open
        chain (``p_source`` then says ``"not a torus knot"``).
    knot : RunKnot or None
        The run's knot as it recorded it (:func:`knotmm.analysis.knot_types.run_knot`).
    shape : ShapeSeries or None
        Rg, Rg perpendicular to gravity, asphericity, ACN and writhe over the window
        (:mod:`knotmm.analysis.shape`); their window means are the JSON keys of those names,
        their block-bootstrap errors entries of ``uncertainties``.
    swirl_amplitude : float
        C, from the vortex-knot fit; NaN (null) without a detected swirl or a flat torus.
    tau_swirl, tau_rot : float
        Swirl and rotation periods from the spectra (positive), with ``*_uncertainty``; NaN
        (null) where not measured, with the reason in ``notes``: ``tau_rot`` (and its ratio)
        when the window holds less than
        :data:`~knotmm.analysis.window.MIN_ROTATION_FRACTION` of a rotation or its
        uncertainty is as large as the period (:func:`~knotmm.analysis.window.rotation_unmeasured`).
    rotation_frequency : float
        Signed rotation frequency, in 1/tau_d (positive: counterclockwise seen from above);
        NaN (null) where ``tau_rot`` is not measured for want of a window.
    window : Window
    swirl_spectrum, rotation_spectrum : Spectrum
    fit : VortexFit or None
    knots : KnotTypes
    swirl_detected : bool
        False when the swirl test fails (:mod:`knotmm.analysis.detect`) or the window is
        tilted (the lab-frame swirl then mixes tilt and swirl): ``swirl_sense`` is then None
        (and ``tau_swirl`` is None in the JSON).
    extra : dict
        The keys of :func:`knotmm.analysis.regime_report.regime_keys` (body frame, torus
        fraction, swirl detection, bootstrap uncertainties), the elasto-gravitation number,
        an open chain's end-to-end vector (:mod:`knotmm.analysis.objects`), a system's
        ``chains`` and ``system``; merged into ``to_dict()``.
    not_applicable : dict
        ``{key: reason}``: analysis.json keys that do not apply to what was analysed (a
        ring's knot type and torus quantities for an open chain, one structure's for
        separate chains, an end-to-end vector for a ring): ``None`` in ``to_dict()``, which
        also holds this mapping, and "n/a (reason)" in the table.
    """

    sedimentation_velocity: float
    sedimentation_velocity_uncertainty: float
    major_radius: float
    major_radius_std: float
    major_radius_geometric: float
    swirl_amplitude: float
    tau_swirl: float
    tau_swirl_uncertainty: float
    tau_rot: float
    tau_rot_uncertainty: float
    rotation_frequency: float
    rotation_sense: str | None
    writhe: float
    writhe_std: float
    handedness: str | None
    window: Window
    p: int | None
    q: int | None
    p_detected: int | None
    q_detected: int | None
    p_source: str
    q_source: str
    bond_length: float
    swirl_spectrum: Spectrum
    rotation_spectrum: Spectrum
    fit: VortexFit | None
    knots: KnotTypes
    notes: list[str] = field(default_factory=list)
    tilt: dict | None = None
    plots: list[str] = field(default_factory=list)
    swirl_detected: bool = True
    extra: dict = field(default_factory=dict)
    data: RunData | None = field(default=None, repr=False)
    coords: Cylindrical | None = field(default=None, repr=False)
    knot: RunKnot | None = None
    shape: ShapeSeries | None = field(default=None, repr=False)
    not_applicable: dict = field(default_factory=dict)

    # -- display -------------------------------------------------------------------------
    def summary(self) -> str:
        """The plain-text table that ``knotmm analyze`` prints (:func:`format_table`).

        One row per reported quantity (window, knot, V, rho0, the shape measures, periods,
        ratios, senses, writhe, knot type and its changes, fit quality, regime checks), then
        the notes, one per line.
        """
        return format_table(self)

    def __repr__(self) -> str:
        """One line: what was analysed, its frames and duration, and the key results."""
        d = self.to_dict()
        data = self.data
        what = "in-memory trajectory"
        if data is not None and data.directory is not None:
            what = str(Path(data.directory).name or data.directory)
        frames = data.n_frames if data is not None else "?"
        span = float(data.times[-1]) if data is not None and len(data.times) else float("nan")
        knot = d["knot_type"] or d["knot_description"] or "knot ?"
        parts = [
            f"{what}: {frames} frames, {span:g} tau_d",
            f"window {self.window.t0:g}..{self.window.t1:g}",
            f"{knot}",
            f"V = {_fmt(d['sedimentation_velocity'], d['sedimentation_velocity_uncertainty'])}",
            f"Rg = {_fmt(d['radius_of_gyration'])}",
            f"ACN = {_fmt(d['average_crossing_number'])}",
            "swirl " + (f"tau = {_fmt(d['tau_swirl'])}" if d["swirl_detected"] else "none"),
        ]
        if d["knot_type_changes"]:
            parts.append(f"{len(d['knot_type_changes'])} knot-type change(s)")
        return f"<AnalysisResult {'; '.join(parts)}>"

    def _repr_html_(self) -> str:
        """The :meth:`summary` table as HTML, for Jupyter."""
        import html

        rows, notes = _rows(self)
        body = "".join(
            f"<tr><th style='text-align:left'>{html.escape(k)}</th>"
            f"<td style='text-align:left'>{html.escape(v)}</td></tr>"
            for k, v in rows
        )
        foot = "".join(f"<li>{html.escape(n)}</li>" for n in notes)
        return (f"<table><caption>{html.escape(repr(self))}</caption>{body}</table>"
                + (f"<ul>{foot}</ul>" if foot else ""))

    # -- derived -------------------------------------------------------------------------
    @property
    def tau_sed(self) -> float:
        """``2 rho0 / V``, in tau_d: the time to fall one structure diameter."""
        return 2.0 * self.major_radius / self.sedimentation_velocity

    @property
    def tau_sed_uncertainty(self) -> float:
        """Propagated from the uncertainties of rho0 (its std) and V, in tau_d."""
        return _ratio(
            2 * self.major_radius,
            self.sedimentation_velocity,
            2 * self.major_radius_std,
            self.sedimentation_velocity_uncertainty,
        )[1]

    @property
    def swirl_sense(self) -> str | None:
        """How beads circle the cross-section: ``"outward at the top"`` or ``"inward at the top"``.

        Read from the sign of the swirl line of ``(z - <z>) + i (rho - <rho>)``: positive
        means a bead at the top of its cross-section moves away from the vertical axis.
        """
        f = self.swirl_spectrum.peak.frequency
        if not self.swirl_detected or not np.isfinite(f) or f == 0:
            return None
        return "outward at the top" if f > 0 else "inward at the top"

    def ratios(self) -> dict[str, float]:
        """``tau_swirl / tau_sed`` and ``tau_rot / tau_sed`` with propagated uncertainties."""
        t_sed, t_sed_err = self.tau_sed, self.tau_sed_uncertainty
        sw, sw_err = _ratio(self.tau_swirl, t_sed, self.tau_swirl_uncertainty, t_sed_err)
        rot, rot_err = _ratio(self.tau_rot, t_sed, self.tau_rot_uncertainty, t_sed_err)
        return {
            "tau_swirl_over_tau_sed": sw,
            "tau_swirl_over_tau_sed_uncertainty": sw_err,
            "tau_rot_over_tau_sed": rot,
            "tau_rot_over_tau_sed_uncertainty": rot_err,
        }

    def changes(self) -> list[dict]:
        """Every knot-type change, in order (``time``, ``from``, ``to``): the analysis's own
        (frames identified with topoly), or run.toml's record when it identified none."""
        if self.knots.initial is not None:
            return list(self.knots.changes)
        facts = (self.data.get("knotmm", {}) if self.data is not None else {}) or {}
        return [dict(c) for c in facts.get("knot_type_changes", []) or []]

    def _shape_keys(self) -> dict[str, Any]:
        names = ("average_crossing_number", "radius_of_gyration", "radius_of_gyration_perp",
                 "asphericity")
        if self.shape is None:
            return {name: None for name in names} | {"shape_series": None}
        return {name: self.shape.value(name) for name in names} | {"shape_series": SHAPE_FILE}

    def to_dict(self) -> dict[str, Any]:
        """The JSON content (``analysis.json``): model units, non-finite values as null."""
        fit = self.fit.to_dict() if self.fit is not None else None
        quality = None
        if self.fit is not None:
            quality = {
                "r2": self.fit.r2.get("total"),
                "r2_rho": self.fit.r2.get("rho"),
                "r2_alpha": self.fit.r2.get("alpha"),
                "r2_z": self.fit.r2.get("z"),
                "rms": self.fit.rms.get("total"),
                "rms_over_amplitude": fit["rms_over_amplitude"],
                "converged": self.fit.converged,
            }
        data = self.data
        out: dict[str, Any] = {
            "units": {"length": "d", "time": "tau_d", "velocity": "d/tau_d"},
            "sedimentation_velocity": self.sedimentation_velocity,
            "sedimentation_velocity_uncertainty": self.sedimentation_velocity_uncertainty,
            "major_radius": self.major_radius,
            "major_radius_std": self.major_radius_std,
            "major_radius_geometric": self.major_radius_geometric,
            "swirl_amplitude": self.swirl_amplitude,
            "tau_sed": self.tau_sed,
            "tau_sed_uncertainty": self.tau_sed_uncertainty,
            "tau_swirl": self.tau_swirl,
            "tau_swirl_uncertainty": self.tau_swirl_uncertainty,
            "tau_rot": self.tau_rot,
            "tau_rot_uncertainty": self.tau_rot_uncertainty,
            **self.ratios(),
            "rotation_sense": self.rotation_sense,
            "rotation_frequency": self.rotation_frequency,
            "swirl_sense": self.swirl_sense,
            "writhe": self.writhe,
            "writhe_std": self.writhe_std,
            "handedness": self.handedness,
            **self._shape_keys(),
            "knot_type": self.knot.knot_type if self.knot is not None else self.knots.initial,
            "knot_type_source": self.knot.source if self.knot is not None else None,
            "knot_description": self.knot.description if self.knot is not None else None,
            "torus_knot": self.p is not None,
            "knot_type_changes": [
                {"time": c["time"], "from": c["from"], "to": c["to"]} for c in self.changes()
            ],
            "knot_type_initial": self.knots.initial,
            "knot_type_start": self.knots.start,
            "knot_type_end": self.knots.end,
            "knot_type_changed_at": self.knots.changed_at,
            "window": [self.window.t0, self.window.t1],
            "window_info": self.window.to_dict(),
            "p": self.p,
            "q": self.q,
            "p_detected": self.p_detected,
            "q_detected": self.q_detected,
            "p_source": self.p_source,
            "q_source": self.q_source,
            "fit_quality": quality,
            "fit": fit,
            "spectra": {
                "swirl": self.swirl_spectrum.peak.to_dict(),
                "rotation": self.rotation_spectrum.peak.to_dict(),
            },
            "n_beads": data.n_beads if data is not None else None,
            "n_frames": data.n_frames if data is not None else None,
            "frame_interval": data.frame_interval if data is not None else None,
            "bond_length": self.bond_length,
            "source": {
                "trajectory": _relative(data, "trajectory"),
                "topology": _relative(data, "topology"),
                "run_file": _relative(data, "run_file"),
                "knotmm_version": _version(),
            },
            "plots": list(self.plots),
            "tilt": self.tilt,
            **self.extra,  # regime checks, body frame, bootstrap (knotmm.analysis.regime_report)
        }
        for key in self.not_applicable:  # never a number for what does not apply
            out[key] = None
        if isinstance(out.get("uncertainties"), dict):
            out["uncertainties"] = uncertainties = dict(out["uncertainties"])
            for name in uncertainties:
                if _UNCERTAINTY_OF.get(name, name) in self.not_applicable:
                    uncertainties[name] = None
        out["not_applicable"] = dict(self.not_applicable)
        out["notes"] = list(self.notes)
        return _clean(out)


#: The analysis.json key each bootstrap entry of ``uncertainties`` belongs to, where named
#: otherwise.
_UNCERTAINTY_OF = {"swirl_rms": "swirl_amplitude", "swirl_frequency": "tau_swirl"}


def _relative(data: RunData | None, name: str) -> str | None:
    """A source file's path relative to the run directory (absolute if outside it)."""
    path = getattr(data, name, None) if data is not None else None
    if path is None:
        return None
    path = Path(path).resolve()
    if data.directory is not None:
        with contextlib.suppress(ValueError):
            return str(path.relative_to(Path(data.directory).resolve()))
    return str(path)


def _version() -> str:
    from knotmm import __version__

    return __version__


def _fmt(value, err=None, digits: int = 4) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "n/a"
    if isinstance(value, str):
        return value
    text = f"{value:.{digits}g}"
    if err is not None and isinstance(err, float) and math.isfinite(err):
        text += f" +- {err:.2g}"
    return text


def _fmt_signed(value) -> str:
    """A number with its sign always shown (``+2.5``, ``-2.5``), as knot types show theirs."""
    text = _fmt(value)
    positive = isinstance(value, float) and math.isfinite(value) and value > 0
    return f"+{text}" if positive else text


def _knot_row(d: dict) -> str:
    na = d.get("not_applicable") or {}
    if "knot_type" in na:  # an open chain, separate chains
        what, why = d["knot_description"] or "chain", na["knot_type"]
        return f"{what}: no knot type" + ("" if what in why else f" ({why})")
    named = d["knot_type"] or "type not identified"
    if d["knot_type_source"]:
        named += f", from {d['knot_type_source']}"
    if d["p"] is None:
        return f"{d['knot_description'] or 'knot'} ({named}): not a torus knot"
    q = d["q"] if d["q"] is not None else "?"
    return f"T({d['p']},{q})  p from {d['p_source']}  ({named})"


def _with_error(d: dict, name: str) -> str:
    err = ((d.get("uncertainties") or {}).get(name) or {}).get("std_error")
    return _fmt(d.get(name), err)


def _rows(result: AnalysisResult) -> tuple[list[tuple[str, str]], list[str]]:
    """The rows of :func:`format_table` and its notes.

    Rows whose quantities do not apply (``not_applicable``) are left out and named in one
    row per reason: "n/a  rho0, C, tau_sed, ...  (an open chain)".
    """
    d = result.to_dict()
    q = d["fit_quality"] or {}
    knot = d["knot_type_start"]
    if d["knot_type_end"] != d["knot_type_start"]:
        knot = f"{d['knot_type_start']} -> {d['knot_type_end']}"
    changes = describe_changes(d["knot_type_changes"] or [])
    win = result.window
    end = win.end_reason
    if win.collapse_time is not None:
        what = "torus radius" if "major_radius" not in result.not_applicable else (
            "mean radius about the vertical axis")
        end += f"; {what} collapsed at t = {win.collapse_time:g}"
    rho0 = _fmt(d["major_radius"])
    if d["major_radius_geometric"] is not None:
        rho0 += f"   (N l0/(2 pi p) = {_fmt(d['major_radius_geometric'])})"
    rows = [
        ("window [tau_d]", (), f"{win.t0:g} .. {win.t1:g}  ({win.n_frames} frames; end: {end})"),
        ("knot", ("knot_description",), _knot_row(d)),
        ("V [d/tau_d]", ("sedimentation_velocity",),
         _fmt(d["sedimentation_velocity"], d["sedimentation_velocity_uncertainty"])),
        ("rho0 [d]", ("major_radius",), rho0),
        ("Rg [d]", ("radius_of_gyration",), _with_error(d, "radius_of_gyration")),
        ("Rg perp. to gravity [d]", ("radius_of_gyration_perp",),
         _with_error(d, "radius_of_gyration_perp")),
        ("asphericity", ("asphericity",), _with_error(d, "asphericity")),
        ("average crossing number", ("average_crossing_number",),
         _with_error(d, "average_crossing_number")),
        ("end-to-end length [d]", ("end_to_end_length",), _end_to_end(d, "end_to_end_length")),
        ("end-to-end vs vertical [deg]", ("end_to_end_angle_to_vertical_deg",),
         _end_to_end(d, "end_to_end_angle_to_vertical", "_deg") + "  (90: horizontal)"),
        ("B = N^3 F0 l0/A", ("elasto_gravitation_number",),
         _fmt(d.get("elasto_gravitation_number"))),
        ("C [d]", ("swirl_amplitude",), _fmt(d["swirl_amplitude"])),
        ("tau_sed [tau_d]", ("tau_sed",), _fmt(d["tau_sed"], d["tau_sed_uncertainty"])),
        ("tau_swirl [tau_d]", ("tau_swirl",), _fmt(d["tau_swirl"], d["tau_swirl_uncertainty"])),
        ("tau_rot [tau_d]", ("tau_rot",), _fmt(d["tau_rot"], d["tau_rot_uncertainty"])),
        ("tau_swirl/tau_sed", ("tau_swirl_over_tau_sed",),
         _fmt(d["tau_swirl_over_tau_sed"], d["tau_swirl_over_tau_sed_uncertainty"])),
        ("tau_rot/tau_sed", ("tau_rot_over_tau_sed",),
         _fmt(d["tau_rot_over_tau_sed"], d["tau_rot_over_tau_sed_uncertainty"])),
        ("rotation (from above)", ("rotation_sense",), _fmt(d["rotation_sense"])),
        ("swirl", ("swirl_sense",), _fmt(d["swirl_sense"])),
        ("writhe", ("writhe",),
         f"{_fmt_signed(d['writhe'])}  (handedness {_fmt(d['handedness'])})"),
        ("knot type", ("knot_type_start",),
         _fmt(knot) + (f"  (changes: {changes})" if changes else "")),
        ("fit R^2 (rho, alpha, z)", ("fit_quality",),
         ", ".join(_fmt(q.get(k), digits=3) for k in ("r2_rho", "r2_alpha", "r2_z"))),
    ]
    tilt = tilt_row(d)
    if tilt:
        rows.append(("torus axis vs gravity", (), tilt))
        rows.append(("swirl test", (), d["swirl_detection"]["reason"].split(":")[0]))
        body_tau = _fmt(d["tau_swirl_body"], d["tau_swirl_body_uncertainty"])
        rows.append(("tau_swirl body [tau_d]", (), body_tau))
        rows.append(("swirl half-amplitude rho, z [d]", (),
                     f"{_fmt(d['swirl_amplitude_rho'])}, {_fmt(d['swirl_amplitude_z'])}"))
    na = d.get("not_applicable") or {}
    shown = [(label, text) for label, keys, text in rows
             if not (keys and all(k in na for k in keys))]
    for reason in dict.fromkeys(na.values()):  # one row per reason, in order
        names = [_short(label) for label, keys, _ in rows
                 if keys and all(na.get(k) == reason for k in keys)]
        if names:
            shown.append(("n/a", f"{', '.join(names)}  ({reason})"))
    shown += _system_rows(d)
    return shown, list(d["notes"])


def _short(label: str) -> str:
    """A row's label without its unit: ``"rho0 [d]"`` -> ``"rho0"``."""
    return label.split(" [")[0]


def _end_to_end(d: dict, name: str, unit: str = "") -> str:
    """Window mean, then the first and last frame's value of an end-to-end quantity."""
    return (f"{_fmt(d.get(name + unit))}  (start {_fmt(d.get(name + '_start' + unit))}, "
            f"end {_fmt(d.get(name + '_end' + unit))})")


def _system_rows(d: dict) -> list[tuple[str, str]]:
    """One row per chain and per pair of a system of chains (:mod:`knotmm.analysis.chains`)."""
    rows = [(f"chain {c['id']}", _chain_text(c)) for c in d.get("chains") or []]
    system = d.get("system") or {}
    for pair in system.get("pairs", []):
        rows.append((f"chains {pair['chains']}", (
            f"centres {_fmt(pair['distance_start'])} -> {_fmt(pair['distance_end'])} d apart, "
            f"{_fmt(pair.get('separation_angle_to_vertical_start_deg'), digits=3)} -> "
            f"{_fmt(pair.get('separation_angle_to_vertical_end_deg'), digits=3)} deg from the "
            f"vertical; axes {_fmt(pair['axis_angle_start_deg'], digits=3)} -> "
            f"{_fmt(pair['axis_angle_end_deg'], digits=3)} deg")))
    for link in system.get("links", []):
        rows.append((f"link {'-'.join(link['chains'])}", (
            f"{link['link']}: V {_fmt(link.get('sedimentation_velocity'))}; rho0 "
            f"{_fmt(link.get('major_radius'))}; tau_sed {_fmt(link.get('tau_sed'))}; Rg "
            f"{_fmt(link.get('radius_of_gyration'))}; tau_swirl {_fmt(link.get('tau_swirl'))}")))
    if system.get("linked"):
        rows.append(("linked", "; ".join(f"{pair} {v['status']} ({v['reason']})"
                                         for pair, v in system["linked"].items())))
    if system.get("linking_numbers"):
        start, end = system["linking_numbers"], system.get("linking_numbers_end") or {}
        text = ", ".join(f"{k}: {v} -> {end.get(k)}" for k, v in start.items())
        rows.append(("linking numbers", text + (
            f" ({len(system['linking_number_changes'])} changes)"
            if system.get("linking_number_changes") else "")))
    return rows


def _chain_text(c: dict) -> str:
    """One chain of a system in a line: what it is, then what applies to it."""
    speed = _fmt(c.get("sedimentation_velocity"), c.get("sedimentation_velocity_uncertainty"))
    parts = [f"{c['beads']} beads, {'ring' if c['closed'] else 'open'}", f"V {speed}"]
    if c["closed"]:
        parts += [f"knot {_fmt(c.get('knot_type_start'))}", f"rho0 {_fmt(c.get('major_radius'))}",
                  f"tau_sed {_fmt(c.get('tau_sed'))}"]
    parts += [f"Rg {_fmt(c.get('radius_of_gyration'))}",
              f"ACN {_fmt(c.get('average_crossing_number'))}"]
    if c["closed"]:
        parts += [f"tau_swirl {_fmt(c.get('tau_swirl'), c.get('tau_swirl_uncertainty'))}",
                  f"tau_rot {_fmt(c.get('tau_rot'))}"]
    else:
        parts.append(f"end-to-end {_fmt(c.get('end_to_end_length'))} d at "
                     f"{_fmt(c.get('end_to_end_angle_to_vertical_deg'), digits=3)} deg "
                     "to the vertical")
    parts.append(f"B {_fmt(c.get('elasto_gravitation_number'))}")
    return "; ".join(parts)


def format_table(result: AnalysisResult) -> str:
    """A short plain-text table of the reported quantities (:meth:`AnalysisResult.summary`)."""
    rows, notes = _rows(result)
    width = max(len(k) for k, _ in rows)
    lines = [f"{k:<{width}}  {v}" for k, v in rows]
    lines += [f"note: {n}" for n in notes]
    return "\n".join(lines)
