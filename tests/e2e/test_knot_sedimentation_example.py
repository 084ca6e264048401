"""examples/knot_sedimentation/make_figure.py: error propagation, the fit, the table."""

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from example_scripts import load_script

SCRIPT = (Path(__file__).resolve().parents[2] / "examples" / "knot_sedimentation"
          / "make_figure.py")


@pytest.fixture(scope="module")
def mf():
    return load_script(SCRIPT)


def test_ratio_error_is_quadrature_of_relative_errors(mf):
    r, se = mf.ratio(2.0, 0.1, 1.0, 0.05)
    assert r == pytest.approx(2.0)
    assert se == pytest.approx(2.0 * np.sqrt(0.05**2 + 0.05**2))


def test_ratio_error_matches_monte_carlo(mf):
    rng = np.random.default_rng(3)
    v, v0 = rng.normal(12.0, 0.06, 200_000), rng.normal(8.0, 0.04, 200_000)
    _, se = mf.ratio(12.0, 0.06, 8.0, 0.04)
    assert se == pytest.approx(np.std(v / v0), rel=0.02)


def test_linear_fit_exact_line(mf):
    x = np.array([0.0, 3.0, 4.0, 5.0, 7.0])
    fit = mf.linear_fit(x, 1.0 + 0.1 * x)
    assert fit["slope"] == pytest.approx(0.1)
    assert fit["intercept"] == pytest.approx(1.0)
    assert fit["r2"] == pytest.approx(1.0)


def test_linear_fit_against_closed_form(mf):
    rng = np.random.default_rng(1)
    x = np.linspace(0.0, 10.0, 9)
    y = 0.5 + 0.2 * x + rng.normal(0.0, 0.1, x.size)
    fit = mf.linear_fit(x, y)
    # ordinary least squares by hand: slope = Sxy / Sxx, se^2 = s^2 / Sxx
    dx, dy = x - x.mean(), y - y.mean()
    slope = (dx @ dy) / (dx @ dx)
    resid = dy - slope * dx
    s2 = (resid @ resid) / (x.size - 2)
    assert fit["slope"] == pytest.approx(slope)
    assert fit["slope_se"] == pytest.approx(np.sqrt(s2 / (dx @ dx)))
    assert fit["r2"] == pytest.approx(1.0 - (resid @ resid) / (dy @ dy))


def _fake_set(directory: Path, speeds: dict[str, float]) -> None:
    directory.mkdir()
    points = {}
    for k, (knot, v) in enumerate(speeds.items()):
        stats = {"sedimentation_velocity": {"n": 8, "mean": v, "std_error": 0.01 * v},
                 "average_crossing_number": {"n": 8, "mean": 2.0 + 3.0 * k, "std_error": 0.1},
                 "radius_of_gyration": {"n": 8, "mean": 5.0, "std_error": 0.1}}
        points[f"knot.name={knot}"] = {"runs": [], "failed": {}, "statistics": stats}
    (directory / "replicas.json").write_text(json.dumps({"points": points}))
    with (directory / "summary.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["point", "knot_type_start", "knot_type_end", "knot_type_changed_at"])
        for knot in speeds:
            w.writerow([f"knot.name={knot},replica=0", knot, knot, ""])
            w.writerow([f"knot.name={knot},replica=1", knot, "0_1", "40.0"])


def test_main_writes_table_and_figure(mf, tmp_path):
    _fake_set(tmp_path / "set", {"3_1": 12.0, "0_1": 8.0, "7_1": 16.0})
    out = tmp_path / "out"
    assert mf.main([f"demo={tmp_path / 'set'}", "--out", str(out)]) == 0
    rows = list(csv.DictReader((out / "table.csv").open()))
    assert [r["knot"] for r in rows] == ["0_1", "3_1", "7_1"]
    assert float(rows[2]["V_over_V0"]) == pytest.approx(2.0)
    assert float(rows[2]["V_over_V0_se"]) == pytest.approx(2.0 * np.sqrt(2) * 0.01, rel=1e-4)
    assert rows[1]["knot_changed_replicas"] == "1"
    assert (out / "v_over_v0_vs_acn.png").stat().st_size > 1000
    assert (out / "v_over_v0_vs_crossing_number.png").stat().st_size > 1000
    md = (out / "tables.md").read_text()
    assert "| demo | 8.00 +- 0.08 | 1.50 +- 0.02 | 2.00 +- 0.03 |" in md


def test_set_without_unknot_is_one_line_exit_2(mf, tmp_path, capsys):
    _fake_set(tmp_path / "set", {"3_1": 12.0, "4_1": 13.0})
    with pytest.raises(SystemExit) as info:
        mf.main([str(tmp_path / "set"), "--out", str(tmp_path / "out")])
    assert info.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "0_1" in err


def test_other_swept_keys_make_separate_sets(mf, tmp_path):
    d = tmp_path / "grid"
    d.mkdir()
    points = {}
    for pe, v0 in (("inf", 7.0), ("10.0", 8.0)):
        for knot, v in (("0_1", v0), ("3_1", 2.0 * v0)):
            stats = {"sedimentation_velocity": {"n": 8, "mean": v, "std_error": 0.1},
                     "average_crossing_number": {"n": 8, "mean": 1.0 if knot == "3_1" else 0.0,
                                                 "std_error": 0.1}}
            points[f"knot.name={knot},run.peclet={pe}"] = {"statistics": stats}
    (d / "replicas.json").write_text(json.dumps({"points": points}))
    assert mf.main([f"g={d}", "--out", str(tmp_path / "out")]) == 0
    rows = list(csv.DictReader((tmp_path / "out" / "table.csv").open()))
    assert sorted({r["set"] for r in rows}) == ["g run.peclet=10.0", "g run.peclet=inf"]
    assert all(float(r["V_over_V0"]) == pytest.approx(2.0) for r in rows if r["knot"] == "3_1")


def test_knot_checks_come_from_the_runs_own_record(mf, tmp_path):
    sweep = tmp_path / "sweep"
    _fake_set(sweep, {"3_1": 12.0, "0_1": 8.0})
    for name, final, changes in (
        ("knot.name=0_1,replica=0", "0_1", ""),
        ("knot.name=3_1,replica=0", "+7_5", '{ time = 70.0, from = "+3_1", to = "+7_5" }'),
        ("knot.name=3_1,replica=1", "+3_1", ""),
    ):
        (sweep / name).mkdir()
        (sweep / name / "run.toml").write_text(
            f'[knotmm]\nknot_type_start = "{name[10:13]}"\nknot_type = "{final}"\n'
            f"knot_type_checks = 20\nknot_type_changes = [{changes}]\n")
    mf.write_knot_checks(sweep, sweep)
    rows = list(csv.DictReader((sweep / "knot_checks.csv").open()))
    assert rows[1]["knot_type_changes"] == "70:+3_1>+7_5"
    # the runs' record wins over summary.csv's (where replica 1 of each knot ends as 0_1)
    assert mf.knot_changes(sweep)[("", "3_1")] == (1, 1, "+3_1;+7_5")
    assert mf.knot_changes(sweep)[("", "0_1")] == (0, 1, "0_1")


#: The README's 16 sets: label -> directory under results/ (the saved replicas.json files).
SAVED_SETS = {f"{who} {window}": f"{prefix}{name}"
              for who, prefix in (("N120 rep", ""), ("N90 rep", "n90_"),
                                  ("N120 norep", "norep_"), ("N90 norep", "n90_norep_"))
              for window, name in (("Pe=inf 20-70", "pe_inf_early"),
                                   ("Pe=inf 150-200", "pe_inf_late"), ("Pe=10", "pe10"),
                                   ("Pe=1", "pe1"))}


@pytest.fixture(scope="module")
def saved_rows(mf):
    results = SCRIPT.parent / "results"
    return [row for label, d in SAVED_SETS.items() for row in mf.read_set(label, results / d)]


def test_readme_command_names_the_16_saved_sets(mf):
    """The README's command lists every set as LABEL=DIR, as this test reads them."""
    readme = (SCRIPT.parent / "README.md").read_text()
    for label, d in SAVED_SETS.items():
        assert f'"{label}=results/{d}"' in readme, label


def test_saved_figure_knot_labels_overlap_nothing(mf, saved_rows):
    """Issue 35: the knot labels were printed over each other ("4512" for 4_1 and 5_2). On
    the saved data of all 16 sets: no two texts of the figure overlap (2 px apart), every
    knot label lies inside its panel, near its own marker (or joined to it by a line), and
    no text is smaller than 8 pt at the figure's 150 dpi."""
    import sys

    import matplotlib

    matplotlib.use("Agg")
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from drawn_text import overlapping_texts, smallest_text_px

    per_set, _ = mf.set_fits(saved_rows)
    fig = mf.acn_figure(saved_rows, per_set)
    assert overlapping_texts(fig, pad=1.0) == []
    assert smallest_text_px(fig) >= 8 * fig.dpi / 72 - 1e-9
    renderer = fig.canvas.get_renderer()
    named = 0
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        frame = ax.get_window_extent(renderer)
        for text in ax.texts:
            box = text.get_window_extent(renderer)
            assert frame.x0 <= box.x0 and box.x1 <= frame.x1, text.get_text()
            assert frame.y0 <= box.y0 and box.y1 <= frame.y1, text.get_text()
            point = ax.transData.transform(text.xy)
            near = np.hypot(point[0] - np.clip(point[0], box.x0, box.x1),
                            point[1] - np.clip(point[1], box.y0, box.y1))
            assert near <= 30 * fig.dpi / 72 or text.arrow_patch is not None, text.get_text()
            named += 1
    assert named == len(saved_rows) == 16 * 7
