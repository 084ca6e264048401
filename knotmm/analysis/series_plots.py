"""The time-series panels of an open chain and of several chains.

A ring's time series are its beads' cylindrical coordinates about the vertical axis (rho,
alpha, z: :func:`knotmm.analysis.plots.plot_bead_coordinate`). An open chain has no torus to
swirl about and several chains no one axis, so their panels are what
:mod:`knotmm.analysis.objects` measures for them, drawn over the whole run:

==================  ==========================================================================
``height``          centre-of-mass height (all beads, the fitted fall over the window) and,
                    for several chains, each chain's own
``size``            radius of gyration; one chain: Rg and its part perpendicular to gravity
                    (Rg_perp); several: each chain's Rg
``ring_radius``     (several chains with a ring) each ring's mean distance from the vertical
                    axis through its own centre of mass
``end_to_end``      length of each open chain's end-to-end vector (last bead - first), with
                    the contour length ``(N - 1) l0`` of one open chain
``end_angle``       (one open chain) angle of the end-to-end vector to the vertical, 0-90
                    degrees: 0 hanging vertically, 90 falling broadside
``distance``        (several chains) distance of the centres of mass of every pair
==================  ==========================================================================

:func:`time_series_panels` names the panels of a result; :func:`plot_series_panel` draws
one. Units: d, tau_d, degrees.
"""

from __future__ import annotations

import numpy as np

from knotmm.analysis.drawing import run_layout
from knotmm.analysis.shape import gyration_measures

__all__ = ["RING_PANELS", "time_series_panels", "plot_series_panel", "plot_chain_heights",
           "chain_colors"]

#: The panels of a ring (or a link's rings as one object): the beads' cylindrical coordinates.
RING_PANELS = ("height", "rho", "alpha", "z")


def time_series_panels(result) -> tuple[str, ...]:
    """The panels of ``result``'s time-series figure, top to bottom.

    One ring (or no layout): :data:`RING_PANELS`. One open chain: ``height``, ``size``,
    ``end_to_end``, ``end_angle``. Several chains: ``height``, ``size``, ``ring_radius``
    (if any ring), ``end_to_end`` (if any open chain), ``distance``.
    """
    layout = run_layout(result.data)
    if layout is None or (layout.n_chains == 1 and layout.closed[0]):
        return RING_PANELS
    if layout.n_chains == 1:
        return ("height", "size", "end_to_end", "end_angle")
    panels = ["height", "size"]
    if any(layout.closed):
        panels.append("ring_radius")
    if not all(layout.closed):
        panels.append("end_to_end")
    panels.append("distance")
    return tuple(panels)


def chain_colors(n_chains: int) -> list:
    """One colour per chain, as the snapshots and ``view.vmd`` colour them (tab10)."""
    import matplotlib

    palette = matplotlib.colormaps["tab10"]
    return [palette(c % 10) for c in range(n_chains)]


def _chains(result):
    """``(id, slice, closed)`` of every chain of the run."""
    layout = run_layout(result.data)
    return list(zip(layout.ids, layout.slices(), layout.closed, strict=True))


def plot_chain_heights(result, ax) -> None:
    """Each chain's centre-of-mass height in its colour (several chains)."""
    layout = run_layout(result.data)
    if layout is None or layout.n_chains < 2:
        return
    z = np.asarray(result.data.positions)[..., 2]
    for cid, sl, closed, color in zip(layout.ids, layout.slices(), layout.closed,
                                      chain_colors(layout.n_chains), strict=True):
        ax.plot(result.data.times, z[:, sl].mean(axis=1), color=color, lw=1.0,
                label=f"{cid} ({'ring' if closed else 'open'})")


def _end_to_end(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Length (d) and angle to the vertical (degrees, 0-90) of ``x[:, -1] - x[:, 0]``.

    ``x``: one chain's positions, shape (n_frames, n_beads, 3).
    """
    e = x[:, -1] - x[:, 0]
    length = np.linalg.norm(e, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        angle = np.degrees(np.arccos(np.clip(np.abs(e[:, 2]) / length, 0.0, 1.0)))
    return length, angle


def _legend(ax, ncol: int, loc: str = "lower right") -> None:
    ax.legend(loc=loc, fontsize="small", frameon=False, ncol=ncol, handlelength=1.5,
              columnspacing=1.0)


def _from_zero(ax) -> None:
    """A length axis from 0 (a rigid chain's constant size is no zoomed-in wiggle)."""
    top = max(ax.dataLim.y1, 0.0)
    ax.set_ylim(0.0, 1.12 * top if top > 0 else 1.0)


def plot_series_panel(result, name: str, ax) -> None:
    """Draw panel ``name`` (:func:`time_series_panels`, not ``height`` or a ring panel).

    Parameters
    ----------
    result : AnalysisResult
    name : {"size", "ring_radius", "end_to_end", "end_angle", "distance"}
    ax : matplotlib Axes
    """
    t = result.data.times
    x = np.asarray(result.data.positions, dtype=np.float64)
    chains = _chains(result)
    colors = chain_colors(len(chains))
    one = len(chains) == 1
    if name == "size":
        if one:
            g = gyration_measures(x)
            ax.plot(t, g["radius_of_gyration"], color="k", lw=1.2, label=r"$R_g$")
            ax.plot(t, g["radius_of_gyration_perp"], color="tab:blue", lw=1.0,
                    label=r"$R_{g,\perp}$ (across gravity)")
            _legend(ax, 2)
        else:
            for (_cid, sl, _), color in zip(chains, colors, strict=True):
                ax.plot(t, gyration_measures(x[:, sl])["radius_of_gyration"], color=color,
                        lw=1.1)
        ax.set_ylabel(r"$R_g$ [d]")
    elif name == "ring_radius":
        for (_cid, sl, closed), color in zip(chains, colors, strict=True):
            if closed:
                rel = x[:, sl] - x[:, sl].mean(axis=1, keepdims=True)
                ax.plot(t, np.hypot(rel[..., 0], rel[..., 1]).mean(axis=1), color=color,
                        lw=1.1)
        ax.set_ylabel(r"ring $\bar\rho$ [d]")
    elif name == "end_to_end":
        for (_cid, sl, closed), color in zip(chains, colors, strict=True):
            if not closed:
                ax.plot(t, _end_to_end(x[:, sl])[0], color="k" if one else color, lw=1.1)
        if one:
            contour = (chains[0][1].stop - chains[0][1].start - 1) * result.bond_length
            ax.axhline(contour, color="0.4", ls=":", lw=1, label=r"contour $(N-1)\,l_0$")
            _legend(ax, 1)
        ax.set_ylabel("end to end [d]")
    elif name == "end_angle":
        ax.plot(t, _end_to_end(x)[1], color="k", lw=1.1)
        ax.set_ylim(-5.0, 95.0)
        ax.set_yticks([0, 30, 60, 90])
        ax.set_ylabel("end-to-end\nto vertical [deg]")
    elif name == "distance":
        from knotmm.analysis.chains import centre_distances

        styles = ("-", "--", ":", "-.")
        k = 0
        for i, (a, sa, _) in enumerate(chains):
            for b, sb, _ in chains[i + 1:]:
                ax.plot(t, centre_distances(x, sa, sb), color="0.2", lw=1.1,
                        ls=styles[k % len(styles)], label=f"{a}-{b}")
                k += 1
        _legend(ax, min(k, 6), loc="best")
        ax.set_ylabel("centres apart [d]")
    else:
        raise ValueError(f"panel {name!r}: expected one of size, ring_radius, end_to_end, "
                         "end_angle, distance")
    if name != "end_angle":
        _from_zero(ax)
