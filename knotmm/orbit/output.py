"""What ``knotmm orbit`` writes: ``orbit.json``, the orbit and its leading mode for VMD, a plot.

Files (names owned here):

* ``orbit.json``: see :func:`orbit_summary` for every key.
* ``orbit.dcd`` + ``topology.pdb``: one period of the orbit, ``ORBIT_FRAMES + 1`` frames
  (the last one is the first fallen and turned by the orbit's translation and rotation).
* ``mode_1.dcd``: the orbit with the leading Floquet mode added, carried along the orbit by
  the linearised flow and scaled to ``MODE_AMPLITUDE`` d rms per bead in every frame, so
  that VMD shows how the shape departs from the orbit.
* ``orbit_multipliers.png``: the multipliers in the complex plane with the unit circle.

A continuation writes ``continuation.csv``, ``continuation.json``, ``continuation.png`` and
``continuation_state.npz`` (every point's orbit in float64, for ``--resume``), all rewritten
after each converged point. Every file is written to a temporary name and renamed, so none
is ever half-written under its name; a failure while writing is one line naming the file
(:class:`knotmm.io.rundir.WriteFault`, exit code 3), the files written before kept. Before
an orbit's files are written, those of an earlier orbit in the same directory are removed
(a ``--modes 0`` orbit leaves no ``mode_1.dcd`` of another one behind).
"""

from __future__ import annotations

import json
import math

import numpy as np

from knotmm.errors import ConfigError
from knotmm.io.atomic import replacing, write_atomic, write_text_atomic
from knotmm.io.rundir import TOPOLOGY_FILE as TOPOLOGY
from knotmm.io.rundir import writing_output
from knotmm.orbit.flow import JVP_EPSILON, rms
from knotmm.plotstyle import label as axis_label
from knotmm.plotstyle import plain_ticks

__all__ = ["ORBIT_FILE", "ORBIT_OUTPUTS", "BRANCH_OUTPUTS", "orbit_summary",
           "write_orbit_files", "plot_multipliers", "write_branch", "read_branch",
           "remove_outputs"]

ORBIT_FILE = "orbit.json"
ORBIT_DCD = "orbit.dcd"
MODE_DCD = "mode_1.dcd"
PLOT = "orbit_multipliers.png"
#: Every file an orbit writes (removed before a new orbit is written into the directory).
ORBIT_OUTPUTS = (ORBIT_FILE, TOPOLOGY, ORBIT_DCD, MODE_DCD, PLOT)
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
            "wavenumbers": dict(shape.wavenumbers),
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
    ax.set_xlabel(axis_label("multiplier_re"))
    ax.set_ylabel(axis_label("multiplier_im"))
    ax.set_title(title or f"$T$ = {result.period:.4g} $\\tau_d$", fontsize=10)
    plain_ticks(ax)
    ax.legend(loc="lower left", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def remove_outputs(out, names) -> None:
    """Remove the files ``names`` from ``out``, and temporaries of them a killed writer left.

    Raises OSError (the callers turn it into one line).
    """
    for name in names:
        for p in [out / name, *out.glob(f".{name}.*")]:
            if p.is_file() or p.is_symlink():
                p.unlink()


def _kept(out, written) -> str:
    return (f"kept in {str(out)!r}: {', '.join(written)}" if written
            else f"nothing was written in {str(out)!r}")


def _dcd_bytes(frames: np.ndarray) -> int:
    return int(frames.size * 4 + 4 * frames.shape[0] * 6 + 8192)


def write_orbit_files(out, flow, orbit, result=None, summary: dict | None = None) -> list:
    """Write every file of an orbit into the directory ``out``; return the names written.

    The frames are computed first, then the files of an earlier orbit are removed and the
    new ones written, ``orbit.json`` first. :class:`~knotmm.io.rundir.WriteFault` (exit 3)
    names the file that failed and the ones kept.
    """
    from knotmm.io.dcd import write_dcd
    from knotmm.io.pdb import write_pdb

    frames = flow.trajectory(orbit.positions, orbit.period, ORBIT_FRAMES)
    with_mode = result is not None and len(result.multipliers) > 0
    mode = _mode_frames(flow, orbit, result.modes[0], frames) if with_mode else None
    written: list[str] = []

    def put(name, write, needed=0):
        with writing_output(out / name, needed, kept=_kept(out, written)):
            write(out / name)
        written.append(name)

    def via_temporary(write):
        def go(path):
            with replacing(path) as tmp:
                write(tmp)
        return go

    with writing_output(out, kept=_kept(out, written)):
        remove_outputs(out, ORBIT_OUTPUTS)
    if summary is not None:
        put(ORBIT_FILE, lambda p: write_json(p, summary))
    put(TOPOLOGY, via_temporary(lambda p: write_pdb(p, orbit.positions)))
    put(ORBIT_DCD, lambda p: write_dcd(p, frames), _dcd_bytes(frames))
    if with_mode:
        put(MODE_DCD, lambda p: write_dcd(p, mode), _dcd_bytes(mode))
        put(PLOT, via_temporary(lambda p: plot_multipliers(result, p)))
    return written


BRANCH_CSV = "continuation.csv"
BRANCH_JSON = "continuation.json"
BRANCH_PLOT = "continuation.png"
#: Every point's orbit (float64) and the continuation's options, for ``--resume``.
BRANCH_STATE = "continuation_state.npz"
#: Every file a continuation writes (removed when a new one starts in the directory).
BRANCH_OUTPUTS = (BRANCH_CSV, BRANCH_JSON, BRANCH_PLOT, BRANCH_STATE)


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


def write_branch(out, key: str, branch, bifurcations, modes: int, extra: dict,
                 state: dict | None = None) -> list:
    """Write ``continuation.csv``, ``.json``, ``.png`` and (with ``state``) the state file.

    Called after every converged point, so an interrupted continuation keeps its points;
    ``state`` (the continuation's options, :func:`read_branch`) makes it resumable.
    """
    import csv
    import io

    rows = branch_rows(key, branch, modes)
    text = io.StringIO()
    if rows:
        writer = csv.DictWriter(text, fieldnames=list(rows[0]), lineterminator="\n")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: ("" if v is None else v) for k, v in row.items()})
    written: list[str] = []

    def put(name, write):
        with writing_output(out / name, kept=_kept(out, written)):
            write(out / name)
        written.append(name)

    put(BRANCH_CSV, lambda p: write_text_atomic(p, text.getvalue()))
    put(BRANCH_JSON, lambda p: write_json(p, {
        "parameter": key, "points": rows,
        "bifurcations": [b.to_dict() | {"notes": b.notes} for b in bifurcations], **extra,
    }))
    if rows:
        def plot(path):
            with replacing(path) as tmp:
                _plot_branch(tmp, key, rows, bifurcations)

        put(BRANCH_PLOT, plot)
    if state is not None:
        put(BRANCH_STATE, lambda p: write_atomic(p, lambda fh: np.savez(
            fh, **_state_arrays(branch, state))))
    return written


def _state_arrays(branch, state: dict) -> dict:
    points = []
    arrays = {}
    for i, point in enumerate(branch):
        o, f = point.orbit, point.floquet
        arrays[f"x{i}"] = np.asarray(o.positions, dtype=np.float64)
        entry = {"value": float(point.value), "period": float(o.period),
                 "rotation": float(o.rotation),
                 "displacement": [float(v) for v in o.displacement],
                 "residual": float(o.residual), "converged": bool(o.converged),
                 "iterations": int(o.iterations), "history": [float(h) for h in o.history],
                 "message": str(o.message), "n_flows": int(o.n_flows),
                 "timestep": float(o.timestep), "floquet": None}
        if f is not None:
            arrays[f"mu{i}"] = np.asarray(f.multipliers, dtype=np.complex128)
            arrays[f"neutral{i}"] = np.asarray(f.neutral, dtype=np.complex128)
            entry["floquet"] = {"neutral_names": list(f.neutral_names),
                                "period": float(f.period), "n_flows": int(f.n_flows),
                                "converged": bool(f.converged)}
        points.append(entry)
    arrays["meta"] = np.array(json.dumps({"version": 1, **state, "branch": points}))
    return arrays


def read_branch(out) -> tuple[dict, list]:
    """The options and the points of the continuation saved in ``out`` (for ``--resume``).

    Returns
    -------
    (dict, list of ContinuationPoint)
        The ``state`` given to :func:`write_branch` and the branch, orbits in float64 as
        they were found.

    Raises
    ------
    ConfigError
        No state file (nothing to resume), or a damaged one.
    """
    from knotmm.orbit.continuation import ContinuationPoint
    from knotmm.orbit.floquet import FloquetResult
    from knotmm.orbit.shooting import Orbit

    path = out / BRANCH_STATE
    if not path.exists():
        raise ConfigError(
            f"--resume: {str(out)!r} holds no continuation to resume (no {BRANCH_STATE}: "
            f"none was started there, or it stopped before its first point); start it "
            f"without --resume"
        )
    try:
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
            branch = []
            for i, e in enumerate(meta.pop("branch")):
                orbit = Orbit(np.array(data[f"x{i}"], dtype=np.float64), e["period"],
                              e["rotation"], np.array(e["displacement"]), e["residual"],
                              e["converged"], e["iterations"], list(e["history"]),
                              e["message"], e["n_flows"], e["timestep"])
                f = e["floquet"]
                res = None if f is None else FloquetResult(
                    np.array(data[f"mu{i}"]), np.empty((0,) + orbit.positions.shape),
                    np.array(data[f"neutral{i}"]), list(f["neutral_names"]), f["period"],
                    f["n_flows"], f["converged"])
                branch.append(ContinuationPoint(float(e["value"]), orbit, res))
    except Exception as exc:  # noqa: BLE001 - a damaged file, whatever numpy or json says
        raise ConfigError(
            f"--resume: {str(path)!r} is damaged ({type(exc).__name__}: "
            f"{' '.join(str(exc).split())[:120]}); start the continuation again without "
            f"--resume"
        ) from None
    return meta, branch


def _plot_branch(path, key, rows, bifurcations) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    p = [r[key] for r in rows]
    fig, axes = plt.subplots(1, 3, figsize=(11, 3.4))
    axes[0].plot(p, [r["period"] for r in rows], "o-")
    axes[0].set_ylabel(axis_label("period"))
    axes[1].plot(p, [r["tau_swirl_over_tau_sed"] for r in rows], "o-")
    axes[1].set_ylabel(r"$\tau_{swirl} / \tau_{sed}$")
    k = 1
    while f"mu{k}_abs" in rows[0]:
        vals = [r[f"mu{k}_abs"] for r in rows]
        if any(v is not None for v in vals):
            axes[2].plot(p, [np.nan if v is None else v for v in vals], ".-", lw=0.8,
                         color=f"C{(k - 1) % 10}")
        k += 1
    axes[2].axhline(1.0, color="k", lw=0.8)
    axes[2].set_ylabel(r"Floquet multipliers $|\mu|$")
    for b in bifurcations:
        for ax in axes:
            ax.axvline(b.value, color="r", ls="--", lw=0.8)
    for ax in axes:
        ax.set_xlabel(axis_label(key))
        plain_ticks(ax)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
