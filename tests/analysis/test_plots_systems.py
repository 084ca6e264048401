"""The analysis figures of several chains and of an open chain (issue 34, "Drawing"), and
figures that show only what the table reports (issue 35): read back from the figures."""

from __future__ import annotations

import math
import re

import matplotlib
import numpy as np
import pytest
from saved_figures import saved_figures

matplotlib.use("Agg")

from drawn_segments import (  # noqa: E402
    allowed_pairs,
    drawn_pairs,
    system_positions,
    write_system_run,
)
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from synthetic import vortex_knot_positions  # noqa: E402

from knotmm.analysis import load_run  # noqa: E402
from knotmm.analysis.core import analyze  # noqa: E402
from knotmm.analysis.plots import (  # noqa: E402
    plot_bead_coordinate,
    plot_snapshot,
    plot_spectrum,
    plot_time_series,
    save_plots,
)
from knotmm.io.run_data import RunData  # noqa: E402
from knotmm.model.layout import ChainLayout  # noqa: E402

SYSTEMS = {
    "ring and open chain": ((30, 20), (True, False)),
    "open filament": ((60,), (False,)),
    "three chains": ((24, 16, 20), (True, True, False)),
}


def _fig() -> Figure:
    fig = Figure()
    FigureCanvasAgg(fig)
    return fig


@pytest.fixture(scope="module", params=list(SYSTEMS))
def system(request, tmp_path_factory):
    lengths, closed = SYSTEMS[request.param]
    layout = ChainLayout(lengths, closed)
    x = system_positions(lengths=lengths, closed=closed)
    run = write_system_run(tmp_path_factory.mktemp("system"), x, layout, 0.5)
    data = load_run(run)
    return lengths, closed, analyze(data, knot_samples=0)


def _snapshot_figure(result, frame):
    fig = _fig()
    plot_snapshot(result, frame, view="3d", ax=fig.add_subplot(1, 3, 1, projection="3d"))
    plot_snapshot(result, frame, view="side", ax=fig.add_subplot(1, 3, 2))
    plot_snapshot(result, frame, view="top", ax=fig.add_subplot(1, 3, 3))
    return fig


def test_every_drawn_segment_is_a_bond_of_the_layout(system):
    lengths, closed, result = system
    frame = 5
    fig = _snapshot_figure(result, frame)
    x = result.data.positions[frame]
    drawn = drawn_pairs(fig, x - x.mean(axis=0))
    allowed = allowed_pairs(lengths, closed)
    assert drawn - allowed == set(), f"segments that are no bond: {sorted(drawn - allowed)}"
    assert drawn == allowed  # and every bond is drawn


def test_written_snapshot_figure_draws_only_bonds(system, tmp_path):
    lengths, closed, result = system
    with saved_figures() as captured:
        save_plots(result, tmp_path)
    snapshot = captured[-1]
    frame = (result.window.start + result.window.stop) // 2
    x = result.data.positions[frame]
    assert drawn_pairs(snapshot, x - x.mean(axis=0)) == allowed_pairs(lengths, closed)
    title = snapshot.get_suptitle()
    if len(lengths) == 1:
        assert title == f"open filament, N = {lengths[0]}"
    else:
        assert title.startswith(f"{len(lengths)} chains (A: ")
        for cid, n, ring in zip("ABC", lengths, closed, strict=False):
            assert f"{cid}: {n} beads, {'ring' if ring else 'open'}" in title


def test_beads_are_coloured_by_chain(system):
    lengths, _, result = system
    if len(lengths) == 1:
        pytest.skip("one chain is coloured along its beads")
    ax = plot_snapshot(result, 0, view="side", ax=_fig().add_subplot())
    beads = [line for line in ax.get_lines() if line.get_marker() == "o"]
    colors = [matplotlib.colors.to_hex(line.get_color()) for line in beads]
    starts = np.cumsum((0, *lengths))
    per_chain = [set(colors[a:b]) for a, b in zip(starts[:-1], starts[1:], strict=True)]
    assert all(len(c) == 1 for c in per_chain)
    assert len(set.union(*per_chain)) == len(lengths)


def test_top_view_of_a_straight_rod_is_square_with_a_minimum_span(tmp_path):
    n = 40
    rod = np.zeros((24, n, 3))
    rod[:, :, 0] = 0.6 * np.arange(n)
    rod[:, :, 2] = -np.arange(24)[:, None] * 0.5
    rod[:, :, 1] = 1e-3 * np.sin(np.arange(n))  # a straight rod, off by a hair
    data = RunData.from_arrays(rod, 0.5, bonds=ChainLayout((n,), (False,)).bonds(),
                               config={"knot": {"kind": "straight"}})
    result = analyze(data, knot_samples=0)
    ax = plot_snapshot(result, 0, view="top", ax=_fig().add_subplot())
    x_span, y_span = np.ptp(ax.get_xlim()), np.ptp(ax.get_ylim())
    assert y_span == pytest.approx(x_span) and y_span > 0.6 * (n - 1)
    assert ax.get_aspect() == 1.0


# -- issue 35: the figures show what the table shows ---------------------------------------
@pytest.fixture(scope="module")
def torus_result():
    times = np.arange(0, 120.0, 0.5)
    x = vortex_knot_positions(times, n_beads=60, tau_swirl=10.0, tau_rot=80.0)
    config = {"knot": {"kind": "torus", "p": 2, "q": 3, "beads": 60}}
    return analyze(RunData.from_arrays(x, 0.5, config=config), knot_samples=0)


def _legend_texts(ax) -> list[str]:
    legend = ax.get_legend()
    return [t.get_text() for t in legend.get_texts()] if legend is not None else []


def test_spectrum_legend_has_no_number_for_an_unmeasured_tau_rot(torus_result, monkeypatch):
    assert math.isfinite(torus_result.rotation_spectrum.peak.period)  # a peak to misreport
    monkeypatch.setattr(torus_result, "tau_rot", float("nan"))  # not measured
    assert re.search(r"tau_rot \[tau_d\]\s+n/a", torus_result.summary())
    texts = _legend_texts(plot_spectrum(torus_result, ax=_fig().add_subplot()))
    rotation = [t for t in texts if t.startswith("rotation")]
    assert len(rotation) == 1
    said = rotation[0].split(";", 1)[1]
    assert "n/a" in said and not re.search(r"\d", said), said


def test_spectrum_legend_shows_the_tables_tau_rot(torus_result):
    d = torus_result.to_dict()
    texts = _legend_texts(plot_spectrum(torus_result, ax=_fig().add_subplot()))
    rotation = next(t for t in texts if t.startswith("rotation"))
    value = float(f"{d['tau_rot']:.4g}")
    assert f"{value:g}" in rotation


def test_rho_panel_lists_no_geometric_radius_it_does_not_draw(torus_result, monkeypatch):
    monkeypatch.setattr(torus_result, "major_radius_geometric", float("nan"))
    ax = plot_bead_coordinate(torus_result, "rho", ax=_fig().add_subplot())
    assert not any("l_0" in t for t in _legend_texts(ax))
    assert all(np.isfinite(line.get_ydata()).all() for line in ax.get_lines())


def test_a_collapse_inside_the_window_is_not_called_steady(torus_result, monkeypatch):
    win = torus_result.window
    inside = 0.5 * (win.t0 + win.t1)
    monkeypatch.setattr(win, "collapse_time", inside)
    axes = plot_time_series(torus_result, axes=_fig().subplots(4, 1, sharex=True))
    title = axes[0].get_title()
    assert not title.startswith("steady window") and "collapses" in title, title
    for ax in axes:  # the shading covers exactly the window the analysis used
        for patch in ax.patches:
            path = patch.get_path().vertices  # a Rectangle's unit square, or a Polygon's
            xs = patch.get_patch_transform().transform(path)[:, 0]
            assert (xs.min(), xs.max()) == pytest.approx((win.t0, win.t1))
