"""The figures a talk would show (issue 24, item 3): what is written, labels with units,
no offset notation. Read back from the Axes on matplotlib's Agg backend."""

from __future__ import annotations

import json

import matplotlib
import pytest

matplotlib.use("Agg")

from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from knotmm.cli.main import main  # noqa: E402
from knotmm.plotstyle import LABELS, label, plain_ticks  # noqa: E402


def _fig() -> Figure:
    fig = Figure()
    FigureCanvasAgg(fig)
    return fig


@pytest.fixture(scope="module")
def no_swirl_run(tmp_path_factory):
    """The default T(2,3) of 90 beads for 20 tau_d: no swirl detected, so no vortex-knot fit."""
    out = tmp_path_factory.mktemp("plot_labels") / "run"
    assert main(["run", "--duration", "20", "--out", str(out),
                 "--set", "run.topology_check_interval=0", "--no-progress"]) == 0
    (out / "analysis_collapse.png").write_bytes(b"stale")  # left by an earlier analysis
    assert main(["analyze", str(out), "--knot-samples", "0"]) == 0
    return out


def test_no_collapse_figure_without_a_fit_and_the_notes_say_so(no_swirl_run):
    analysis = json.loads((no_swirl_run / "analysis.json").read_text())
    assert analysis.get("fit") is None
    assert not (no_swirl_run / "analysis_collapse.png").exists()
    assert "analysis_collapse.png not written: no vortex-knot fit" in analysis["notes"]
    for name in ("analysis_timeseries.png", "analysis_spectrum.png", "analysis_snapshot.png"):
        assert (no_swirl_run / name).stat().st_size > 1000


def _result(run):
    from knotmm.analysis import analyze_run

    return analyze_run(run, plots=False, knot_samples=0)


def test_axes_labels_carry_units_and_ticks_have_no_offset(no_swirl_run):
    from knotmm.analysis.plots import plot_snapshot, plot_spectrum, plot_time_series

    result = _result(no_swirl_run)
    fig = _fig()
    axes = plot_time_series(result, axes=fig.subplots(4, 1, sharex=True))
    fig.canvas.draw()
    assert "[$\\tau_d$]" in axes[-1].get_xlabel()
    for ax in axes:
        assert "[" in ax.get_ylabel() and "]" in ax.get_ylabel(), ax.get_ylabel()
        assert ax.yaxis.get_offset_text().get_text() == ""
    spec = plot_spectrum(result, ax=_fig().add_subplot())
    assert "[$1/\\tau_d$]" in spec.get_xlabel()
    assert all("e+" not in t.get_text() for t in spec.get_legend().get_texts())
    ax3 = plot_snapshot(result, view="3d", ax=_fig().add_subplot(projection="3d"))
    assert ax3.get_zlabel() == "$z$ [$d$]"


def test_title_and_shading_follow_whether_a_window_is_steady(no_swirl_run):
    from knotmm.analysis.plots import _steady, plot_time_series

    result = _result(no_swirl_run)
    axes = plot_time_series(result, axes=_fig().subplots(4, 1, sharex=True))
    title = axes[0].get_title()
    if _steady(result):
        assert title.startswith("steady window")
    else:
        assert title.startswith("no steady window")
        assert not axes[0].patches  # nothing shaded as "steady"
    first = result.data.times[0]
    assert all(line.get_xdata()[0] != first for line in axes[0].lines
               if line.get_label() == "radius collapse")


def test_plain_ticks_removes_the_offset():
    fig = _fig()
    ax = fig.add_subplot()
    ax.plot([1000.01, 1000.02, 1000.03], [0, 1, 2])
    fig.canvas.draw()
    assert ax.xaxis.get_offset_text().get_text() != ""  # matplotlib's default: +1.19e1
    plain_ticks(ax)
    fig.canvas.draw()
    assert ax.xaxis.get_offset_text().get_text() == ""


def test_every_swept_key_label_has_units_or_is_a_count():
    for key, text in LABELS.items():
        dimensionless = key in ("knot.beads", "knot.p", "knot.q", "run.peclet", "run.seed",
                                "point", "replica", "multiplier_re", "multiplier_im",
                                "multiplier_abs")
        assert dimensionless or ("[" in text and "]" in text), key
    assert label("not.a.key") == "not.a.key"


def test_ensemble_plot_mean_and_standard_error_without_offset(tmp_path):
    import numpy as np

    from knotmm.sweep.plots import plot_ratios

    rng = np.random.default_rng(1)
    rows = []
    for n in (40, 60):
        for rep in range(4):
            rows.append({"knot.beads": n, "replica": rep, "status": "finished",
                         "tau_swirl_over_tau_sed": 11.9 + 0.01 * rng.standard_normal(),
                         "tau_rot_over_tau_sed": 50 + rng.standard_normal(),
                         "fit_r2": 0.99})
    fig = _fig()
    axes = plot_ratios(rows, "knot.beads", axes=fig.subplots(2, 1))
    fig.canvas.draw()
    ax = axes[0]
    assert axes[-1].get_xlabel() == LABELS["knot.beads"]
    assert ax.yaxis.get_offset_text().get_text() == ""
    ticks = [t for t in ax.get_xticks() if ax.get_xlim()[0] <= t <= ax.get_xlim()[1]]
    assert all(float(t).is_integer() for t in ticks)
    assert any("s.e." in t.get_text() for t in ax.get_legend().get_texts())
    # the error bar is the standard error of the 4 replicas, not their spread
    ys = np.array([r["tau_swirl_over_tau_sed"] for r in rows[:4]])
    sem = ys.std(ddof=1) / 2
    segments = [c for c in ax.collections if hasattr(c, "get_segments")]
    lengths = [s[1][1] - s[0][1] for c in segments for s in c.get_segments()]
    assert any(abs(length - 2 * sem) < 1e-9 for length in lengths)


@pytest.fixture(scope="module")
def vortex_result(tmp_path_factory):
    """A synthetic swirling T(2,3) (tau_swirl 20, tau_rot 400 tau_d), analysed: a fit."""
    import numpy as np
    from synthetic import vortex_knot_positions, write_run_directory

    from knotmm.analysis import analyze_run

    times = np.arange(0.0, 400.0, 0.5)
    directory = write_run_directory(tmp_path_factory.mktemp("vortex") / "run",
                                    vortex_knot_positions(times), 0.5,
                                    {"knot": {"p": 2, "q": 3, "beads": 90}})
    result = analyze_run(directory, plots=False, knot_samples=0)
    assert result.fit is not None
    return result


@pytest.mark.parametrize("name", ["spectrum", "collapse"])
def test_the_legend_stays_off_the_curves_and_no_texts_overlap(vortex_result, name):
    """Issue 35: the spectrum's legend sat over its curves and the collapse legend was
    x-small stacked text with one curve unlabelled. As ``save_plots`` draws them (8 x 4.5
    inches, 150 dpi): the legend lies outside the data area, every line has an entry, no two
    texts overlap, the smallest text is at least 16 px (8 pt at 150 dpi)."""
    from drawn_text import overlapping_texts, smallest_text_px

    from knotmm.analysis.plots import plot_collapse, plot_spectrum

    fig = Figure(figsize=(8, 4.5), layout="constrained", dpi=150)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    (plot_spectrum if name == "spectrum" else plot_collapse)(vortex_result, ax=ax)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    legend = ax.get_legend().get_window_extent(renderer)
    assert not legend.overlaps(ax.get_window_extent(renderer)), name
    labelled = {t.get_text() for t in ax.get_legend().get_texts()}
    # every curve (not the vertical peak markers) has its legend entry
    lines = [ln for ln in ax.get_lines() if len(set(map(float, ln.get_xdata()))) > 1]
    assert all(ln.get_label() in labelled for ln in lines), [ln.get_label() for ln in lines]
    assert overlapping_texts(fig) == []
    assert smallest_text_px(fig) >= 16.0


def test_the_wrote_line_names_every_file_written_the_shape_series_too(no_swirl_run, capsys):
    """Issue 35: ``analysis_shape.csv`` was written but not named in the "wrote" line."""
    capsys.readouterr()
    assert main(["analyze", str(no_swirl_run), "--knot-samples", "0"]) == 0
    wrote = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("wrote ")]
    assert len(wrote) == 1
    named = wrote[0].removeprefix("wrote ").rsplit(" in ", 1)[0].split(", ")
    assert "analysis.json" in named and "analysis_shape.csv" in named
    for name in named:
        assert (no_swirl_run / name).stat().st_size > 0, name
