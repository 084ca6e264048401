"""Weighted fits of V / V0 against the candidate laws, per set, with chi^2 and p-values.

Usage::

    python examples/knot_sedimentation/fit_laws.py [[LABEL=]DIR ...] [--out DIR] [--boot B]
    python examples/knot_sedimentation/fit_laws.py --rerun

Without ``DIR`` it reads the 16 saved sets of ``results/`` (the labels of the README), with
``--rerun`` the 16 saved sets of the thermal runs at the designed 200 tau_d
(:data:`RERUN_SETS`; default OUT ``results/rerun_200``). Each ``DIR`` holds a
``replicas.json`` (``knotmm analyze``) whose points differ in ``knot.name`` and which holds
the unknot ``0_1``. It writes ``OUT/laws.csv`` (one row per set, law, degree and point set)
and ``OUT/laws.md`` (default OUT: ``results`` beside this script); ``laws.md`` ends with
the straight lines' chi^2 summed over the sets that share a window (:func:`pooled`).

The data of a set: per knot type i the replicas' mean sedimentation speed ``V_i`` and its
standard error ``s_i`` (d / tau_d), and the mean ``x_i`` of the law's variable over the
replicas with its standard error and its covariance with ``V_i`` (from the per-replica
values). The laws, ``V / V0 = c0 + c1 x (+ c2 x^2)``, with ``x``:

- ``ACN``: the window-mean average crossing number of the sedimenting shape (measured);
- ``ropelength``: the ropelength of the ideal knot (KnotInfo; the ideal knots' ACN is not in
  KnotInfo or in the package, and ropelength is the ideal-shape quantity KnotInfo has);
- ``inv_Rg``, ``inv_Rg_perp``: ``1 / Rg`` and ``1 / Rg_perp`` (1/d), Rg_perp the radius of
  gyration perpendicular to gravity (the law Piili et al. 2013 found for DNA knots);
- ``crossing_number``: the minimal crossing number of the knot type the ring started as.

The fit (:func:`weighted_fit`): weighted least squares in units of the measured ``V0``, the
errors of ``x`` carried by the effective variance ``s_y^2 + f'(x)^2 s_x^2 - 2 f'(x)
cov(x, y)`` (iterated to a fixed point); chi^2, its degrees of freedom and p-value; the
parameter errors from the points' errors (not rescaled by chi^2 / dof), with ``V0``'s own
uncertainty propagated to first order (:func:`v0_propagated_cov`); the errors rescaled by
``sqrt(chi^2 / dof)`` where that exceeds 1 are given beside them. ``r2`` is the R^2 of the
unweighted fit of the mean points (descriptive, as ``fits.csv``); ``r2_lo``/``r2_hi`` the 2.5 and
97.5 % points of the unweighted fit's R^2 over sets of replicas resampled with replacement
within each knot type (:func:`bootstrap_r2`). Quadratic against linear: the F-test
``F = (chi2_lin - chi2_quad) / (chi2_quad / dof_quad)`` with (1, dof_quad) degrees of
freedom (it needs the errors only up to a common factor; F <= 0, p = 1: no better).

The points' errors are themselves estimated from 8 replicas, so chi^2 has heavier tails
than the chi^2 distribution: ``p_sim`` (:func:`simulated_p`, straight lines) is the p-value
from sets simulated under the fitted line with errors re-estimated from 8 Gaussian replicas
each, and the verdicts of ``laws.md`` use it (rejected: ``p_sim < 0.01``; strained: < 0.05).
Laws compared on the same points have two parameters each, so their AIC differences are
their chi^2 differences.

Units: speeds in d / tau_d, lengths in d; V / V0, ACN, ropelength, chi^2 dimensionless.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import re
import sys
from pathlib import Path

import numpy as np
from scipy import linalg, stats

HERE = Path(__file__).resolve().parent
#: Minimal crossing numbers of the study's knot types.
CROSSING = {"0_1": 0, "3_1": 3, "4_1": 4, "5_1": 5, "5_2": 5, "6_1": 6, "7_1": 7}
#: Ropelength (length / tube diameter) of the ideal knots, KnotInfo's ``ropelength``
#: (database_knotinfo 2026.11.2); the unknot's ideal shape is the round circle, L / D = pi.
ROPELENGTH = {"0_1": math.pi, "3_1": 32.7436, "4_1": 42.0887, "5_1": 47.2016,
              "5_2": 49.4701, "6_1": 56.7058, "7_1": 61.4067}
#: The laws' variables, in table order.
LAWS = ("ACN", "ropelength", "inv_Rg", "inv_Rg_perp", "crossing_number")
#: The 16 saved sets (label, folder under results/), as in the README.
SETS = tuple(
    (f"N{n} {rep} {pe}", f"{'n90_' if n == 90 else ''}{'norep_' if rep == 'norep' else ''}{d}")
    for rep in ("rep", "norep") for n in (120, 90)
    for pe, d in (("Pe=inf 20-70", "pe_inf_early"), ("Pe=inf 150-200", "pe_inf_late"),
                  ("Pe=10", "pe10"), ("Pe=1", "pe1")))
#: The 16 saved sets of the thermal runs at the designed 200 tau_d (README, "The thermal
#: sets at their designed 200 tau_d"): each sweep on its late window and on the old one.
RERUN_SETS = tuple(
    (f"N{n} {rep} Pe={pe} {w}",
     f"n{n}_{rep}_pe{pe}_200_{d}")
    for pe in (10, 1) for rep in ("rep", "norep") for n in (120, 90)
    for w, d in (("150-200", "late"), ("50-100", "mid")))
COLUMNS = ("set", "law", "degree", "points", "n", "dof", "c0", "c0_se", "c1", "c1_se",
           "c1_se_scaled", "c2", "c2_se", "chi2", "chi2_dof", "p", "p_sim", "f_quad", "p_quad",
           "r2", "r2_lo", "r2_hi", "v0", "v0_rel_se")


def _fail(message: str) -> None:
    print(f"fit_laws.py: error: {message}", file=sys.stderr)
    raise SystemExit(2)


def design(x, degree: int) -> np.ndarray:
    """Columns ``1, x, ..., x^degree``, shape (n, degree + 1)."""
    return np.vander(np.asarray(x, float), degree + 1, increasing=True)


def weighted_fit(x, y, sy, degree: int = 1, sx=None, cxy=None, iterations: int = 50) -> dict:
    """Polynomial ``y = sum_k c_k x^k`` by weighted least squares, errors in x included.

    Parameters
    ----------
    x, y, sy : array_like, shape (n,)
        Points and the standard errors of ``y`` (all > 0).
    degree : int
        1 (line) or 2 (quadratic).
    sx, cxy : array_like, shape (n,), optional
        Standard errors of ``x`` and covariances of the ``x`` and ``y`` errors: each point's
        variance is then ``sy^2 + f'(x)^2 sx^2 - 2 f'(x) cxy`` at the current fit, iterated
        until the coefficients stop changing (the effective-variance method).

    Returns
    -------
    dict
        ``coef`` (degree + 1,), ``cov`` (degree + 1, degree + 1): the covariance from the
        points' errors, unscaled; ``matrix`` (degree + 1, n): the coefficients' weights
        ``(A^T W A)^-1 A^T W`` at the final variances; ``var`` (n,) those variances;
        ``slope`` (n,) the curve's slope ``f'(x)`` at the points; ``x`` (n,) and ``resid``
        (n,) the points' ``x`` and residuals ``y - f(x)``;
        ``chi2``, ``dof``, ``p`` (upper tail of chi^2 with dof degrees of freedom; NaN when
        dof = 0), ``n``.
    """
    x, y, sy = (np.asarray(v, float) for v in (x, y, sy))
    sx = np.zeros_like(x) if sx is None else np.asarray(sx, float)
    cxy = np.zeros_like(x) if cxy is None else np.asarray(cxy, float)
    a = design(x, degree)
    var = sy**2
    coef = None
    for _ in range(iterations):
        w = 1.0 / var
        normal = a.T @ (a * w[:, None])
        matrix = linalg.solve(normal, a.T * w, assume_a="pos")
        new = matrix @ y
        slope = sum(k * new[k] * x ** (k - 1) for k in range(1, degree + 1))
        var = sy**2 + slope**2 * sx**2 - 2.0 * slope * cxy
        done = coef is not None and np.allclose(new, coef, rtol=1e-12, atol=1e-14)
        coef = new
        if done or not (sx.any() or cxy.any()):
            break
    resid = y - a @ coef
    chi2 = float(resid**2 @ (1.0 / var))
    dof = len(x) - (degree + 1)
    cov = linalg.inv(a.T @ (a / var[:, None]))
    return {"coef": coef, "cov": cov, "matrix": matrix, "var": var, "slope": slope,
            "x": x, "resid": resid, "chi2": chi2,
            "dof": dof, "p": float(stats.chi2.sf(chi2, dof)) if dof > 0 else math.nan,
            "n": len(x)}


def v0_propagated_cov(fit: dict, sy, sx, cxy, unknot_index: int | None,
                      y0_se: float) -> np.ndarray:
    """The coefficients' covariance with ``V0``'s own uncertainty propagated, to first order.

    The fit is made in units of the measured ``V0`` (``y_i = V_i / V0``): chi^2 does not
    depend on that unit, but the coefficients ``c = M y`` (``M``: the fit's ``matrix``) scale
    as ``1 / V0``. With ``u_i = dV_i / V0`` and ``w_i = dx_i`` the points' errors and ``g_i =
    f'(x_i)`` the fitted curve's slope, ``dc = sum_i M_i u_i + sum_i (N^-1 a'_i r_i / var_i
    - g_i M_i) w_i - c u_0`` (the derivative of the weighted least squares at the data, the
    weights held: ``N = A^T W A``, ``a'_i = d(1, x_i, x_i^2)/dx_i``, ``r_i`` the residuals),
    the unknot's ``u_0 = dV0 / V0`` entering through its point (where fitted) and through
    the unit; its variance, summed over the points (independent between knot types), is
    returned.

    Parameters
    ----------
    fit : dict
        :func:`weighted_fit`'s result, over the fitted points.
    sy, sx, cxy : array_like, shape (n,)
        The fitted points' errors of ``y`` and ``x`` and their covariances (as fitted).
    unknot_index : int or None
        The unknot's row among the fitted points, or None where it was left out.
    y0_se : float
        ``s0 / V0``, the unknot's relative standard error.

    Returns
    -------
    ndarray, shape (degree + 1, degree + 1)
    """
    c, m, g = fit["coef"], fit["matrix"], fit["slope"]
    x = fit["x"]
    da = np.stack([k * x ** max(k - 1, 0) for k in range(len(c))])  # (p, n): d row_i / dx_i
    ly, lx = m.copy(), fit["cov"] @ (da * (fit["resid"] / fit["var"])) - m * g
    sy, sx, cxy = (np.asarray(v, float).copy() for v in (sy, sx, cxy))
    if unknot_index is None:  # the unknot enters through the unit only
        ly = np.column_stack([ly, np.zeros_like(c)])
        lx = np.column_stack([lx, np.zeros_like(c)])
        sy, sx, cxy = np.append(sy, y0_se), np.append(sx, 0.0), np.append(cxy, 0.0)
        unknot_index = -1
    ly[:, unknot_index] -= c
    return ((ly * sy**2) @ ly.T + (lx * sx**2) @ lx.T + (ly * cxy) @ lx.T
            + (lx * cxy) @ ly.T)


def _values(stat: dict) -> np.ndarray:
    return np.array([math.nan if v is None else v for v in stat["values"]], float)


def law_values(knot: str, stats_: dict, law: str) -> np.ndarray | None:
    """Per-replica values of a law's variable for one knot type, shape (replicas,); None for
    the laws of the knot type (the same for every replica: no error)."""
    if law == "ACN":
        return _values(stats_["average_crossing_number"])
    if law == "inv_Rg":
        return 1.0 / _values(stats_["radius_of_gyration"])
    if law == "inv_Rg_perp":
        return 1.0 / _values(stats_["radius_of_gyration_perp"])
    return None


def law_constant(knot: str, law: str) -> float:
    """The knot-type laws' value (crossing number, ideal ropelength)."""
    return float(CROSSING[knot] if law == "crossing_number" else ROPELENGTH[knot])


def read_sets(items) -> list[tuple[str, dict]]:
    """``[(label, {knot: statistics})]`` from ``[(label, directory)]`` (replicas.json)."""
    out = []
    for label, directory in items:
        path = Path(directory) / "replicas.json"
        if not path.is_file():
            _fail(f"{path} not found: give a sweep directory analysed by `knotmm analyze`")
        groups: dict[str, dict] = {}
        for name, point in json.loads(path.read_text())["points"].items():
            match = re.search(r"knot\.name=([^,]+)", name)
            if match is None:
                _fail(f"{path}: point {name!r} has no knot.name; the sweep must vary knot.name")
            rest = ",".join(p for p in name.split(",") if not p.startswith("knot.name="))
            groups.setdefault(rest, {})[match.group(1)] = point["statistics"]
        for rest, knots in groups.items():
            if "0_1" not in knots:
                _fail(f"{path}: no unknot 0_1 {rest}; V / V0 needs it")
            unknown = sorted(set(knots) - set(CROSSING))
            if unknown:
                _fail(f"{path}: knot types {unknown} have no crossing number here; "
                      f"add them to CROSSING and ROPELENGTH")
            out.append((f"{label} {rest}".strip(), knots))
    return out


def _mean_se_cov(v: np.ndarray, x: np.ndarray | None):
    """Means, standard errors and the covariance of the two means over the replicas where
    both are measured."""
    ok = np.isfinite(v) if x is None else np.isfinite(v) & np.isfinite(x)
    n = int(ok.sum())
    vm, vs = v[ok].mean(), v[ok].std(ddof=1) / math.sqrt(n)
    if x is None:
        return vm, vs, math.nan, 0.0, 0.0
    xm, xs = x[ok].mean(), x[ok].std(ddof=1) / math.sqrt(n)
    c = float(np.cov(v[ok], x[ok], ddof=1)[0, 1]) / n
    return vm, vs, xm, xs, c


def points(knots: dict, law: str):
    """The set's points for one law: knot names, ``x``, ``sx``, ``V``, ``sV``, ``cov(x, V)``
    (arrays over the knot types, unknot first), and the per-replica arrays for resampling."""
    names = sorted(knots, key=lambda k: (CROSSING[k], k))
    rows, reps = [], []
    for k in names:
        v = _values(knots[k]["sedimentation_velocity"])
        xr = law_values(k, knots[k], law)
        vm, vs, xm, xs, c = _mean_se_cov(v, xr)
        if xr is None:
            xm = law_constant(k, law)
        rows.append((xm, xs, vm, vs, c))
        reps.append((v, xr))
    x, sx, v, sv, cxv = (np.array(col) for col in zip(*rows, strict=True))
    return names, x, sx, v, sv, cxv, reps


def bootstrap_r2(reps, law: str, names, degree: int, mask, draws: int, rng) -> np.ndarray:
    """Unweighted R^2 of the degree-``degree`` fit of ``V / V0`` against ``x`` over ``draws``
    resamplings of the replicas (with replacement, within each knot type), shape (draws,)."""
    ys, xs = [], []
    for k, (v, xr) in zip(names, reps, strict=True):
        ok = np.isfinite(v) if xr is None else np.isfinite(v) & np.isfinite(xr)
        idx = rng.integers(0, ok.sum(), size=(draws, ok.sum()))
        ys.append(v[ok][idx].mean(axis=1))
        xs.append(np.full(draws, law_constant(k, law)) if xr is None
                  else xr[ok][idx].mean(axis=1))
    y = np.array(ys).T  # (draws, knots)
    y = y / y[:, [names.index("0_1")]]
    x = np.array(xs).T
    y, x = y[:, mask], x[:, mask]
    a = np.stack([x**k for k in range(degree + 1)], axis=-1)  # (draws, n, p)
    normal = np.einsum("dnp,dnq->dpq", a, a)
    coef = np.linalg.solve(normal, np.einsum("dnp,dn->dp", a, y)[..., None])[..., 0]
    resid = y - np.einsum("dnp,dp->dn", a, coef)
    total = ((y - y.mean(axis=1, keepdims=True)) ** 2).sum(axis=1)
    return 1.0 - (resid**2).sum(axis=1) / total


def simulated_p(fit: dict, sy, sx, cxy, counts, chi2: float, draws: int, rng) -> float:
    """p-value of ``chi2`` with the points' errors themselves estimated from the replicas:
    the fraction of :func:`simulated_chi2`'s sets whose chi^2 is at least ``chi2``
    (dimensionless; at best ``1 / draws`` resolution)."""
    return float(np.mean(simulated_chi2(fit, sy, sx, cxy, counts, draws, rng) >= chi2))


def simulated_chi2(fit: dict, sy, sx, cxy, counts, draws: int, rng) -> np.ndarray:
    """chi^2 of ``draws`` sets simulated under the fitted curve, shape (draws,).

    Per point ``counts[i]`` replicas, Gaussian, centred on ``(x_i, f(x_i))`` with the
    observed covariance of one replica (``counts[i]`` times that of the mean); each set's
    means, standard errors and covariances are refitted like the data.

    Parameters
    ----------
    fit : dict
        :func:`weighted_fit`'s result for the data.
    sy, sx, cxy : array_like, shape (n,)
        The fitted points' errors and covariances.
    counts : array_like of int, shape (n,)
        Replicas behind each point.
    """
    x, c = fit["x"], fit["coef"]
    degree = len(c) - 1
    fx = design(x, degree) @ c
    sy, sx, cxy = (np.asarray(v, float) for v in (sy, sx, cxy))
    rho = np.divide(cxy, sx * sy, out=np.zeros_like(sx), where=sx > 0)
    cols = []
    for i, n in enumerate(counts):
        z1, z2 = rng.normal(size=(2, draws, n)) * math.sqrt(n)
        ys = fx[i] + sy[i] * z1
        xs = x[i] + sx[i] * (rho[i] * z1 + math.sqrt(max(0.0, 1.0 - rho[i] ** 2)) * z2)
        cov = ((ys - ys.mean(1, keepdims=True)) * (xs - xs.mean(1, keepdims=True))).sum(1)
        cols.append((ys.mean(1), ys.std(1, ddof=1) / math.sqrt(n), xs.mean(1),
                     xs.std(1, ddof=1) / math.sqrt(n), cov / (n - 1) / n))
    ym, ys_, xm, xs_, cv = (np.array(col).T for col in zip(*cols, strict=True))
    return np.array([weighted_fit(xm[k], ym[k], ys_[k], degree, xs_[k], cv[k])["chi2"]
                     for k in range(draws)])


def fit_set(label: str, knots: dict, draws: int = 2000, sims: int = 400,
            seed: int = 2026) -> list[dict]:
    """The rows of ``laws.csv`` for one set: every law, degree 1 and 2, over all the knot
    types (``all``) and over the knotted ones (``knots``)."""
    rows = []
    for law in LAWS:
        names, x, sx, v, sv, cxv, reps = points(knots, law)
        counts = np.array([int((np.isfinite(r[0]) if r[1] is None else
                                np.isfinite(r[0]) & np.isfinite(r[1])).sum()) for r in reps])
        i0 = names.index("0_1")
        v0, v0_rel = v[i0], sv[i0] / v[i0]
        y, sy, cxy = v / v0, sv / v0, cxv / v0
        for which in ("all", "knots"):
            mask = np.ones(len(names), bool) if which == "all" else np.array(
                [k != "0_1" for k in names])
            unknot = int(np.flatnonzero(mask).tolist().index(i0)) if mask[i0] else None
            linear = None
            for degree in (1, 2):
                fit = weighted_fit(x[mask], y[mask], sy[mask], degree, sx[mask], cxy[mask])
                cov = v0_propagated_cov(fit, sy[mask], sx[mask], cxy[mask], unknot, v0_rel)
                se = np.sqrt(np.diag(cov))
                scale = math.sqrt(max(1.0, fit["chi2"] / fit["dof"])) if fit["dof"] else math.nan
                plain = np.polyfit(x[mask], y[mask], degree)  # unweighted, for R^2
                resid = y[mask] - np.polyval(plain, x[mask])
                dev = y[mask] - y[mask].mean()
                rng = np.random.default_rng([seed, LAWS.index(law), degree, which == "all"])
                boot = bootstrap_r2(reps, law, names, degree, mask, draws, rng)
                row = {"set": label, "law": law, "degree": degree, "points": which,
                       "n": fit["n"], "dof": fit["dof"], "c0": fit["coef"][0], "c0_se": se[0],
                       "c1": fit["coef"][1], "c1_se": se[1], "c1_se_scaled": se[1] * scale,
                       "c2": fit["coef"][2] if degree == 2 else math.nan,
                       "c2_se": se[2] if degree == 2 else math.nan,
                       "chi2": fit["chi2"], "chi2_dof": fit["chi2"] / fit["dof"],
                       "p": fit["p"], "p_sim": math.nan, "f_quad": math.nan, "p_quad": math.nan,
                       "r2": 1.0 - float(resid @ resid) / float(dev @ dev),
                       "r2_lo": float(np.percentile(boot, 2.5)),
                       "r2_hi": float(np.percentile(boot, 97.5)), "v0": v0,
                       "v0_rel_se": v0_rel}
                if degree == 1:
                    linear = fit
                    row["sims"] = simulated_chi2(fit, sy[mask], sx[mask], cxy[mask],
                                                 counts[mask], sims, rng)
                    row["p_sim"] = float(np.mean(row["sims"] >= fit["chi2"]))
                else:
                    f = (linear["chi2"] - fit["chi2"]) / (fit["chi2"] / fit["dof"])
                    row["f_quad"], row["p_quad"] = f, float(stats.f.sf(f, 1, fit["dof"]))
                rows.append(row)
    return rows


def _g(v, digits=3):
    return "n/a" if not math.isfinite(v) else f"{v:.{digits}g}"


#: A law is rejected where its simulated p-value is below this, strained below STRAINED.
REJECTED, STRAINED = 0.01, 0.05


def verdict(row: dict) -> str:
    """``rejected``, ``strained`` or ``fits`` from a row's simulated p-value."""
    p = row["p_sim"]
    return "rejected" if p < REJECTED else "strained" if p < STRAINED else "fits"


def _p(p: float, draws_floor: float = 0.0025) -> str:
    return f"< {draws_floor:g}" if p < draws_floor else f"{p:.2g}"


def summary(rows: list[dict], which: str = "knots") -> list[str]:
    """One line per set: each straight line's verdict with chi^2/dof and simulated p, the
    laws ordered by chi^2 (same points, two parameters each: AIC differences are chi^2
    differences), the quadratic term's F-test in the ACN, and the slope in the crossing
    number with its error (V0 included, scaled by ``sqrt(chi^2/dof)`` where above 1)."""
    by = {(r["set"], r["law"], r["degree"], r["points"]): r for r in rows}
    out = []
    for label in dict.fromkeys(r["set"] for r in rows):
        lines = sorted((by[(label, law, 1, which)] for law in LAWS), key=lambda r: r["chi2"])
        parts = [f"{r['law']} {verdict(r)} ({_g(r['chi2_dof'])}, p {_p(r['p_sim'])})"
                 for r in lines]
        quad = by[(label, "ACN", 2, which)]
        sig = "significant" if quad["p_quad"] < STRAINED else "not significant"
        cn = by[(label, "crossing_number", 1, which)]
        out.append(f"- {label}: " + "; ".join(parts) + f". Quadratic term in the ACN {sig} "
                   f"(F-test p {_g(quad['p_quad'], 2)}). Slope in the crossing number "
                   f"{cn['c1']:.3f} +- {cn['c1_se_scaled']:.3f} "
                   f"({cn['c1'] / cn['c1_se_scaled']:.1f} s.e.).")
    return out


def markdown(rows: list[dict]) -> str:
    """Two tables, straight lines over the 6 knots and over all 7 (chi^2/dof and p per law)
    and the ACN line's quadratic test, slope and R^2 spread; then the verdicts per set."""
    by = {(r["set"], r["law"], r["degree"], r["points"]): r for r in rows}
    labels = list(dict.fromkeys(r["set"] for r in rows))
    out = []
    for which, title in (("knots", "the 6 knots"), ("all", "all 7 (unknot included)")):
        out.append(f"Straight lines over {title}: chi^2/dof (p from chi^2 / p simulated with "
                   "the errors estimated from 8 replicas)\n\n| set | "
                   + " | ".join(LAWS) + " | ACN: quadratic F-test p | ACN: slope +- s.e. "
                   "(V0 incl.) [x sqrt(chi^2/dof)] | ACN: R^2 (resampled 95 %) |\n|---|"
                   + "---|" * (len(LAWS) + 3) + "\n")
        for label in labels:
            cells = []
            for law in LAWS:
                r = by[(label, law, 1, which)]
                cells.append(f"{_g(r['chi2_dof'])} ({_p(r['p'], 1e-4)} / {_p(r['p_sim'])})")
            lin, quad = by[(label, "ACN", 1, which)], by[(label, "ACN", 2, which)]
            cells += [_g(quad["p_quad"], 2),
                      f"{lin['c1']:.4f} +- {lin['c1_se']:.4f} [{lin['c1_se_scaled']:.4f}]",
                      f"{lin['r2']:.2f} ({lin['r2_lo']:.2f}-{lin['r2_hi']:.2f})"]
            out.append(f"| {label} | " + " | ".join(cells) + " |\n")
        out.append("\n")
    out.append(f"Verdicts over the 6 knots (rejected: simulated p < {REJECTED}; strained: "
               f"< {STRAINED}; laws by increasing chi^2):\n\n")
    out.append("\n".join(summary(rows)) + "\n")
    out += pooled(rows)
    return "".join(out)


def window(label: str) -> str:
    """The group a set is pooled in: the last word of its label (its window or Pe)."""
    return label.split()[-1]


def pooled(rows: list[dict], which: str = "knots") -> list[str]:
    """Straight lines summed over the sets of each group (:func:`window`) with two or more
    sets: per law the sum of chi^2 and of the degrees of freedom, the chi^2 p-value, and the
    simulated p-value of the sum (the sets are independent runs: draw k of every set's
    :func:`simulated_chi2` summed; resolution 1 / draws)."""
    by = {(r["set"], r["law"], r["points"]): r for r in rows if r["degree"] == 1}
    groups: dict[str, list[str]] = {}
    for label in dict.fromkeys(r["set"] for r in rows):
        groups.setdefault(window(label), []).append(label)
    groups = {g: labels for g, labels in groups.items() if len(labels) > 1}
    if not groups:
        return []
    out = ["\nStraight lines over the 6 knots summed over the sets of a group (the last word "
           "of their labels): chi^2 / dof (p from chi^2 / p simulated)\n\n| group | sets | "
           + " | ".join(LAWS) + " |\n|---|---|" + "---|" * len(LAWS) + "\n"]
    for g, labels in groups.items():
        cells = []
        for law in LAWS:
            sets = [by[(label, law, which)] for label in labels]
            chi2 = sum(r["chi2"] for r in sets)
            dof = sum(r["dof"] for r in sets)
            sims = np.sum([r["sims"] for r in sets], axis=0)
            p_sim = float(np.mean(sims >= chi2))
            cells.append(f"{chi2:.1f} / {dof} ({_p(float(stats.chi2.sf(chi2, dof)), 1e-4)} / "
                         f"{_p(p_sim)})")
        out.append(f"| {g} | {len(labels)} | " + " | ".join(cells) + " |\n")
    return out


def write(rows: list[dict], out: Path) -> None:
    """``out/laws.csv`` (6 significant digits) and ``out/laws.md``."""
    out.mkdir(parents=True, exist_ok=True)
    with (out / "laws.csv").open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=COLUMNS, lineterminator="\n",
                                extrasaction="ignore")  # not the simulated chi^2
        writer.writeheader()
        for row in rows:
            writer.writerow({k: (("nan" if not math.isfinite(v) else f"{v:.6g}")
                                 if isinstance(v, float) else v) for k, v in row.items()})
    (out / "laws.md").write_text(markdown(rows))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("sets", nargs="*", metavar="[LABEL=]DIR",
                    help="analysed sweep directories (default: the 16 sets in results/)")
    ap.add_argument("--out", type=Path, default=HERE / "results",
                    help="where laws.csv and laws.md go (default: results/)")
    ap.add_argument("--boot", type=int, default=2000, help="replica resamplings (default 2000)")
    ap.add_argument("--rerun", action="store_true",
                    help="the 16 saved sets of the 200 tau_d thermal runs instead (default "
                         "--out: results/rerun_200/)")
    args = ap.parse_args(argv)
    if args.boot < 10:
        _fail(f"--boot {args.boot}: give at least 10 resamplings")
    if args.rerun and args.sets:
        _fail("--rerun reads the saved sets: give no DIR with it")
    saved = RERUN_SETS if args.rerun else SETS
    if args.rerun and args.out == HERE / "results":
        args.out = HERE / "results" / "rerun_200"
    items = [(label, HERE / "results" / d) for label, d in saved] if not args.sets else [
        (s.rpartition("=")[0] or Path(s).name, Path(s.rpartition("=")[2])) for s in args.sets]
    rows = [row for label, knots in read_sets(items)
            for row in fit_set(label, knots, draws=args.boot)]
    write(rows, args.out)
    print(f"wrote laws.csv ({len(rows)} rows) and laws.md in {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
