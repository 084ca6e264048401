"""The time-series figure draws what applies to the run's objects (issue 34: an open chain
showed ring panels) and its texts neither overlap nor shrink (issue 35), as ``save_plots``
draws it. The curves are read back from the figure and compared with the quantities
computed here, bead by bead, with plain loops."""

from __future__ import annotations

import math

import matplotlib
import numpy as np
import pytest
from saved_figures import saved_figures

matplotlib.use("Agg")

from drawn_segments import system_positions, write_system_run  # noqa: E402
from drawn_text import overlapping_texts, smallest_text_px  # noqa: E402
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from synthetic import vortex_knot_positions  # noqa: E402

from knotmm.analysis import load_run  # noqa: E402
from knotmm.analysis.core import analyze  # noqa: E402
from knotmm.analysis.plots import plot_time_series, save_plots  # noqa: E402
from knotmm.analysis.series_plots import time_series_panels  # noqa: E402
from knotmm.io.run_data import RunData  # noqa: E402
from knotmm.model.layout import ChainLayout  # noqa: E402

SYSTEMS = {
    "open filament": ((40,), (False,)),
    "ring and open chain": ((30, 20), (True, False)),
    "three chains": ((24, 16, 20), (True, True, False)),
}
RING_WORDS = ("rho", "alpha", "bead ", "swirl", "torus", "tau_{rot}", "l_0/(2")


def _analysed(lengths, closed, directory):
    x = system_positions(n_frames=40, lengths=lengths, closed=closed)
    run = write_system_run(directory, x, ChainLayout(lengths, closed), 0.5,
                           "[model]\nbond_length = 0.6\n")
    return analyze(load_run(run), knot_samples=0)


@pytest.fixture(scope="module", params=list(SYSTEMS))
def system(request, tmp_path_factory):
    lengths, closed = SYSTEMS[request.param]
    return lengths, closed, _analysed(lengths, closed, tmp_path_factory.mktemp("series"))


@pytest.fixture(scope="module")
def ring():
    times = np.arange(0, 120.0, 0.5)
    x = vortex_knot_positions(times, n_beads=60, tau_swirl=10.0, tau_rot=80.0)
    config = {"knot": {"kind": "torus", "p": 2, "q": 3, "beads": 60}}
    return analyze(RunData.from_arrays(x, 0.5, config=config), knot_samples=0)


def _saved_figure(result, tmp_path) -> Figure:
    """The time-series figure exactly as ``save_plots`` writes it (the first one saved)."""
    with saved_figures() as captured:
        save_plots(result, tmp_path)
    fig = captured[0]
    FigureCanvasAgg(fig)
    fig.set_dpi(150)  # save_plots' dpi
    return fig


def _all_text(fig) -> str:
    out = []
    for ax in fig.axes:
        out += [ax.get_ylabel(), ax.get_title()]
        legend = ax.get_legend()
        if legend is not None:
            out += [t.get_text() for t in legend.get_texts()]
    return " | ".join(out)


def _curve(ax, label=None, color=None):
    """The y data of the one line of ``ax`` with that legend label or colour."""
    found = [ln for ln in ax.get_lines()
             if (label is None or ln.get_label() == label)
             and (color is None or matplotlib.colors.to_hex(ln.get_color()) == color)
             and len(ln.get_xdata()) > 2]
    assert len(found) == 1, [(ln.get_label(), ln.get_color()) for ln in ax.get_lines()]
    return np.asarray(found[0].get_ydata(), dtype=float)


def _rg(x):
    """Radius of gyration of one frame, by a loop."""
    c = [sum(p[k] for p in x) / len(x) for k in range(3)]
    return math.sqrt(sum(sum((p[k] - c[k]) ** 2 for k in range(3)) for p in x) / len(x))


def test_an_open_chain_has_no_ring_panel(system, tmp_path):
    lengths, closed, result = system
    fig = _saved_figure(result, tmp_path)
    panels = time_series_panels(result)
    assert len(fig.axes) == len(panels)
    assert "rho" not in panels and "alpha" not in panels and "z" not in panels
    text = _all_text(fig)
    found = [w for w in RING_WORDS if w in text and not (w == "rho" and "ring" in text)]
    if len(lengths) == 1:  # one open chain: not one ring word anywhere
        assert found == [], text
        assert panels == ("height", "size", "end_to_end", "end_angle")
    else:
        assert ("ring_radius" in panels) == any(closed)
        assert ("end_to_end" in panels) == (not all(closed))


def test_open_chain_end_to_end_and_size_curves(tmp_path):
    result = _analysed((40,), (False,), tmp_path / "run")
    axes = plot_time_series(result, axes=Figure().subplots(4, 1, sharex=True))
    x = result.data.positions.astype(float)
    length = [math.dist(frame[-1], frame[0]) for frame in x]
    # angle to the vertical from the horizontal and vertical parts of the vector
    angle = [math.degrees(math.atan2(math.hypot(*(f[-1][:2] - f[0][:2])),
                                     abs(f[-1][2] - f[0][2]))) for f in x]
    assert _curve(axes[2], color="#000000") == pytest.approx(length, rel=1e-9)
    assert _curve(axes[3]) == pytest.approx(angle, abs=1e-6)
    assert _curve(axes[1], label="$R_g$") == pytest.approx([_rg(f) for f in x], rel=1e-9)
    contour = [ln for ln in axes[2].get_lines() if "contour" in ln.get_label()]
    assert contour[0].get_ydata()[0] == pytest.approx(39 * 0.6)
    assert 85.0 < np.mean(angle) <= 90.0  # the test's chain falls broadside


def test_several_chains_curves_are_each_chains(system):
    lengths, closed, result = system
    if len(lengths) == 1:
        pytest.skip("one chain")
    panels = time_series_panels(result)
    axes = plot_time_series(result, axes=Figure().subplots(len(panels), 1, sharex=True))
    ax = dict(zip(panels, axes, strict=True))
    x = result.data.positions.astype(float)
    palette = matplotlib.colormaps["tab10"]
    starts = np.cumsum((0, *lengths))
    for c, (a, b) in enumerate(zip(starts[:-1], starts[1:], strict=True)):
        color = matplotlib.colors.to_hex(palette(c))
        name = f"{'ABC'[c]} ({'ring' if closed[c] else 'open'})"
        z = [sum(p[2] for p in f[a:b]) / (b - a) for f in x]
        assert _curve(ax["height"], label=name) == pytest.approx(z, rel=1e-9)
        assert _curve(ax["size"], color=color) == pytest.approx([_rg(f[a:b]) for f in x],
                                                                 rel=1e-9)
        if closed[c]:
            mean_rho = []
            for f in x:
                cx, cy = (sum(p[k] for p in f[a:b]) / (b - a) for k in (0, 1))
                mean_rho.append(sum(math.hypot(p[0] - cx, p[1] - cy) for p in f[a:b]) / (b - a))
            assert _curve(ax["ring_radius"], color=color) == pytest.approx(mean_rho, rel=1e-9)
        else:
            assert _curve(ax["end_to_end"], color=color) == pytest.approx(
                [math.dist(f[b - 1], f[a]) for f in x], rel=1e-9)
    pairs = [(i, j) for i in range(len(lengths)) for j in range(i + 1, len(lengths))]
    for i, j in pairs:
        ci = x[:, starts[i]:starts[i + 1]].mean(axis=1)
        cj = x[:, starts[j]:starts[j + 1]].mean(axis=1)
        d = [math.dist(p, q) for p, q in zip(ci, cj, strict=True)]
        assert _curve(ax["distance"], label=f"{'ABC'[i]}-{'ABC'[j]}") == pytest.approx(d)


@pytest.mark.parametrize("which", ["ring", "open filament", "ring and open chain"])
def test_no_texts_overlap_legends_beside_readable_sizes(which, ring, tmp_path):
    """As ``save_plots`` writes it: no two texts overlap, every legend lies beside its
    panel (not over the curves), the smallest text is at least 16 px (8 pt at 150 dpi)."""
    if which == "ring":
        result = ring
    else:
        result = _analysed(*SYSTEMS[which], tmp_path / "run")
    fig = _saved_figure(result, tmp_path)
    assert overlapping_texts(fig) == []
    assert smallest_text_px(fig) >= 16.0
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes:
        legend = ax.get_legend()
        if legend is not None:
            assert not legend.get_window_extent(renderer).overlaps(
                ax.get_window_extent(renderer)), ax.get_ylabel()


def test_wrong_number_of_axes_is_refused(ring):
    with pytest.raises(ValueError, match="4 panels"):
        plot_time_series(ring, axes=Figure().subplots(3, 1))


@pytest.mark.parametrize("which", ["ring", "open filament"])
def test_title_says_which_frames_an_unsteady_analysis_uses(which, ring, tmp_path,
                                                           monkeypatch):
    """No steady window, but the window cut short (a radius "collapse" ends it: for an open
    chain that is the radius signal leaving its band, no torus): the title said "the whole
    run is analysed" while the fitted fall covered half of it."""
    result = ring if which == "ring" else _analysed(*SYSTEMS[which], tmp_path / "run")
    win = result.window
    monkeypatch.setattr(result, "notes", [*result.notes, "no frame is steady by the criterion"])
    half = float(result.data.times[len(result.data.times) // 2])
    monkeypatch.setattr(win, "t1", half)
    monkeypatch.setattr(win, "end_reason", "collapse")
    panels = time_series_panels(result)
    axes = plot_time_series(result, axes=Figure().subplots(len(panels), 1, sharex=True))
    title = axes[0].get_title()
    assert title.startswith("no steady window found") and f"-{half:g} " in title, title
    assert ("collapse" in title) == (which == "ring"), title
    assert "whole run" not in title
