"""Plots of an analysis: time series, spectra, the scaled-coordinate collapse, snapshots.

Every function draws into ``ax`` (a new pyplot figure when None) and returns the Axes.
:func:`save_plots` writes the PNG files without touching pyplot (Agg canvas), so it works
without a display and leaves an interactive session's figures alone.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from knotmm.analysis.drawing import bead_colors, drawn_bonds, run_layout, system_title
from knotmm.analysis.fit import scaled_coordinates
from knotmm.analysis.result import AnalysisResult
from knotmm.analysis.series_plots import (
    RING_PANELS,
    plot_chain_heights,
    plot_series_panel,
    time_series_panels,
)
from knotmm.io.atomic import write_atomic
from knotmm.plotstyle import label as axis_label
from knotmm.plotstyle import plain_ticks

__all__ = [
    "plot_com_height",
    "plot_bead_coordinate",
    "plot_time_series",
    "plot_spectrum",
    "plot_collapse",
    "plot_snapshot",
    "save_plots",
    "PLOT_FILES",
]

#: File names written by :func:`save_plots`.
PLOT_FILES = {
    "timeseries": "analysis_timeseries.png",
    "spectrum": "analysis_spectrum.png",
    "collapse": "analysis_collapse.png",
    "snapshot": "analysis_snapshot.png",
}

_COORD_STYLE = {  # the study's figure: squares, circles, triangles
    "rho": {"marker": "s", "color": "tab:blue", "label": r"$(\rho-\rho_0)/C$"},
    "alpha": {
        "marker": "o",
        "color": "tab:red",
        "label": r"$\frac{q\rho_0}{p}(\alpha-2\pi t/\tau_{rot})/C$",
    },
    "z": {"marker": "^", "color": "tab:green", "label": r"$\frac{q}{\sqrt{p^2+q^2}}(z-Vt)/C$"},
}


def _new_axes(projection=None):
    import matplotlib.pyplot as plt

    fig = plt.figure()
    return fig.add_subplot(projection=projection)


def _shade_window(ax, result: AnalysisResult, labels: bool = False) -> None:
    """Shade the window; mark the radius collapse (red dashes) and knot-type change (purple)."""
    win = result.window
    if _steady(result):  # the window the analysis used, steady or not (the title says which)
        ax.axvspan(win.t0, win.t1, color="0.9", zorder=0, lw=0)
    # a collapse "at" the first frame is no event to mark; a torus collapse only where there
    # is a torus (not for an open chain or separate chains)
    if (win.collapse_time is not None and win.collapse_time > result.data.times[0]
            and _torus(result)):
        ax.axvline(
            win.collapse_time,
            color="tab:red",
            ls="--",
            lw=1,
            label="radius collapse" if labels else None,
        )
    kt = result.knots
    if kt.changed_at is not None:
        text = f"knot {kt.initial} changes" if labels else None
        ax.axvline(kt.changed_at, color="tab:purple", ls=":", lw=1.5, label=text)


def _steady(result: AnalysisResult) -> bool:
    """Whether the analysis found a steady window (not the whole run taken for want of one)."""
    return not any("no frame is steady" in n for n in [*result.window.notes, *result.notes])


def _torus(result: AnalysisResult) -> bool:
    """Whether the run is one torus object (a ring, a link): rho0 applies."""
    return "major_radius" not in result.not_applicable


def _collapse_inside(result: AnalysisResult) -> float | None:
    """The torus collapse time when it falls inside the window (not steady throughout)."""
    win = result.window
    t = win.collapse_time
    return t if t is not None and win.t0 < t < win.t1 and _torus(result) else None


def _finite(value) -> bool:
    return value is not None and np.isfinite(value)


def _default_beads(n: int, count: int = 3, q: int | None = None) -> list[int]:
    """``count`` beads spread over one symmetric sector of the chain.

    A T(p, q) template has q-fold symmetry about the vertical axis: beads ``n / q`` apart
    trace identical rho and z curves, so beads spread over the whole chain (0, 30, 60 for
    N = 90, q = 3) would draw one curve three times. Spread over ``n / q`` beads instead,
    they show ``count`` different phases of the swirl.
    """
    sector = n // q if q and q > 1 and n % q == 0 else n
    return sorted({int(round(k * sector / count)) % n for k in range(count)})


def plot_com_height(result: AnalysisResult, ax=None):
    """Centre-of-mass height against time, with the fitted fall over the window.

    Parameters
    ----------
    result : AnalysisResult
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib Axes
    """
    ax = ax or _new_axes()
    t, com = result.data.times, result.coords.com
    _shade_window(ax, result, labels=True)
    layout = run_layout(result.data)
    several = layout is not None and layout.n_chains > 1  # tab:orange is chain B's colour
    ax.plot(t, com[:, 2], color="k", lw=1.2,
            label="centre of mass, all" if several else "centre of mass")
    win = result.window
    tw = t[win.frames]
    zw = com[win.frames, 2]
    line = zw.mean() - result.sedimentation_velocity * (tw - tw.mean())
    ax.plot(
        tw,
        line,
        color="0.45" if several else "tab:orange",
        ls="--",
        lw=1,
        label=f"V = {result.sedimentation_velocity:.4g} d/$\\tau_d$",
    )
    ax.set_ylabel(r"$z_{cm}$ [d]")
    ax.legend(loc="upper right", fontsize="small", frameon=False)
    return ax


def plot_bead_coordinate(result: AnalysisResult, which: str = "rho", beads=None, ax=None):
    """One cylindrical coordinate of a few beads against time.

    Parameters
    ----------
    result : AnalysisResult
    which : {"rho", "alpha", "z"}
        ``rho`` (d, with the mean over beads in black), ``alpha`` (rad, unwrapped) or
        ``z`` (d, above the centre of mass).
    beads : sequence of int, optional
        Default: three beads evenly spaced over one symmetric sector (``n / q`` beads) of
        the chain, so that they show different phases of the swirl.
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib Axes
    """
    if which not in ("rho", "alpha", "z"):
        raise ValueError(f"which={which!r}: expected 'rho', 'alpha' or 'z'")
    ax = ax or _new_axes()
    t = result.data.times
    values = getattr(result.coords, which)
    beads = _default_beads(values.shape[1], 3, result.q) if beads is None else list(beads)
    _shade_window(ax, result)
    for b in beads:
        ax.plot(t, values[:, b], lw=0.9, label=f"bead {b}")
    if which == "rho" and "major_radius" not in result.not_applicable:  # rho0's series
        ax.plot(t, values.mean(axis=1), color="k", lw=1.2, label="mean")
        if _finite(result.major_radius_geometric):  # defined for a torus knot only
            ax.axhline(result.major_radius_geometric, color="0.4", ls=":", lw=1,
                       label=r"$N l_0/(2\pi p)$")
    labels = {"rho": r"$\rho$ [d]", "alpha": r"$\alpha$ [rad]", "z": r"$z - z_{cm}$ [d]"}
    ax.set_ylabel(labels[which])
    ax.legend(loc="upper right", fontsize="x-small", frameon=False, ncol=len(beads) + 2)
    return ax


def plot_time_series(result: AnalysisResult, axes=None):
    """Stacked panels against time: what applies to the run's objects.

    A ring (or a link, one torus object): the centre-of-mass height and the beads' rho,
    alpha and z. An open chain: height, Rg, the end-to-end length and its angle to the
    vertical. Several chains: height (all beads and each chain), each chain's Rg, each
    ring's mean radius, each open chain's end-to-end length, the distances of the chains'
    centres (:mod:`knotmm.analysis.series_plots`, :func:`time_series_panels` names them).

    Parameters
    ----------
    result : AnalysisResult
    axes : sequence of Axes, optional
        One per panel (``len(time_series_panels(result))``). Default: a new pyplot figure.

    Returns
    -------
    ndarray of Axes
    """
    panels = time_series_panels(result)
    if axes is None:
        import matplotlib.pyplot as plt

        _, axes = plt.subplots(len(panels), 1, sharex=True, figsize=_series_size(panels))
    axes = np.asarray(axes).ravel()
    if len(axes) != len(panels):
        raise ValueError(f"plot_time_series: this run has {len(panels)} panels "
                         f"({', '.join(panels)}); {len(axes)} axes were given")
    plot_com_height(result, ax=axes[0])
    if panels != RING_PANELS:
        plot_chain_heights(result, axes[0])
    for ax, which in zip(axes[1:], panels[1:], strict=True):
        if which in ("rho", "alpha", "z"):
            plot_bead_coordinate(result, which, ax=ax)
        else:
            _shade_window(ax, result)
            plot_series_panel(result, which, ax)
    for ax in axes:  # beside the panels, never over the curves; one column
        handles, labels = ax.get_legend_handles_labels()
        if handles:
            ax.legend(handles, labels, loc="center left", bbox_to_anchor=(1.01, 0.5),
                      fontsize="small", frameon=False, borderaxespad=0.0, handlelength=1.5)
    axes[-1].set_xlabel(axis_label("time"))
    axes[0].set_title(_series_title(result), fontsize="medium")
    for ax in axes:
        plain_ticks(ax)
    return axes


def _series_size(panels) -> tuple[float, float]:
    """Figure size (inches) of the time series: 8 wide, about 2 per panel."""
    return 8.0, 1.0 + 2.0 * len(panels)


def _series_title(result: AnalysisResult) -> str:
    """What the shading is: the steady window and why it ends, or the whole run."""
    win = result.window
    collapse = _collapse_inside(result)
    if _steady(result) and collapse is not None:
        return (f"analysis window {win.t0:g}-{win.t1:g} $\\tau_d$ (shaded): not steady "
                f"throughout, the torus collapses at $t$ = {collapse:g}")
    end = win.end_reason
    if end == "collapse" and not _torus(result):  # no torus: the radius signal left
        end = "departure: radius"
    if _steady(result):
        return f"steady window {win.t0:g}-{win.t1:g} $\\tau_d$ (shaded); end: {end}"
    t = result.data.times
    if win.t0 > t[0] or win.t1 < t[-1]:  # cut short (a collapse of the radius signal)
        return (f"no steady window found: the analysis uses {win.t0:g}-{win.t1:g} $\\tau_d$ "
                f"(end: {end})")
    return "no steady window found: the whole run is analysed"


def plot_spectrum(result: AnalysisResult, ax=None):
    """Swirl and rotation power spectra with their peaks marked.

    Parameters
    ----------
    result : AnalysisResult
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib Axes
        Power (normalised, log scale) against signed frequency in 1/tau_d.
    """
    ax = ax or _new_axes()
    d = result.to_dict()  # the values the table prints: a number only where measured
    specs = (
        (
            result.swirl_spectrum,
            "tab:blue",
            r"swirl: $(z-\bar z) + i(\rho-\bar\rho)$",
            r"\tau_{swirl}",
            "tau_swirl",
        ),
        (result.rotation_spectrum, "tab:red", r"rotation: $e^{i\alpha}$", r"\tau_{rot}",
         "tau_rot"),
    )
    f_sw = abs(result.swirl_spectrum.peak.frequency)
    f_rot = abs(result.rotation_spectrum.peak.frequency)
    f_max = min(max(3.0 * f_sw, 3.0 * f_rot), 0.5 / result.data.frame_interval)
    for spec, color, label, tau, key in specs:
        keep = np.abs(spec.frequencies) <= f_max
        peak = spec.peak
        value, err = d.get(key), d.get(f"{key}_uncertainty")
        marked = True
        why = result.not_applicable.get(key)
        if why is not None:
            text, marked = f"${tau}$ n/a ({why})", False
        elif spec.name == "swirl" and not result.swirl_detected:
            text = "no swirl detected: dashes at the highest point"
        elif value is None:
            text, marked = f"${tau}$ n/a (not measured)", False
        else:
            text = f"${tau}$ = {float(f'{value:.4g}'):g}"
            if err is not None:
                text += f" $\\pm$ {float(f'{err:.2g}'):g}"
            text += " $\\tau_d$"
        ax.semilogy(spec.frequencies[keep], spec.power[keep], color=color, lw=1,
                    label=f"{label}; {text}")
        if marked:
            ax.axvline(peak.frequency, color=color, ls="--", lw=0.8)
    ax.set_ylim(1e-6, 3.0)
    ax.set_xlim(-f_max, f_max)
    # no tick at the edges: the first one would sit on the corner's 10^-6
    from matplotlib.ticker import MaxNLocator

    ax.xaxis.set_major_locator(MaxNLocator(nbins=8, symmetric=True, prune="both"))
    ax.set_xlabel(axis_label("frequency") + " (> 0: counterclockwise seen from above)")
    ax.set_ylabel("power / peak power")
    # above the axes, never over the curves (the low-power tails fill the bottom)
    ax.legend(loc="lower left", bbox_to_anchor=(0.0, 1.01, 1.0, 0.1), mode="expand",
              fontsize="small", frameon=False, borderaxespad=0.0)
    plain_ticks(ax)
    return ax


def plot_collapse(
    result: AnalysisResult, ax=None, beads=None, periods: float = 3.0, max_markers: int = 400
):
    """The scaled coordinates of several beads on the vortex-knot curves.

    Squares: ``(rho - rho0)/C``; circles: ``(q rho0/p)(alpha - 2 pi t/tau_rot)/C``;
    triangles: ``q/sqrt(p^2+q^2)(z - Vt)/C``, against the swirl angle in turns
    ``(t - t0)/tau_swirl + phi_i/(2 pi)``. Lines: ``sin`` and ``cos`` predicted by the
    formula.

    Parameters
    ----------
    result : AnalysisResult
        Must hold a vortex-knot fit.
    ax : matplotlib Axes, optional
    beads : sequence of int, optional
        Beads shown; default six evenly spaced over one symmetric sector (``n / q`` beads).
    periods : float
        Swirl periods shown from the window start.
    max_markers : int
        Markers per coordinate (frames are thinned evenly).

    Returns
    -------
    matplotlib Axes
    """
    ax = ax or _new_axes()
    fit = result.fit
    if fit is None:
        ax.text(0.5, 0.5, "no vortex-knot fit", ha="center", va="center", transform=ax.transAxes)
        return ax
    win = result.window
    c = result.coords
    sel = win.frames
    sc = scaled_coordinates(
        fit, result.data.times[sel], c.rho[sel], c.alpha[sel], result.data.positions[sel, :, 2]
    )
    n = sc.cycle.shape[1]
    beads = _default_beads(n, 6, result.q) if beads is None else list(beads)
    start = np.floor(sc.cycle[0, beads].min())
    x = sc.cycle[:, beads] - start
    shown = x[:, 0] <= periods + 1
    rows = np.flatnonzero(shown)
    per_frame = len(beads)
    rows = rows[:: max(1, int(np.ceil(len(rows) * per_frame / max_markers)))]
    for name in ("rho", "alpha", "z"):
        style = _COORD_STYLE[name]
        y = getattr(sc, name)[:, beads]
        ax.plot(
            x[rows].ravel(),
            y[rows].ravel(),
            ls="none",
            marker=style["marker"],
            ms=4,
            mfc="none",
            mec=style["color"],
            mew=0.8,
            label=style["label"],
        )
    grid = np.linspace(0, max(1.0, x[rows].max()), 600)
    ax.plot(grid, np.sin(2 * np.pi * grid), color=_COORD_STYLE["rho"]["color"], lw=1.2,
            label="formula: sin")
    ax.plot(grid, np.cos(2 * np.pi * grid), color="0.2", lw=1.2, label="formula: cos")
    q_text = f"{fit.q}" if result.q is not None else f"{fit.q} (detected)"
    ax.set_title(
        f"T({fit.p},{q_text}): $\\rho_0$ = {fit.rho0:.3g} d, C = {fit.swirl_amplitude:.3g} d, "
        f"$R^2$ = {fit.r2['total']:.3f}",
        fontsize="medium",
    )
    ax.set_xlabel(r"$(t - t_0)/\tau_{swirl} + \phi_i/2\pi$")
    ax.set_ylabel("scaled coordinate")
    ax.set_ylim(-1.8, 1.8)
    # beside the axes: the markers fill the whole box
    ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize="small",
              frameon=False, borderaxespad=0.0)
    return ax


def _square_limits(ax, horizontal, vertical, minimum_half: float = 1.0) -> None:
    """Equal spans on both axes, centred on the beads, at least ``2 minimum_half`` d wide
    (a straight rod seen end-on or edge-on is no zero-height strip)."""
    half = max(0.5 * float(np.ptp(horizontal)), 0.5 * float(np.ptp(vertical)), minimum_half)
    half += 0.6  # a bead's margin
    ch = 0.5 * (float(np.max(horizontal)) + float(np.min(horizontal)))
    cv = 0.5 * (float(np.max(vertical)) + float(np.min(vertical)))
    ax.set_xlim(ch - half, ch + half)
    ax.set_ylim(cv - half, cv + half)


def plot_snapshot(result: AnalysisResult, frame: int | None = None, view: str = "side", ax=None):
    """The chains at one frame, in the centre-of-mass frame: side, top or 3D view.

    Only the bonds of the run's layout are drawn (:func:`run_layout`): none between chains,
    none across an open chain's ends. In the side and top views (orthographic projections on
    2D axes) nearer strands are drawn over farther ones, so crossings read correctly; beads
    are coloured as ``view.vmd`` colours them (:func:`bead_colors`).

    Parameters
    ----------
    result : AnalysisResult
    frame : int, optional
        Default: the middle of the window.
    view : {"side", "top", "3d"}
        ``side``: x-z plane seen from -y (gravity points down the page); ``top``: x-y plane
        seen from above (counterclockwise on the page is counterclockwise seen from above;
        equal aspect, at least 3.2 d each way); ``3d``: a perspective view (``ax`` must then
        be a 3D Axes).
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib Axes
    """
    if view not in ("side", "top", "3d"):
        raise ValueError(f"view={view!r}: expected 'side', 'top' or '3d'")
    ax = ax or _new_axes("3d" if view == "3d" else None)
    win = result.window
    frame = (win.start + win.stop) // 2 if frame is None else int(frame)
    x = result.data.positions[frame]
    x = x - x.mean(axis=0)
    n = len(x)
    layout = run_layout(result.data)
    colors = bead_colors(layout, n)
    several = layout is not None and layout.n_chains > 1
    t = result.data.times[frame]
    if view == "3d":
        for c, sl in enumerate(layout.slices() if layout is not None else []):
            path = np.vstack([x[sl], x[sl][:1]]) if layout.closed[c] else x[sl]
            line_color = colors[sl.start] if several else "0.3"
            ax.plot(path[:, 0], path[:, 1], path[:, 2], color=line_color, lw=1)
        ax.scatter(*x.T, c=colors, s=18, depthshade=True)
        half = float(np.abs(x).max()) * 1.05
        for setter in (ax.set_xlim, ax.set_ylim, ax.set_zlim):
            setter(-half, half)
        ax.set_box_aspect((1, 1, 1), zoom=0.8)  # room for the z label beside the side view
        ax.view_init(elev=25, azim=-60)
        ax.set_xlabel(r"$x$ [$d$]")
        ax.set_ylabel(r"$y$ [$d$]")
        ax.set_zlabel(r"$z$ [$d$]")
        ax.set_title(f"$t$ = {t:g} $\\tau_d$ ($z$ up)", fontsize="medium")
        return ax
    horizontal, vertical, depth = (x[:, 0], x[:, 2], -x[:, 1]) if view == "side" else x.T
    bonds = drawn_bonds(layout)
    # painter's order: bonds by mean depth, each bead just above its bonds
    rank = np.argsort(np.argsort(0.5 * (depth[bonds[:, 0]] + depth[bonds[:, 1]])))
    seg_z = 2.0 + 2.0 * rank / max(len(bonds), 1)
    bead_z = np.full(n, 2.0)
    for end in (0, 1):
        np.maximum.at(bead_z, bonds[:, end], seg_z)
    bead_z += 0.002
    for k, (i, j) in enumerate(bonds):
        xs, ys = horizontal[[i, j]], vertical[[i, j]]
        line_color = colors[i] if several else "0.25"
        ax.plot(xs, ys, color="white", lw=4.0, solid_capstyle="butt", zorder=seg_z[k])
        ax.plot(xs, ys, color=line_color, lw=1.4, solid_capstyle="round",
                zorder=seg_z[k] + 0.001)
    for i in range(n):
        ax.plot(horizontal[i], vertical[i], "o", ms=4.5, mec="none", color=colors[i],
                zorder=bead_z[i])
    ax.set_aspect("equal")
    ax.set_xlabel(r"$x$ [$d$]")
    if view == "side":
        ax.set_ylabel(r"$z$ [$d$]")
        ax.annotate(
            "",
            xy=(0.04, 0.55),
            xytext=(0.04, 0.95),
            xycoords="axes fraction",
            arrowprops={"arrowstyle": "->", "color": "tab:red", "lw": 1.5},
        )
        ax.text(0.07, 0.85, "g", color="tab:red", transform=ax.transAxes)
        ax.set_title(f"side view, $t$ = {t:g} $\\tau_d$", fontsize="medium")
        pad = max(1.0, 0.6 * float(np.ptp(vertical)))
        ax.set_ylim(vertical.min() - pad, vertical.max() + pad)
    else:
        ax.set_ylabel(r"$y$ [$d$]")
        _square_limits(ax, horizontal, vertical)
        sense = f", rotating {result.rotation_sense}" if result.rotation_sense else ""
        ax.set_title(f"seen from above{sense}", fontsize="medium")
    return ax


def save_plots(result: AnalysisResult, directory, dpi: int = 150) -> list[Path]:
    """Write the PNG files of :data:`PLOT_FILES` into ``directory``.

    Without a vortex-knot fit (``result.fit`` None) the collapse figure is not written (one
    from an earlier analysis is removed) and a note in ``result.notes`` says so; the same for
    the spectrum figure where the swirl does not apply (``result.not_applicable``: an open
    chain, a system of separate chains).

    Returns
    -------
    list of Path
        The files written.
    """
    from matplotlib.figure import Figure

    out = Path(directory)
    written = []

    title = system_title(result.data, result.to_dict())
    panels = time_series_panels(result)
    fig = Figure(figsize=_series_size(panels), layout="constrained")
    plot_time_series(result, axes=fig.subplots(len(panels), 1, sharex=True))
    fig.suptitle(title)
    written.append(_save(fig, out / PLOT_FILES["timeseries"], dpi))

    spectrum = out / PLOT_FILES["spectrum"]
    why = result.not_applicable.get("tau_swirl")
    if why is None:
        fig = Figure(figsize=(8, 4.5), layout="constrained")
        plot_spectrum(result, ax=fig.add_subplot())
        written.append(_save(fig, spectrum, dpi))
    else:  # no swirl or rotation to show (an open chain, separate chains)
        spectrum.unlink(missing_ok=True)
        result.notes.append(f"{PLOT_FILES['spectrum']} not written: swirl and rotation do not "
                            f"apply ({why})")

    collapse = out / PLOT_FILES["collapse"]
    if result.fit is not None:
        fig = Figure(figsize=(8, 4.5), layout="constrained")
        plot_collapse(result, ax=fig.add_subplot())
        written.append(_save(fig, collapse, dpi))
    else:  # no figure of an empty fit; one left by an earlier analysis would mislead
        collapse.unlink(missing_ok=True)
        result.notes.append(f"{PLOT_FILES['collapse']} not written: no vortex-knot fit")

    fig = Figure(figsize=(13, 4.6), layout="constrained")
    grid = fig.add_gridspec(1, 3, width_ratios=(1.0, 1.3, 1.0))
    plot_snapshot(result, view="3d", ax=fig.add_subplot(grid[0], projection="3d"))
    plot_snapshot(result, view="side", ax=fig.add_subplot(grid[1]))
    plot_snapshot(result, view="top", ax=fig.add_subplot(grid[2]))
    fig.suptitle(title)
    written.append(_save(fig, out / PLOT_FILES["snapshot"], dpi))
    return written


def _save(fig, path: Path, dpi: int) -> Path:
    """Write ``fig`` to ``path`` as a PNG, whole or not at all (a full disk leaves the earlier
    file, or none, under that name: never an empty or cut one)."""
    write_atomic(path, lambda fh: fig.savefig(fh, dpi=dpi, format="png"))
    return path
