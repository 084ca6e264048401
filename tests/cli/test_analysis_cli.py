"""``knotmm analyze``: table, files, and exit code 2 on broken input."""

from __future__ import annotations

import json

import numpy as np
import pytest
from synthetic import vortex_knot_positions, write_run_directory

from knotmm.cli.main import main


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    times = np.arange(301) * 0.5
    x = vortex_knot_positions(times, noise=0.02)
    config = {"knot": {"kind": "torus", "p": 2, "q": 3}, "model": {"bond_length": 0.6}}
    return write_run_directory(tmp_path_factory.mktemp("cli") / "run", x, 0.5, config)


def test_analyze_writes_json_and_plots(run, capsys):
    assert main(["analyze", str(run), "--knot-samples", "3"]) == 0
    out = capsys.readouterr().out
    for word in ("V [d/tau_d]", "tau_swirl/tau_sed", "counterclockwise", "handedness right"):
        assert word in out
    result = json.loads((run / "analysis.json").read_text())
    assert result["tau_swirl"] == pytest.approx(20.0, rel=0.01)
    assert len(result["plots"]) == 4
    for name in result["plots"]:
        png = run / name
        assert png.read_bytes()[:4] == b"\x89PNG" and png.stat().st_size > 10_000


def test_analyze_options(run, tmp_path, capsys):
    code = main(
        [
            "analyze",
            str(run),
            "--from",
            "20",
            "--to",
            "120",
            "--p",
            "2",
            "--q",
            "3",
            "--no-plots",
            "--knot-samples",
            "0",
            "--out",
            str(tmp_path),
        ]
    )
    assert code == 0
    result = json.loads((tmp_path / "analysis.json").read_text())
    assert result["window"] == [20.0, 120.0]
    assert result["p_source"] == "argument" and result["plots"] == []
    assert not result["window_info"]["automatic_start"]


@pytest.mark.parametrize(
    "args, message",
    [
        (["{missing}"], "no such run directory"),
        (["{run}", "--from", "900"], "--from 900 lies outside"),
        (["{run}/trajectory.dcd", "--topology", "{missing}"], "--topology"),
        (["{run}", "--p", "0"], "--p 0"),
    ],
)
def test_errors_exit_2_with_one_line(run, tmp_path, capsys, args, message):
    argv = [
        "analyze",
        *(a.format(run=run, missing=tmp_path / "missing") for a in args),
        "--no-plots",
        "--knot-samples",
        "0",
        "--out",
        str(tmp_path),
    ]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("knotmm: error:") and message in err
    assert err.count("\n") == 1


def test_plot_functions_return_axes(run):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.axes import Axes

    from knotmm import analysis

    result = analysis.analyze(analysis.load_run(run), knot_samples=0)
    try:
        for func, kwargs in (
            (analysis.plot_com_height, {}),
            (analysis.plot_bead_coordinate, {"which": "alpha", "beads": [0, 5]}),
            (analysis.plot_spectrum, {}),
            (analysis.plot_collapse, {}),
            (analysis.plot_snapshot, {"view": "top"}),
            (analysis.plot_snapshot, {"view": "3d"}),
        ):
            assert isinstance(func(result, **kwargs), Axes)
        _, ax = plt.subplots()
        assert analysis.plot_spectrum(result, ax=ax) is ax
        assert len(analysis.plot_time_series(result)) == 4
    finally:
        plt.close("all")


def test_default_plot_beads_are_not_symmetric_images_of_each_other():
    """In a T(2,3) of 90 beads, beads 30 apart trace the same curves: pick within 30."""
    from knotmm.analysis.plots import _default_beads

    assert _default_beads(90, 3, q=3) == [0, 10, 20]
    assert _default_beads(90, 6, q=3) == [0, 5, 10, 15, 20, 25]
    assert _default_beads(91, 3, q=3) == [0, 30, 61]  # no exact symmetry: whole chain
    assert _default_beads(90, 3, q=None) == [0, 30, 60]


def test_analyze_into_an_unwritable_place_is_one_line(run, capsys):
    """Issue 11, item 4 (analyze): an output directory that cannot be made or written gives
    one line naming the path and the cause, exit 2, no traceback. /proc refuses new entries
    even to root, so this needs no permission games."""
    target = "/proc/knotmm-analysis-out"
    assert main(["analyze", str(run), "--knot-samples", "0", "--out", target]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and target in err[0] and "Traceback" not in err[0], err
