"""examples/orbit_stability/replot.py: the example's figures drawn again from its saved
results (issue 35: continuation.png was stale, with raw key names as axis labels)."""

from __future__ import annotations

import csv
import shutil
import sys
from pathlib import Path

import matplotlib
import pytest
from example_scripts import load_script
from saved_figures import saved_figures

matplotlib.use("Agg")

from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402

HERE = Path(__file__).resolve()
EXAMPLE = HERE.parents[2] / "examples" / "orbit_stability"
FIGURES = ("continuation.png", "beads_continuation.png", "exponent_vs_N.png")


@pytest.fixture(scope="module")
def replot():
    return load_script(EXAMPLE / "replot.py")


@pytest.fixture(scope="module")
def drawn(replot, tmp_path_factory):
    """The three figures as replot.py draws them from a copy of results/."""
    results = tmp_path_factory.mktemp("orbit_results")
    for path in (EXAMPLE / "results").iterdir():
        if path.suffix in (".csv", ".json"):
            shutil.copy(path, results / path.name)
    with saved_figures() as captured:
        assert replot.main(["--results", str(results)]) == 0
    assert all((results / name).stat().st_size > 10_000 for name in FIGURES)
    for fig in captured:
        FigureCanvasAgg(fig)  # pyplot closed the first two; draw them again on Agg
        fig.set_dpi(110)  # the dpi they are written at
    return dict(zip(FIGURES, captured, strict=True))


@pytest.mark.parametrize("name", FIGURES)
def test_no_texts_overlap_and_labels_have_units(drawn, name):
    sys.path.insert(0, str(HERE.parents[1]))
    from drawn_text import overlapping_texts, smallest_text_px

    fig = drawn[name]
    assert overlapping_texts(fig) == []
    assert smallest_text_px(fig) >= 8 * 110 / 72
    for ax in fig.axes:  # no raw run-file key as an axis label
        assert not any(k in ax.get_xlabel() for k in ("model.", "knot.", "tau_d")), \
            ax.get_xlabel()
        assert "tau_" not in ax.get_ylabel().replace("\\tau_", ""), ax.get_ylabel()
    assert "[" in fig.axes[0].get_xlabel() or "$N$" in fig.axes[0].get_xlabel()


def test_changes_of_stability_found_again_where_the_run_counted_them(replot):
    """The beads continuation kept only its CSV: the changes of stability found again from
    its multipliers lie where its own count of unstable multipliers changes."""
    key, rows = replot.read_rows(EXAMPLE / "results" / "beads_continuation.csv")
    found = [b.value for b in replot.discrete_bifurcations(key, rows)]
    with (EXAMPLE / "results" / "beads_continuation.csv").open(newline="") as fh:
        saved = list(csv.DictReader(fh))
    counted = [float(b["knot.beads"]) for a, b in zip(saved, saved[1:], strict=False)
               if a["unstable_multipliers"] != b["unstable_multipliers"]]
    assert found == counted and len(counted) == 10  # N = 41 ... 50, as the README says
