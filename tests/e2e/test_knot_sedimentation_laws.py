"""examples/knot_sedimentation/fit_laws.py: the weighted fits, chi^2, V0's propagation,
and results/laws.csv as the script makes it from the saved sets."""

import csv
import math
from pathlib import Path

import numpy as np
import pytest
from example_scripts import load_script
from scipy import stats

FOLDER = Path(__file__).resolve().parents[2] / "examples" / "knot_sedimentation"


@pytest.fixture(scope="module")
def fl():
    return load_script(FOLDER / "fit_laws.py")


def test_exact_line_gives_zero_chi2_and_its_slope(fl):
    x = np.array([0.0, 3.0, 4.0, 5.0, 5.0, 6.0, 7.0])
    sy = np.array([0.01, 0.05, 0.02, 0.1, 0.03, 0.04, 0.06])
    fit = fl.weighted_fit(x, 1.2 + 0.07 * x, sy)
    assert fit["chi2"] == pytest.approx(0.0, abs=1e-20)
    assert fit["dof"] == 5
    assert fit["coef"] == pytest.approx([1.2, 0.07], rel=1e-12)
    quad = fl.weighted_fit(x, 1.2 + 0.07 * x - 0.003 * x**2, sy, degree=2)
    assert quad["coef"] == pytest.approx([1.2, 0.07, -0.003], rel=1e-10)
    assert quad["chi2"] == pytest.approx(0.0, abs=1e-18)


def test_weighted_line_against_the_closed_form(fl, rng):
    x = np.array([0.0, 3.0, 4.0, 5.0, 5.5, 6.0, 7.0])
    sy = rng.uniform(0.02, 0.2, x.size)
    y = 1.0 + 0.05 * x + rng.normal(0.0, sy)
    fit = fl.weighted_fit(x, y, sy)
    # the textbook sums: S = sum w, Sx, Sxx, Sy, Sxy with w = 1 / sy^2
    w = 1.0 / sy**2
    s, sx_, sxx, sy_, sxy = w.sum(), w @ x, w @ x**2, w @ y, w @ (x * y)
    delta = s * sxx - sx_**2
    slope, icpt = (s * sxy - sx_ * sy_) / delta, (sxx * sy_ - sx_ * sxy) / delta
    chi2 = (w * (y - icpt - slope * x) ** 2).sum()
    assert fit["coef"] == pytest.approx([icpt, slope], rel=1e-10)
    assert fit["cov"][1, 1] == pytest.approx(s / delta, rel=1e-10)
    assert fit["cov"][0, 0] == pytest.approx(sxx / delta, rel=1e-10)
    assert fit["chi2"] == pytest.approx(chi2, rel=1e-10)
    assert fit["p"] == pytest.approx(stats.chi2.sf(chi2, 5), rel=1e-10)


@pytest.mark.parametrize("x_errors", [False, True])
def test_known_gaussian_errors_give_chi2_per_dof_near_one(fl, rng, x_errors):
    """Many synthetic sets from a true line with known errors (in y, and in x with a
    correlation where asked): mean chi^2 / dof near 1 and p-values uniform."""
    xt = np.array([0.0, 8.0, 16.0, 6.0, 23.0, 33.0, 8.0])
    sy = np.array([0.01, 0.06, 0.05, 0.02, 0.07, 0.06, 0.03])
    sx = np.array([0.5, 1.2, 1.0, 0.3, 1.4, 2.2, 0.4]) if x_errors else np.zeros(7)
    rho = 0.4 if x_errors else 0.0
    cxy = rho * sx * sy
    a, b = 1.1, 0.05
    chi2, pvals = [], []
    for _ in range(2000):
        z1, z2 = rng.normal(size=(2, 7))
        ex = sx * z1
        ey = sy * (rho * z1 + math.sqrt(1 - rho**2) * z2)  # cov(ex, ey) = rho sx sy
        fit = fl.weighted_fit(xt + ex, a + b * xt + ey, sy, 1, sx, cxy)
        chi2.append(fit["chi2"] / fit["dof"])
        pvals.append(fit["p"])
    # chi^2 / dof with 5 dof has variance 2/5: the mean of 2000 is 1 +- 0.014
    assert np.mean(chi2) == pytest.approx(1.0, abs=0.05)
    assert 0.035 < np.mean(np.array(pvals) < 0.05) < 0.065
    assert stats.kstest(pvals, "uniform").pvalue > 1e-3


def test_v0_propagation_without_the_unknot_is_the_first_order_formula(fl, rng):
    x = np.array([3.0, 4.0, 5.0, 5.0, 6.0, 7.0])
    sy = np.full(6, 0.05)
    y = 1.0 + 0.1 * x + rng.normal(0.0, 0.05, 6)
    fit = fl.weighted_fit(x, y, sy)
    rel0 = 0.04
    cov = fl.v0_propagated_cov(fit, sy, np.zeros(6), np.zeros(6), None, rel0)
    # c = C / V0 with C independent of V0: var(c)/c^2 = var(C)/C^2 + (s0/V0)^2
    b = fit["coef"][1]
    assert cov[1, 1] == pytest.approx(fit["cov"][1, 1] + b**2 * rel0**2, rel=1e-12)
    a = fit["coef"][0]
    assert cov[0, 0] == pytest.approx(fit["cov"][0, 0] + a**2 * rel0**2, rel=1e-12)


@pytest.mark.parametrize("with_unknot", [True, False])
def test_v0_propagation_matches_monte_carlo(fl, rng, with_unknot):
    """Draw the speeds (and correlated x) of every knot type, the unknot's too, divide by the
    drawn V0, refit with the weights held: the slope's spread is the propagated error."""
    x = np.array([6.0, 8.0, 16.0, 6.0, 23.0, 33.0, 8.0])
    v = np.array([7.0, 14.0, 17.0, 12.5, 19.0, 21.0, 12.6])
    sv = np.array([0.4, 0.5, 0.4, 0.05, 0.5, 0.45, 0.06])
    sx = np.array([0.5, 1.2, 1.0, 0.01, 1.4, 2.2, 0.02])
    rho = -0.5
    cxv = rho * sx * sv
    v0 = v[0]
    keep = slice(None) if with_unknot else slice(1, None)
    fit = fl.weighted_fit(x[keep], (v / v0)[keep], (sv / v0)[keep], 1, sx[keep],
                          (cxv / v0)[keep])
    cov = fl.v0_propagated_cov(fit, (sv / v0)[keep], sx[keep], (cxv / v0)[keep],
                               0 if with_unknot else None, sv[0] / v0)
    w = np.sqrt(1.0 / fit["var"])  # numpy.polyfit's weights are 1 / sigma
    z1, z2 = rng.normal(size=(2, 40000, 7))
    xs = x + sx * z1
    vs = v + sv * (rho * z1 + math.sqrt(1 - rho**2) * z2)
    ys = vs / vs[:, :1]
    slopes = [np.polyfit(xs[k, keep], ys[k, keep], 1, w=w)[0] for k in range(len(ys))]
    assert np.std(slopes) == pytest.approx(math.sqrt(cov[1, 1]), rel=0.03)
    assert np.mean(slopes) == pytest.approx(fit["coef"][1], abs=0.05 * math.sqrt(cov[1, 1])
                                            + 2e-3 * abs(fit["coef"][1]))


def test_bootstrap_of_replicas_on_a_line_gives_r2_one(fl, rng):
    names = ["0_1", "3_1", "4_1", "5_1"]
    acn = {"0_1": 1.0, "3_1": 10.0, "4_1": 14.0, "5_1": 20.0}
    reps = [(np.full(8, 5.0 * (1.0 + 0.02 * acn[k])), np.full(8, acn[k])) for k in names]
    r2 = fl.bootstrap_r2(reps, "ACN", names, 1, np.ones(4, bool), 50, rng)
    assert r2 == pytest.approx(np.ones(50), abs=1e-12)
    noisy = [(v + rng.normal(0, 0.3, 8), xr) for v, xr in reps]
    r2 = fl.bootstrap_r2(noisy, "ACN", names, 1, np.ones(4, bool), 200, rng)
    assert 0.0 < r2.min() < r2.max() < 1.0 and r2.std() > 1e-3


def _rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _same(a, b):
    try:
        fa, fb = float(a), float(b)
    except ValueError:
        return a == b
    return (math.isnan(fa) and math.isnan(fb)) or fa == pytest.approx(fb, rel=2e-5, abs=1e-12)


def test_saved_laws_csv_is_what_the_script_makes(fl, tmp_path):
    assert fl.main(["--out", str(tmp_path)]) == 0
    made, saved = _rows(tmp_path / "laws.csv"), _rows(FOLDER / "results" / "laws.csv")
    assert len(made) == len(saved) == 16 * len(fl.LAWS) * 2 * 2
    for m, s in zip(made, saved, strict=True):
        assert m.keys() == s.keys()
        bad = [k for k in m if not _same(m[k], s[k])]
        assert not bad, (m["set"], m["law"], bad)
    assert (tmp_path / "laws.md").read_text() == (FOLDER / "results" / "laws.md").read_text()


def test_laws_agree_with_the_tables_of_make_figure(fl):
    """The same means as table.csv, and the unweighted R^2 of fits.csv (numpy.polyfit there)."""
    table = {(r["set"], r["knot"]): r for r in _rows(FOLDER / "results" / "table.csv")}
    fits = {(r["set"], r["x"], r["points"]): r for r in _rows(FOLDER / "results" / "fits.csv")}
    laws = _rows(FOLDER / "results" / "laws.csv")
    assert {r["set"] for r in laws} == {k[0] for k in table}
    for label, knots in fl.read_sets([(s, FOLDER / "results" / d) for s, d in fl.SETS]):
        names, x, _, v, _, _, _ = fl.points(knots, "ACN")
        for k, xi, vi in zip(names, x, v, strict=True):
            assert xi == pytest.approx(float(table[(label, k)]["ACN"]), rel=1e-5)
            assert vi / v[0] == pytest.approx(float(table[(label, k)]["V_over_V0"]), rel=1e-5)
    for r in laws:
        if r["law"] in ("ACN", "crossing_number") and r["degree"] == "1":
            f = fits[(r["set"], r["law"], r["points"])]
            assert float(r["r2"]) == pytest.approx(float(f["r2"]), rel=1e-4)


def test_ropelengths_are_knotinfos(fl):
    knotinfo = pytest.importorskip("database_knotinfo")
    got = {k["name"]: k["ropelength"] for k in knotinfo.link_list()[:40]}
    for knot, value in fl.ROPELENGTH.items():
        if knot != "0_1":
            assert value == pytest.approx(float(got[knot]), rel=1e-9)
    assert fl.ROPELENGTH["0_1"] == pytest.approx(math.pi)  # the round circle: L / D = pi


def test_missing_set_is_one_line_exit_2(fl, tmp_path, capsys):
    with pytest.raises(SystemExit) as err:
        fl.main([f"x={tmp_path / 'nothing'}", "--out", str(tmp_path / "out")])
    assert err.value.code == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "replicas.json" in lines[0]


def test_simulated_p_tends_to_the_chi2_p_with_many_replicas(fl, rng):
    """With 2000 replicas per point the errors are known: the simulated p is the chi^2 p."""
    x = np.array([0.0, 3.0, 4.0, 5.0, 5.5, 6.0, 7.0])
    sy = np.full(7, 0.05)
    y = 1.0 + 0.05 * x + np.array([0.06, -0.05, 0.02, 0.07, -0.08, 0.01, 0.04])
    fit = fl.weighted_fit(x, y, sy)
    p = fl.simulated_p(fit, sy, np.zeros(7), np.zeros(7), [2000] * 7, fit["chi2"], 400, rng)
    assert 0.05 < fit["p"] < 0.95
    assert p == pytest.approx(fit["p"], abs=0.08)
    exact = fl.weighted_fit(x, 1.0 + 0.05 * x, sy)
    assert fl.simulated_p(exact, sy, np.zeros(7), np.zeros(7), [8] * 7, exact["chi2"],
                          50, rng) == 1.0


def test_readme_states_the_saved_verdicts_and_table(fl):
    """The README's per-set lines and six-knot table are those laws.md holds."""
    readme = (FOLDER / "README.md").read_text()
    md = (FOLDER / "results" / "laws.md").read_text()
    verdicts = [line for line in md.splitlines() if line.startswith("- N")]
    assert len(verdicts) == 16
    for line in verdicts:
        assert line in readme, line
    table = [line for line in md.split("Straight lines over all 7")[0].splitlines()
             if line.startswith("| N")]
    assert len(table) == 16 and all(line in readme for line in table)
    assert "python examples/knot_sedimentation/fit_laws.py" in readme


def test_simulated_p_is_calibrated_with_errors_from_8_replicas(fl, rng):
    """Sets drawn from a true line, 8 Gaussian replicas per point, errors estimated from
    them: the simulated p falls below 0.1 about 10 % of the time; the chi^2 p, which takes
    the estimated errors as exact, more often."""
    x = np.array([0.0, 3.0, 4.0, 5.0, 5.5, 6.0, 7.0])
    sd = np.array([0.1, 0.2, 0.15, 0.05, 0.2, 0.1, 0.3])  # one replica's spread
    low_sim = low_chi2 = 0
    sets = 200
    for _ in range(sets):
        reps = 1.0 + 0.05 * x[:, None] + sd[:, None] * rng.normal(size=(7, 8))
        y, sy = reps.mean(1), reps.std(1, ddof=1) / math.sqrt(8)
        fit = fl.weighted_fit(x, y, sy)
        p = fl.simulated_p(fit, sy, np.zeros(7), np.zeros(7), [8] * 7, fit["chi2"], 100, rng)
        low_sim += p < 0.1
        low_chi2 += fit["p"] < 0.1
    assert 0.04 < low_sim / sets < 0.17
    assert low_chi2 > low_sim


def _rows_of(fl, label, chi2, dof, sims):
    return [{"set": label, "law": law, "degree": 1, "points": "knots", "chi2": chi2, "dof": dof,
             "sims": sims} for law in fl.LAWS]


def test_pooled_sum_of_sets_is_the_chi2_law_of_the_summed_dof(fl, rng):
    """Independent sets whose simulated chi^2 follow the chi^2 law: the summed chi^2 is the
    chi^2 law with the summed degrees of freedom (closed form), and the pooled simulated p
    (draws summed index by index) is its survival function."""
    dofs, chi2s, draws = (4, 4, 3), (6.0, 2.5, 5.0), 20000
    rows = []
    for i, (dof, chi2) in enumerate(zip(dofs, chi2s, strict=True)):
        rows += _rows_of(fl, f"set{i} 150-200", chi2, dof, rng.chisquare(dof, draws))
    rows += _rows_of(fl, "alone 50-100", 1.0, 4, rng.chisquare(4, draws))  # a group of one
    lines = [line for line in "".join(fl.pooled(rows)).splitlines() if line.startswith("| ")]
    assert len(lines) == 2 and lines[1].startswith("| 150-200 | 3 |")
    total = sum(chi2s)
    exact = stats.chi2.sf(total, sum(dofs))
    cell = lines[1].split(" | ")[2]  # the ACN column
    assert cell.startswith(f"{total:.1f} / {sum(dofs)} ")
    p_chi2, p_sim = (float(v) for v in cell.split("(")[1].rstrip(")").split(" / "))
    assert p_chi2 == pytest.approx(exact, rel=0.01)
    assert p_sim == pytest.approx(exact, abs=0.01)
    assert fl.pooled(_rows_of(fl, "one 150-200", 1.0, 4, np.ones(5))) == []


def test_saved_rerun_laws_are_what_the_script_makes(fl, tmp_path):
    """results/rerun_200: the fits of the 200 tau_d thermal sets, remade from the saved
    replicas.json of every set that RERUN_SETS names."""
    assert len(fl.RERUN_SETS) == 16
    assert fl.main(["--rerun", "--out", str(tmp_path)]) == 0
    saved = FOLDER / "results" / "rerun_200"
    made, kept = _rows(tmp_path / "laws.csv"), _rows(saved / "laws.csv")
    assert len(made) == len(kept) == 16 * len(fl.LAWS) * 2 * 2
    for m, s in zip(made, kept, strict=True):
        bad = [k for k in m if not _same(m[k], s[k])]
        assert not bad, (m["set"], m["law"], bad)
    assert (tmp_path / "laws.md").read_text() == (saved / "laws.md").read_text()
    readme = (FOLDER / "README.md").read_text()
    assert "fit_laws.py --rerun" in readme
    for line in (saved / "laws.md").read_text().splitlines():
        if line.startswith("- N"):
            assert line in readme, line
