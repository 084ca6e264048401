"""What ``knotmm orbit`` writes: ``orbit.json``, the orbit and its leading mode for VMD, a plot.

Files (names owned here):

* ``orbit.json``: see :func:`orbit_summary` for every key.
* ``orbit.dcd`` + ``topology.pdb``: one period of the orbit, ``ORBIT_FRAMES + 1`` frames
  (the last one is the first fallen and turned by the orbit's translation and rotation).
* ``mode_1.dcd``: the orbit with the leading Floquet mode added, carried along the orbit by
  the linearised flow and scaled to ``MODE_AMPLITUDE`` d rms per bead in every frame, so
  that VMD shows how the shape departs from the orbit.
* ``orbit_multipliers.png``: the multipliers in the complex plane with the unit circle.
"""

from __future__ import annotations

import json
import math

import numpy as np

from knotmm.io.atomic import write_text_atomic
from knotmm.io.rundir import TOPOLOGY_FILE as TOPOLOGY
from knotmm.orbit.flow import JVP_EPSILON, rms

__all__ = ["ORBIT_FILE", "orbit_summary", "write_orbit_files", "plot_multipliers"]

ORBIT_FILE = "orbit.json"
ORBIT_DCD = "orbit.dcd"
MODE_DCD = "mode_1.dcd"
PLOT = "orbit_multipliers.png"
#: Frames per period in ``orbit.dcd`` and ``mode_1.dcd``.
ORBIT_FRAMES = 60
#: Size of the mode drawn in ``mode_1.dcd``, d rms per bead.
MODE_AMPLITUDE = 0.5


def _pairs(values) -> list:
    return [[float(np.real(v)), float(np.imag(v))] for v in values]


def _finite(value):
    value = float(value)
    return value if math.isfinite(value) else None


def orbit_summary(orbit, result=None, shape=None, extra: dict | None = None) -> dict:
    """The content of ``orbit.json``.

    Keys: ``status`` ("converged" or "did not converge"), ``message``, ``period`` (tau_d),
    ``rotation_per_period`` (rad, positive counterclockwise from above), ``tau_rot``
    (``2 pi T / |rotation|``, tau_d; null without rotation), ``sedimentation_velocity``
    (d/tau_d, downward positive), ``rho0`` (mean horizontal distance of the beads from the
    vertical axis through the centroid, d), ``tau_sed`` (``2 rho0 / V``), the ratios
    ``tau_swirl_over_tau_sed`` and ``tau_rot_over_tau_sed``, ``residual`` (d rms per bead),
    ``newton_iterations``, ``residual_history``, ``n_beads``; with a Floquet analysis
    ``floquet_multipliers`` (``[re, im]`` by decreasing modulus, neutral ones excluded),
    ``floquet_moduli``, ``neutral_multipliers`` (``{"symmetry", "multiplier"}``),
    ``leading_exponent`` (``ln |mu_1| / T``, 1/tau_d), ``unstable_multipliers`` (how many
    lie outside the unit circle), ``leading_mode`` (a short description) and
    ``leading_mode_shape`` (its fractions); null where not measured.
    """
    x = orbit.positions
    v = orbit.sedimentation_velocity
    rho0 = float(np.mean(np.hypot(x[:, 0], x[:, 1])))
    tau_sed = 2 * rho0 / v if v > 0 else math.nan
    tau_rot = 2 * math.pi * orbit.period / abs(orbit.rotation) if orbit.rotation else math.nan
    out = {
        "status": "converged" if orbit.converged else "did not converge",
        "message": orbit.message,
        "n_beads": orbit.n_beads,
        "period": orbit.period,
        "rotation_per_period": orbit.rotation,
        "tau_rot": _finite(tau_rot),
        "sedimentation_velocity": v,
        "rho0": rho0,
        "tau_sed": _finite(tau_sed),
        "tau_swirl_over_tau_sed": _finite(orbit.period / tau_sed),
        "tau_rot_over_tau_sed": _finite(tau_rot / tau_sed),
        "residual": orbit.residual,
        "newton_iterations": orbit.iterations,
        "residual_history": [float(r) for r in orbit.history],
        "floquet_multipliers": None,
        "floquet_moduli": None,
        "neutral_multipliers": None,
        "leading_exponent": None,
        "unstable_multipliers": None,
        "leading_mode": None,
        "leading_mode_shape": None,
    }
    if result is not None:
        out.update({
            "floquet_multipliers": _pairs(result.multipliers),
            "floquet_moduli": [float(abs(m)) for m in result.multipliers],
            "neutral_multipliers": [
                {"symmetry": name, "multiplier": _pairs([m])[0]}
                for name, m in zip(result.neutral_names, result.neutral, strict=False)
            ],
            "leading_exponent": _finite(result.leading_exponent),
            "unstable_multipliers": result.n_unstable,
            "arnoldi_converged": result.converged,
        })
    if shape is not None:
        out["leading_mode"] = shape.describe()
        out["leading_mode_shape"] = {
            "label": shape.label, "tilt": shape.tilt, "out_of_plane": shape.out_of_plane,
            "radial": shape.radial, "tangential": shape.tangential, "m": shape.m,
        }
    out.update(extra or {})
    return out


def write_json(path, summary: dict) -> None:
    """Write ``summary`` as indented JSON, atomically."""
    write_text_atomic(path, json.dumps(summary, indent=2) + "\n")


def _mode_frames(flow, orbit, mode: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """The orbit plus the mode carried along it by the linearised flow, fixed size."""
    v = np.real(mode) if np.iscomplexobj(mode) else mode
    v = np.asarray(v, dtype=float)
    eps = JVP_EPSILON / max(rms(v), 1e-300)
    moved = flow.trajectory(orbit.positions + eps * v, orbit.period, len(frames) - 1)
    out = np.empty_like(frames)
    for k, (base, pert) in enumerate(zip(frames, moved, strict=False)):
        d = pert - base
        d -= d.mean(axis=0)
        size = rms(d)
        out[k] = base + (MODE_AMPLITUDE / size * d if size > 0 else 0.0)
    return out


def plot_multipliers(result, path, title: str = "") -> None:
    """Multipliers in the complex plane with the unit circle (neutral ones as open marks)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(4.5, 4.5))
    t = np.linspace(0, 2 * np.pi, 361)
    ax.plot(np.cos(t), np.sin(t), color="0.6", lw=1)
    ax.plot(result.multipliers.real, result.multipliers.imag, "o", color="C3",
            label="Floquet multipliers")
    ax.plot(result.neutral.real, result.neutral.imag, "s", mfc="none", color="C0",
            label="neutral (symmetries)")
    ax.axhline(0, color="0.85", lw=0.8)
    ax.axvline(0, color="0.85", lw=0.8)
    ax.set_aspect("equal")
    ax.set_xlabel("Re mu")
    ax.set_ylabel("Im mu")
    ax.set_title(title or f"T = {result.period:.4g} tau_d", fontsize=10)
    ax.legend(loc="lower left", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def write_orbit_files(out, flow, orbit, result=None, summary: dict | None = None) -> list:
    """Write every file of an orbit into ``out`` (created); return the names written."""
    from knotmm.io.dcd import write_dcd
    from knotmm.io.pdb import write_pdb

    out.mkdir(parents=True, exist_ok=True)
    written = []
    frames = flow.trajectory(orbit.positions, orbit.period, ORBIT_FRAMES)
    write_pdb(out / TOPOLOGY, orbit.positions)
    write_dcd(out / ORBIT_DCD, frames)
    written += [TOPOLOGY, ORBIT_DCD]
    if result is not None and len(result.multipliers):
        write_dcd(out / MODE_DCD, _mode_frames(flow, orbit, result.modes[0], frames))
        plot_multipliers(result, out / PLOT)
        written += [MODE_DCD, PLOT]
    if summary is not None:
        write_json(out / ORBIT_FILE, summary)
        written.append(ORBIT_FILE)
    return written


BRANCH_CSV = "continuation.csv"
BRANCH_JSON = "continuation.json"
BRANCH_PLOT = "continuation.png"


def branch_rows(key: str, branch, modes: int) -> list[dict]:
    """One row per point: the parameter, the orbit's numbers, the multipliers' moduli/angles."""
    rows = []
    for point in branch:
        s = orbit_summary(point.orbit, point.floquet)
        row = {key: point.value}
        for name in ("period", "rotation_per_period", "sedimentation_velocity", "rho0",
                     "tau_sed", "tau_swirl_over_tau_sed", "tau_rot_over_tau_sed", "residual",
                     "leading_exponent", "unstable_multipliers"):
            row[name] = s[name]
        mult = [] if point.floquet is None else list(point.floquet.multipliers)
        for k in range(modes):
            mu = mult[k] if k < len(mult) else None
            row[f"mu{k + 1}_abs"] = None if mu is None else float(abs(mu))
            row[f"mu{k + 1}_arg"] = None if mu is None else float(np.angle(mu))
        rows.append(row)
    return rows


def write_branch(out, key: str, branch, bifurcations, modes: int, extra: dict) -> list:
    """Write ``continuation.csv``, ``continuation.json`` and ``continuation.png``."""
    import csv
    import io

    out.mkdir(parents=True, exist_ok=True)
    rows = branch_rows(key, branch, modes)
    text = io.StringIO()
    if rows:
        writer = csv.DictWriter(text, fieldnames=list(rows[0]), lineterminator="\n")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: ("" if v is None else v) for k, v in row.items()})
    write_text_atomic(out / BRANCH_CSV, text.getvalue())
    write_json(out / BRANCH_JSON, {
        "parameter": key, "points": rows,
        "bifurcations": [b.to_dict() | {"notes": b.notes} for b in bifurcations], **extra,
    })
    written = [BRANCH_CSV, BRANCH_JSON]
    if rows:
        _plot_branch(out / BRANCH_PLOT, key, rows, bifurcations)
        written.append(BRANCH_PLOT)
    return written


def _plot_branch(path, key, rows, bifurcations) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    p = [r[key] for r in rows]
    fig, axes = plt.subplots(1, 3, figsize=(11, 3.4))
    axes[0].plot(p, [r["period"] for r in rows], "o-")
    axes[0].set_ylabel("period T [tau_d]")
    axes[1].plot(p, [r["tau_swirl_over_tau_sed"] for r in rows], "o-", label="tau_swirl/tau_sed")
    axes[1].set_ylabel("tau_swirl / tau_sed")
    k = 1
    while f"mu{k}_abs" in rows[0]:
        vals = [r[f"mu{k}_abs"] for r in rows]
        if any(v is not None for v in vals):
            axes[2].plot(p, [np.nan if v is None else v for v in vals], ".-", lw=0.8,
                         color=f"C{(k - 1) % 10}")
        k += 1
    axes[2].axhline(1.0, color="k", lw=0.8)
    axes[2].set_ylabel("|mu| (Floquet)")
    for b in bifurcations:
        for ax in axes:
            ax.axvline(b.value, color="r", ls="--", lw=0.8)
    for ax in axes:
        ax.set_xlabel(key)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
