"""Plots of a sweep's summary: time-scale ratios and toroidal shape against a swept key.

Every function takes the rows of ``summary.csv`` (:func:`knotmm.sweep.read_summary` or
:attr:`knotmm.sweep.SweepResult.rows`), draws into the given Axes (a new pyplot figure when
None) and returns them. :func:`save_sweep_plots` writes the PNG files with matplotlib's Agg
canvas, without pyplot. Only rows with ``status = "finished"`` and finite values are drawn;
points that are not a clean periodic state (the knot type changed before the end of the
analysis window, or the vortex-knot fit explains less than half of the motion, ``fit_r2 < 0.5``, see
:data:`MIN_FIT_R2`) are drawn as open markers and not joined to the others. A y axis whose
values span 30x or more is drawn on a log scale.
Points that differ in another swept key are drawn as separate series; replicas of an
ensemble are drawn as small markers with their mean and standard deviation.

Examples
--------
>>> from knotmm.sweep import read_summary
>>> rows = read_summary("sweeps/fig3")                          # doctest: +SKIP
>>> axes = plot_ratios(rows, "knot.beads")                      # doctest: +SKIP
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from knotmm.io.atomic import write_atomic
from knotmm.plotstyle import integer_ticks, plain_ticks
from knotmm.plotstyle import label as axis_label

__all__ = ["plot_ratios", "plot_shape", "save_sweep_plots", "RATIO_PLOT", "SHAPE_PLOT"]

#: Points whose vortex-knot fit has R^2 below this are drawn as open markers, not joined.
MIN_FIT_R2 = 0.5

#: File names written by :func:`save_sweep_plots` into the sweep directory.
RATIO_PLOT = "ratios.png"
SHAPE_PLOT = "shape.png"



def _finite(value: Any) -> bool:
    return (
        isinstance(value, (int, float))
        and not isinstance(value, bool)
        and math.isfinite(float(value))
    )


def _is_numeric_axis(rows: Sequence[Mapping[str, Any]], x: str) -> bool:
    return x != "point" and all(_finite(r.get(x)) for r in rows)


def _poor(row: Mapping[str, Any]) -> bool:
    """Whether a row is not a clean periodic state: the knot type changed before the end of
    the analysis window, or the vortex-knot fit explains less than :data:`MIN_FIT_R2` of the
    motion."""
    r2 = row.get("fit_r2")
    if _finite(r2) and float(r2) < MIN_FIT_R2:
        return True
    changed, t1 = row.get("knot_type_changed_at"), row.get("window_end")
    return _finite(changed) and _finite(t1) and changed <= t1


def _series(rows, x: str, group_keys: Sequence[str], y: str, err: str | None):
    """Group finished rows into series: ``{label: [(x, y, err, poor), ...]}`` in row order."""
    done = [r for r in rows if r.get("status") == "finished" and _finite(r.get(y))]
    numeric = _is_numeric_axis(done, x)
    positions = {}
    if not numeric:
        for r in rows:
            positions.setdefault(r.get(x) if x != "point" else r["point"], len(positions))
    out: dict[str, list[tuple[float, float, float, bool]]] = {}
    for r in done:
        label = ", ".join(f"{k}={r.get(k)}" for k in group_keys)
        xv = r.get(x) if x != "point" else r["point"]
        xv = float(xv) if numeric else float(positions[xv])
        e = r.get(err) if err else None
        out.setdefault(label, []).append(
            (xv, float(r[y]), float(e) if _finite(e) else 0.0, _poor(r))
        )
    return out, numeric, positions


def _draw(ax, series, numeric: bool, positions: dict, x: str, log_x: bool | None) -> None:
    import numpy as np

    colors = [f"C{i}" for i in range(10)]
    xs_all, ys_all = [], []
    poor_drawn = False
    for i, (label, pts) in enumerate(series.items()):
        color = colors[i % len(colors)]
        bad = [p for p in pts if p[3]]
        pts = [p for p in pts if not p[3]]
        if bad:  # open markers, not joined: the motion there is not a clean vortex knot
            ax.plot(
                [p[0] for p in bad],
                [p[1] for p in bad],
                "o",
                mfc="none",
                color=color,
                alpha=0.6,
                label=None if poor_drawn else "not a clean periodic state",
            )
            poor_drawn = True
            xs_all += [p[0] for p in bad]
            ys_all += [p[1] for p in bad]
        if not pts:
            continue
        xs = np.array([p[0] for p in pts])
        ys = np.array([p[1] for p in pts])
        es = np.array([p[2] for p in pts])
        xs_all.extend(xs)
        ys_all.extend(ys)
        uniq = np.unique(xs)
        if x == "replica" and len(xs) > 1:  # one point, K replicas: their mean +- s.e.
            ax.plot(xs, ys, "o", ms=5, alpha=0.4, mec="none", color=color,
                    label=(label + ": " if label else "") + "replicas")
            mean, sem = ys.mean(), ys.std(ddof=1) / np.sqrt(len(ys))
            ax.axhspan(mean - sem, mean + sem, color=color, alpha=0.15, lw=0)
            ax.axhline(mean, color=color, lw=1.2,
                       label=f"mean $\\pm$ s.e. of {len(ys)} replicas")
        elif len(uniq) < len(xs):  # replicas: faint markers, then mean +- standard error
            ax.plot(xs, ys, "o", ms=3, alpha=0.3, mec="none", color=color)
            means = np.array([ys[xs == u].mean() for u in uniq])
            counts = np.array([np.sum(xs == u) for u in uniq])
            sems = np.array([ys[xs == u].std(ddof=1) if c > 1 else 0.0
                             for u, c in zip(uniq, counts, strict=True)]) / np.sqrt(counts)
            fmt = "o-" if len(uniq) > 1 else "o"
            ax.errorbar(uniq, means, yerr=sems, fmt=fmt, color=color, capsize=3,
                        label=(label + " " if label else "") + "mean $\\pm$ s.e.")
        else:
            order = np.argsort(xs)
            ax.errorbar(
                xs[order],
                ys[order],
                yerr=es[order],
                fmt="o" if x in ("replica", "run.seed") else "o-",  # replicas are not a series
                color=color,
                capsize=3,
                label=label or None,
            )
    if not numeric:
        ax.set_xticks(list(positions.values()))
        ax.set_xticklabels([str(k) for k in positions], rotation=30, ha="right", fontsize=8)
    elif xs_all:
        lo, hi = min(xs_all), max(xs_all)
        if log_x is None:
            log_x = lo > 0 and hi / lo >= 100
        if log_x and lo > 0:
            ax.set_xscale("log")
    if ys_all and min(ys_all) > 0 and max(ys_all) / min(ys_all) >= 30:
        ax.set_yscale("log")
    ax.set_xlabel(axis_label(x))
    if numeric and x in ("replica", "knot.beads", "knot.p", "knot.q", "run.seed"):
        integer_ticks(ax.xaxis)
    plain_ticks(ax)
    ax.grid(True, alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()
    if labels:
        ax.legend(fontsize=8)


def _axes(n: int, axes):
    if axes is not None:
        return list(axes) if hasattr(axes, "__len__") else [axes]
    import matplotlib.pyplot as plt

    _, new = plt.subplots(n, 1, figsize=(6.4, 2.6 * n + 0.6), sharex=True, layout="constrained")
    return list(new)


def _group_keys(rows, x: str, keys: Sequence[str] | None) -> list[str]:
    if keys is None:
        skip = {"point", "directory", "status", "error", "replica", "run.seed", x}
        # swept keys are dotted; the analysis columns are not
        keys = [k for k in (rows[0] if rows else {}) if "." in k and k not in skip]
    if x == "point":
        return []
    return [k for k in keys if k != x and len({str(r.get(k)) for r in rows}) > 1]


def plot_ratios(
    rows: Sequence[Mapping[str, Any]],
    x: str,
    axes=None,
    group_by: Sequence[str] | None = None,
    log_x: bool | None = None,
):
    """Plot ``tau_swirl/tau_sed`` (top) and ``tau_rot/tau_sed`` (bottom) against ``x``.

    Parameters
    ----------
    rows : sequence of dict
        Rows of ``summary.csv``.
    x : str
        A swept dotted key (numeric or not), ``"point"`` (one tick per point) or
        ``"replica"``.
    axes : pair of matplotlib Axes, optional
        Default: a new pyplot figure with two panels.
    group_by : sequence of str, optional
        Keys that separate series; default: every other swept key that varies.
    log_x : bool, optional
        Default: log scale when positive values span 100x or more.

    Returns
    -------
    list of Axes
        The two panels. Error bars are the analysis uncertainties (or, for replicas, the
        standard deviation over replicas).
    """
    axes = _axes(2, axes)
    groups = _group_keys(rows, x, group_by)
    for ax, (y, label) in zip(
        axes,
        (
            ("tau_swirl_over_tau_sed", r"$\tau_{swirl} / \tau_{sed}$"),
            ("tau_rot_over_tau_sed", r"$\tau_{rot} / \tau_{sed}$"),
        ),
        strict=True,
    ):
        series, numeric, positions = _series(rows, x, groups, y, f"{y}_uncertainty")
        _draw(ax, series, numeric, positions, x, log_x)
        ax.set_ylabel(label)
    for ax in axes[:-1]:
        ax.set_xlabel("")
    return axes


def plot_shape(
    rows: Sequence[Mapping[str, Any]],
    x: str,
    axes=None,
    group_by: Sequence[str] | None = None,
    log_x: bool | None = None,
):
    """Plot the major radius rho0 (with ``N l0/(2 pi p)`` dashed), the swirl amplitude C and
    the sedimentation speed V against ``x`` (three panels; lengths in d, V in d/tau_d).

    Parameters and return value as in :func:`plot_ratios` (three Axes).
    """
    axes = _axes(3, axes)
    groups = _group_keys(rows, x, group_by)
    panels = (
        ("major_radius", "major_radius_std", r"$\rho_0$ [d]"),
        ("swirl_amplitude", None, "C [d]"),
        ("sedimentation_velocity", "sedimentation_velocity_uncertainty", r"V [d/$\tau_d$]"),
    )
    for ax, (y, err, label) in zip(axes, panels, strict=True):
        series, numeric, positions = _series(rows, x, groups, y, err)
        _draw(ax, series, numeric, positions, x, log_x)
        ax.set_ylabel(label)
    geo, numeric, positions = _series(rows, x, groups, "major_radius_geometric", None)
    for pts in geo.values():
        pts = sorted(p[:2] for p in pts)
        axes[0].plot(
            [p[0] for p in pts],
            [p[1] for p in pts],
            "--",
            color="0.4",
            lw=1,
            label=r"$N l_0 / (2\pi p)$",
        )
    if geo:
        handles, labels = axes[0].get_legend_handles_labels()
        unique = dict(zip(labels, handles, strict=True))
        axes[0].legend(unique.values(), unique.keys(), fontsize=8)
    for ax in axes[:-1]:
        ax.set_xlabel("")
    return axes


def save_sweep_plots(
    rows: Sequence[Mapping[str, Any]],
    directory,
    x: str,
    keys: Sequence[str] = (),
    group_by: Sequence[str] | None = None,
    log_x: bool | None = None,
    dpi: int = 150,
) -> list[Path]:
    """Write ``ratios.png`` and ``shape.png`` into ``directory``.

    Parameters
    ----------
    rows : sequence of dict
        Rows of the summary.
    directory : path
    x : str
        The x axis (``Sweep.x_key``): a swept key, ``"point"`` or ``"replica"``.
    keys : sequence of str
        The swept keys (``Sweep.keys``), named in the title.
    group_by : sequence of str, optional
        Keys that separate series; default ``keys`` (pass ``[]`` in zip mode, where the
        other keys change together with x).
    log_x : bool, optional
        As in :func:`plot_ratios`.
    dpi : int

    Returns
    -------
    list of Path
        The files written; empty when no point has finished.
    """
    from matplotlib.figure import Figure

    if not any(r.get("status") == "finished" for r in rows):
        return []
    directory = Path(directory)
    title = ", ".join(keys) or "ensemble"
    groups = list(keys) if group_by is None else list(group_by)
    written = []
    for name, func, n in ((RATIO_PLOT, plot_ratios, 2), (SHAPE_PLOT, plot_shape, 3)):
        fig = Figure(figsize=(6.4, 2.6 * n + 0.8), layout="constrained")
        axes = fig.subplots(n, 1, sharex=True)
        func(rows, x, axes=axes, group_by=groups, log_x=log_x)
        fig.suptitle(f"sweep over {title}: {directory.name}", fontsize=10)
        path = directory / name
        # atomically: a full disk leaves the old plot (or none), never half a PNG
        write_atomic(path, lambda fh, fig=fig: fig.savefig(fh, dpi=dpi, format="png"))
        written.append(path)
    return written
