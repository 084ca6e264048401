"""Table and figure of the knot-sedimentation example: V / V(unknot) against the ACN.

Usage::

    python examples/knot_sedimentation/make_figure.py [LABEL=]DIR [[LABEL=]DIR ...] [--out DIR]

Each ``DIR`` is a sweep directory analysed with ``knotmm analyze DIR`` (or a copy of its
``replicas.json`` and ``summary.csv``) whose points differ in ``knot.name`` (points that also
differ in other swept keys form one set per combination) and which holds the unknot ``0_1``.
Per set and knot type it reads from ``replicas.json`` the mean and
standard error over the replicas of the sedimentation speed ``V``, the average crossing
number (ACN) of the sedimenting shape, ``Rg``, ``Rg_perp``, the asphericity and the torus
fraction; ``V / V0`` carries both standard errors (the unknot's own point: 1, with V0's
relative error as its bar); per replica, whether its knot type changed and its final type:
from ``knot_checks.csv`` (the runs' own checks, :func:`write_knot_checks`) where the
directory has one, else from ``summary.csv``. It writes ``OUT/table.csv``,
``OUT/fits.csv``, ``OUT/tables.md`` (the README's tables: sets by knot types),
``OUT/v_over_v0_vs_acn.png`` (one panel per set) and
``OUT/v_over_v0_vs_crossing_number.png`` (all sets on one axis) (default OUT: ``results``
beside this script): the straight-line fits of ``V / V0`` against
the ACN and against the minimal crossing number, over all knot types and over the knotted
ones only (unweighted least squares, parameter errors from the scatter).

Units: lengths in d, speeds in d / tau_d; ACN, ratios and fractions are dimensionless.
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

#: The knot types of the study in table order, with their minimal crossing numbers.
KNOTS = {"0_1": 0, "3_1": 3, "4_1": 4, "5_1": 5, "5_2": 5, "6_1": 6, "7_1": 7}
#: Per-knot quantities taken from replicas.json (analysis.json keys).
QUANTITIES = (
    "sedimentation_velocity",
    "average_crossing_number",
    "radius_of_gyration",
    "radius_of_gyration_perp",
    "asphericity",
    "torus_fraction",
    "torus_fraction_window",
)
COLUMNS = (
    "set", "knot", "crossing_number", "replicas", "V", "V_se", "V_over_V0", "V_over_V0_se",
    "ACN", "ACN_se", "Rg", "Rg_se", "Rg_perp", "Rg_perp_se", "asphericity", "asphericity_se",
    "torus_fraction", "torus_fraction_window", "knot_changed_replicas", "knot_kept_replicas",
    "knot_types_end",
)


def _fail(message: str) -> None:
    print(f"make_figure.py: error: {message}", file=sys.stderr)
    raise SystemExit(2)


def knot_of(point: str) -> str:
    """The ``knot.name`` of a point name such as ``knot.name=3_1`` (no replica part)."""
    match = re.search(r"knot\.name=([^,]+)", point)
    if match is None:
        _fail(f"point {point!r} has no knot.name: the sweep must vary knot.name")
    return match.group(1)


def rest_of(point: str) -> str:
    """The other swept values of a point name (``knot.name`` and ``replica`` left out)."""
    return ",".join(part for part in point.split(",")
                    if not part.startswith(("knot.name=", "replica=")))


def ratio(v, v_se, v0, v0_se):
    """``r = V / V0`` and its standard error, the relative errors added in quadrature.

    Parameters
    ----------
    v, v_se, v0, v0_se : float
        Mean speed and standard error of a knot and of the unknot, d / tau_d.

    Returns
    -------
    (float, float)
        ``V / V0`` and ``|V / V0| sqrt((v_se / v)^2 + (v0_se / v0)^2)`` (dimensionless).
    """
    r = v / v0
    return r, abs(r) * math.hypot(v_se / v, v0_se / v0)


def linear_fit(x, y, y_se=None):
    """Straight line ``y = a + b x`` by least squares, with its quality.

    Parameters
    ----------
    x, y : array_like, shape (n,)
    y_se : array_like, shape (n,), optional
        Standard errors of ``y``: weights ``1 / y_se`` (``numpy.polyfit``); the parameter
        errors are then the unscaled covariance. Without them, unweighted, and the
        covariance is scaled by the residuals (errors NaN for 3 points or fewer).

    Returns
    -------
    dict
        ``slope``, ``slope_se``, ``intercept``, ``intercept_se``, ``r2`` (of the unweighted
        residuals about the fitted line), ``n``.
    """
    x, y = np.asarray(x, float), np.asarray(y, float)
    if len(x) < 2:
        return {"slope": math.nan, "slope_se": math.nan, "intercept": math.nan,
                "intercept_se": math.nan, "r2": math.nan, "n": int(len(x))}
    if y_se is not None:
        w = 1.0 / np.maximum(np.asarray(y_se, float), 1e-12)
        coef, cov = np.polyfit(x, y, 1, w=w, cov="unscaled")
    elif len(x) > 3:
        coef, cov = np.polyfit(x, y, 1, cov=True)
    else:  # too few points to scale the covariance by the residuals
        coef, cov = np.polyfit(x, y, 1), np.full((2, 2), math.nan)
    resid = y - np.polyval(coef, x)
    r2 = 1.0 - float(resid @ resid) / float(((y - y.mean()) ** 2).sum())
    return {"slope": float(coef[0]), "slope_se": float(math.sqrt(cov[0, 0])),
            "intercept": float(coef[1]), "intercept_se": float(math.sqrt(cov[1, 1])),
            "r2": r2, "n": int(len(x))}


CHECK_COLUMNS = ("point", "knot_type_start", "knot_type_final", "knot_type_checks",
                 "knot_type_changes")


def write_knot_checks(sweep: Path, out: Path) -> Path:
    """``out/knot_checks.csv``: each replica's run-time knot-type record, from its run.toml.

    A run identifies its knot every ``run.topology_check_interval`` (``[knotmm]
    knot_type_start``, ``knot_type`` after the last check, ``knot_type_checks``,
    ``knot_type_changes``); the columns are those, the changes as ``time:from>to`` joined
    by ``;``. A frame topoly cannot name (``unknown``) is no change.
    """
    from knotmm.io.rundir import RUN_FILE, read_facts

    out.mkdir(parents=True, exist_ok=True)
    path = out / "knot_checks.csv"
    with path.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(CHECK_COLUMNS)
        for run_toml in sorted(sweep.glob(f"*/{RUN_FILE}")):
            facts = read_facts(run_toml.parent)
            changes = ";".join(f"{c['time']:g}:{c['from']}>{c['to']}"
                               for c in facts.get("knot_type_changes", []))
            writer.writerow([run_toml.parent.name, facts.get("knot_type_start", ""),
                             facts.get("knot_type", ""), facts.get("knot_type_checks", ""),
                             changes])
    return path


def knot_changes(directory: Path) -> dict[tuple[str, str], tuple[int, int, str]]:
    """Per (other swept values, knot): replicas whose knot type changed, those whose final
    type is the start's (mirror images count as the same), and the final types.

    From ``knot_checks.csv`` (:func:`write_knot_checks`: the runs' own checks, the type
    after the last one), else from ``summary.csv`` (the sweep's analysis of sampled frames:
    a change anywhere, and the type at the end of that analysis's window).
    """
    out: dict[tuple[str, str], tuple[int, int, set]] = {}
    checks, summary = directory / "knot_checks.csv", directory / "summary.csv"
    source = checks if checks.is_file() else summary
    if not source.is_file():
        return {}
    with source.open(newline="") as fh:
        for row in csv.DictReader(fh):
            key = (rest_of(row["point"]), knot_of(row["point"]))
            if source is checks:
                changed, end = bool(row["knot_type_changes"]), row["knot_type_final"]
            else:
                changed = bool(row.get("knot_type_changed_at")) or (
                    row.get("knot_type_start", "") != row.get("knot_type_end", ""))
                end = row.get("knot_type_end")
            n, kept, ends = out.get(key, (0, 0, set()))
            ends.add(end or "?")
            kept += int((end or "").lstrip("+-") == key[1])
            out[key] = (n + int(changed), kept, ends)
    return {k: (n, kept, ";".join(sorted(e))) for k, (n, kept, e) in out.items()}


def read_set(label: str, directory: Path) -> list[dict]:
    """The table rows of a sweep directory (or a copy of its two files).

    Points that differ in other swept keys than ``knot.name`` (the full design's N, Pe,
    repulsion) form separate sets, labelled ``LABEL REST``; each needs its unknot.
    """
    path = directory / "replicas.json"
    if not path.is_file():
        _fail(f"{path} not found: run `knotmm analyze {directory}` first")
    points = json.loads(path.read_text())["points"]
    groups: dict[str, dict] = {}
    for name, p in points.items():
        groups.setdefault(rest_of(name), {})[knot_of(name)] = p["statistics"]
    changes = knot_changes(directory)
    rows = []
    for rest, stats in groups.items():
        name = f"{label} {rest}".strip()
        if "0_1" not in stats:
            _fail(f"{directory}: no unknot point (knot.name=0_1) for {rest or 'the sweep'}: "
                  "it is the reference V0")
        rows += _rows(name, stats, {k: v for (r, k), v in changes.items() if r == rest})
    return rows


def _rows(label: str, stats: dict, changes: dict) -> list[dict]:
    def get(knot, key):
        s = stats[knot].get(key) or {}
        return s.get("mean", math.nan), s.get("std_error") or math.nan, s.get("n", 0)

    v0, v0_se, _ = get("0_1", "sedimentation_velocity")
    rows = []
    for knot in sorted(stats, key=lambda k: (KNOTS.get(k, 99), k)):
        v, v_se, n = get(knot, "sedimentation_velocity")
        r, r_se = ratio(v, v_se, v0, v0_se)
        if knot == "0_1":  # the reference: 1 exactly; its bar is V0's relative error
            r, r_se = 1.0, v0_se / v0
        row = {"set": label, "knot": knot, "crossing_number": KNOTS.get(knot, ""),
               "replicas": n, "V": v, "V_se": v_se, "V_over_V0": r, "V_over_V0_se": r_se}
        for key, col in (("average_crossing_number", "ACN"), ("radius_of_gyration", "Rg"),
                         ("radius_of_gyration_perp", "Rg_perp"), ("asphericity", "asphericity")):
            row[col], row[col + "_se"], _ = get(knot, key)
        row["torus_fraction"] = get(knot, "torus_fraction")[0]
        row["torus_fraction_window"] = get(knot, "torus_fraction_window")[0]
        (row["knot_changed_replicas"], row["knot_kept_replicas"],
         row["knot_types_end"]) = changes.get(knot, ("", "", ""))
        rows.append(row)
    return rows


def _pm(value, error, digits):
    if not math.isfinite(value):
        return "not measured"
    if not math.isfinite(error):
        return f"{value:.{digits}f}"
    return f"{value:.{digits}f} +- {error:.{digits}f}"


def markdown(rows: list[dict], fits: list[dict]) -> str:
    """The README's tables: one row per set, one column per knot type (Markdown)."""
    labels = list(dict.fromkeys(r["set"] for r in rows))
    knots = sorted({r["knot"] for r in rows}, key=lambda k: (KNOTS.get(k, 99), k))
    cell = {(r["set"], r["knot"]): r for r in rows}
    head = "| set | " + " | ".join(knots) + " |\n|---|" + "---|" * len(knots) + "\n"

    def table(title, fmt):
        lines = [f"{title}\n\n", head]
        for label in labels:
            items = [fmt(cell[(label, k)]) if (label, k) in cell else "" for k in knots]
            lines.append(f"| {label} | " + " | ".join(items) + " |\n")
        return "".join(lines) + "\n"

    out = table("V / V0 (mean +- s.e.; the unknot's entry: V0 in d/tau_d)",
                lambda r: _pm(r["V"], r["V_se"], 2) if r["knot"] == "0_1"
                else _pm(r["V_over_V0"], r["V_over_V0_se"], 2))
    out += table("ACN of the sedimenting shape (window mean over replicas +- s.e.)",
                 lambda r: _pm(r["ACN"], r["ACN_se"], 1))
    out += table("Rg / Rg_perp (d)",
                 lambda r: f"{r['Rg']:.2f} / {r['Rg_perp']:.2f}")
    out += table("Torus fraction: in the window / over the run",
                 lambda r: f"{r['torus_fraction_window']:.2f} / {r['torus_fraction']:.2f}")
    out += table("Replicas whose knot type changed, of those run (the runs' own checks"
                 " where knot_checks.csv is there), and how many end as the knot they started as",
                 lambda r: f"{r['knot_changed_replicas']} of {r['replicas']}"
                 + ("" if r["knot_kept_replicas"] == r["replicas"]
                    else f", {r['knot_kept_replicas']} end as {r['knot']}"))
    by = {(f["set"], f["x"], f["points"]): f for f in fits}
    lines = ["Straight-line fits of V / V0 (slope +- s.e., R^2)\n\n",
             "| set | against ACN, all 7 | against ACN, 6 knots | against crossing number, "
             "6 knots |\n|---|---|---|---|\n"]
    for label in labels:
        items = []
        for key in (("ACN", "all"), ("ACN", "knots"), ("crossing_number", "knots")):
            f = by[(label, *key)]
            items.append(f"{f['slope']:.4f} +- {f['slope_se']:.4f}, {f['r2']:.2f}")
        lines.append(f"| {label} | " + " | ".join(items) + " |\n")
    return out + "".join(lines)


def _parse(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("sets", nargs="+", metavar="[LABEL=]DIR",
                    help="analysed sweep directory (or copy of replicas.json + summary.csv)")
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "results",
                    help="where table.csv and v_over_v0_vs_acn.png go (default: results/)")
    return ap.parse_args(argv)


def set_fits(rows: list[dict]) -> tuple[dict, list[dict]]:
    """Per set, the fits of ``V / V0`` against the ACN and the crossing number (all 7 knots),
    and the table of every fit (ACN and crossing number, all 7 and the 6 knotted types)."""
    per_set, table = {}, []
    for label in dict.fromkeys(r["set"] for r in rows):
        sub = [r for r in rows if r["set"] == label]
        x = np.array([r["ACN"] for r in sub])
        y = np.array([r["V_over_V0"] for r in sub])
        c = np.array([r["crossing_number"] for r in sub], float)
        per_set[label] = {"ACN": linear_fit(x, y), "crossing_number": linear_fit(c, y)}
        knotted = c > 0
        for xname, xs in (("ACN", x), ("crossing_number", c)):
            for which, mask in (("all", np.ones_like(knotted)), ("knots", knotted)):
                table.append({"set": label, "x": xname, "points": which}
                             | linear_fit(xs[mask], y[mask]))
    return per_set, table


#: Offsets (points) tried for a knot's label around its marker, nearest first, upper right
#: first: ``(dx, dy)``; the text is aligned away from the marker.
LABEL_OFFSETS = tuple((r * dx, r * dy) for r in (5, 9, 14, 20)
                      for dx, dy in ((1, 1), (1, -1), (-1, 1), (-1, -1), (1, 0), (-1, 0),
                                     (0, 1), (0, -1)))


def place_labels(ax, xs, ys, texts, color, fontsize: float = 9.0) -> list:
    """Name each marker ``(xs[i], ys[i])`` with ``texts[i]`` where no other label and no
    marker is: the first offset of :data:`LABEL_OFFSETS` whose box lies inside the axes and
    clear of the labels placed before it and of every marker (a 10-point square). A label
    with no free place goes to the least crowded one, with a line to its marker.

    Call after the figure's layout is final (positions are measured in pixels).

    Returns
    -------
    list of matplotlib Text (annotations)
    """
    fig = ax.figure
    renderer = fig.canvas.get_renderer()
    frame = ax.get_window_extent(renderer)
    pts = ax.transData.transform(np.column_stack([xs, ys]))
    marker = 5.0 * fig.dpi / 72.0  # half a marker box, in pixels
    gap = 2.0 * fig.dpi / 72.0  # between two labels, in pixels
    from matplotlib.transforms import Bbox

    markers = [Bbox.from_extents(px - marker, py - marker, px + marker, py + marker)
               for px, py in pts]
    placed, out = [], []
    for i in np.argsort(xs, kind="stable"):
        best, best_cost = None, math.inf
        for dx, dy in LABEL_OFFSETS:
            ha = "left" if dx > 0 else "right" if dx < 0 else "center"
            va = "bottom" if dy > 0 else "top" if dy < 0 else "center"
            text = ax.annotate(texts[i], (xs[i], ys[i]), textcoords="offset points",
                               xytext=(dx, dy), ha=ha, va=va, fontsize=fontsize, color=color)
            box = text.get_window_extent(renderer)
            inside = (box.x0 >= frame.x0 and box.x1 <= frame.x1 and box.y0 >= frame.y0
                      and box.y1 <= frame.y1)
            hits = sum(box.padded(gap).overlaps(b) for b in placed) * 10 + sum(
                box.overlaps(m) for j, m in enumerate(markers) if j != i)
            cost = hits + (0 if inside else 100)
            if cost < best_cost:
                if best is not None:
                    best.remove()
                best, best_cost = text, cost
            else:
                text.remove()
            if cost == 0:
                break
        if best_cost > 0:  # crowded: the least bad place, with a line to its marker
            best.remove()
            dx, dy = (24, 24) if ys[i] < np.nanmean(ys) else (24, -24)
            best = ax.annotate(texts[i], (xs[i], ys[i]), textcoords="offset points",
                               xytext=(dx, dy), ha="left", va="center", fontsize=fontsize,
                               color=color, arrowprops={"arrowstyle": "-", "color": color,
                                                        "lw": 0.6})
        placed.append(best.get_window_extent(renderer))
        out.append(best)
    return out


def acn_figure(rows: list[dict], per_set: dict):
    """``V / V0`` against the ACN, one panel per set, each knot named beside its point.

    Parameters
    ----------
    rows : list of dict
        :func:`read_set`'s rows.
    per_set : dict
        :func:`set_fits`' first result.

    Returns
    -------
    matplotlib.figure.Figure
        Drawn on an Agg canvas, 150 dpi.
    """
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    labels = list(dict.fromkeys(r["set"] for r in rows))
    ncols = min(len(labels), 4)
    nrows = math.ceil(len(labels) / ncols)
    fig = Figure(figsize=(4.0 * ncols, 3.6 * nrows + 0.5), dpi=150, layout="constrained")
    FigureCanvasAgg(fig)
    panels = fig.subplots(nrows, ncols, squeeze=False, sharey=True)
    palette = colormaps["tab20"]  # 20 distinct colours: the full design has 16 sets
    drawn = []
    for k, label in enumerate(labels):
        sub = [r for r in rows if r["set"] == label]
        x = np.array([r["ACN"] for r in sub])
        y = np.array([r["V_over_V0"] for r in sub])
        color = palette(k % 20)
        fit = per_set[label]["ACN"]
        ax = panels[k // ncols][k % ncols]
        ax.errorbar(x, y, yerr=[r["V_over_V0_se"] for r in sub],
                    xerr=[r["ACN_se"] for r in sub], fmt="o", ms=5, color=color, capsize=3)
        grid = np.linspace(np.nanmin(x), np.nanmax(x), 2)
        ax.plot(grid, fit["intercept"] + fit["slope"] * grid, "-", color=color, lw=1)
        span = np.nanmax(x) - np.nanmin(x)
        ax.set_xlim(np.nanmin(x) - 0.08 * span - 1, np.nanmax(x) + 0.15 * span + 1)
        ax.set_title(f"{label}\nslope {fit['slope']:.3f}$\\pm${fit['slope_se']:.3f}, "
                     f"$R^2$ = {fit['r2']:.2f}", fontsize=10)
        ax.set_xlabel("ACN of the shape", fontsize=10)
        ax.tick_params(labelsize=9)
        drawn.append((ax, x, y, [r["knot"] for r in sub], color))
    for k in range(len(labels), nrows * ncols):
        panels[k // ncols][k % ncols].set_visible(False)
    for row in panels:
        row[0].set_ylabel("V / V(unknot)", fontsize=10)
    lo = min(r["V_over_V0"] - r["V_over_V0_se"] for r in rows)
    hi = max(r["V_over_V0"] + r["V_over_V0_se"] for r in rows)
    panels[0][0].set_ylim(lo - 0.1 * (hi - lo), hi + 0.12 * (hi - lo))
    fig.suptitle("Sedimentation speed of knotted flexible rings against the ACN "
                 "(mean $\\pm$ s.e. over replicas)", fontsize=12)
    fig.canvas.draw()  # the layout first: labels are placed in pixels, then it is frozen
    fig.set_layout_engine("none")
    for ax, x, y, texts, color in drawn:  # the set's colour darkened: pale ones stay legible
        place_labels(ax, x, y, texts, tuple(0.55 * np.asarray(color[:3])))
    return fig


def crossing_figure(rows: list[dict], per_set: dict):
    """``V / V0`` against the minimal crossing number, all sets on one axis (sets side by
    side), the legend beside the axes. Returns an Agg-canvas Figure (150 dpi)."""
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    labels = list(dict.fromkeys(r["set"] for r in rows))
    fig = Figure(figsize=(12.5, 6.0), dpi=150, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    palette = colormaps["tab20"]
    for k, label in enumerate(labels):
        sub = [r for r in rows if r["set"] == label]
        y = np.array([r["V_over_V0"] for r in sub])
        c = np.array([r["crossing_number"] for r in sub], float)
        fit = per_set[label]["crossing_number"]
        color = palette(k % 20)
        shift = 0.5 * (k - (len(labels) - 1) / 2) / max(len(labels), 1)
        ax.errorbar(c + shift, y, yerr=[r["V_over_V0_se"] for r in sub], fmt="o",
                    color=color, capsize=2, ms=4,
                    label=f"{label}: slope {fit['slope']:.3f}$\\pm${fit['slope_se']:.3f}, "
                          f"$R^2$ = {fit['r2']:.2f}")
        grid = np.array([0.0, max(KNOTS.values())])
        ax.plot(grid, fit["intercept"] + fit["slope"] * grid, "-", color=color, lw=0.8)
    ax.set_xlabel("minimal crossing number of the knot type", fontsize=10)
    ax.set_ylabel("V / V(unknot)", fontsize=10)
    ax.set_xticks(sorted(set(KNOTS.values())))
    ax.tick_params(labelsize=9)
    ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize=8.5, frameon=False,
              borderaxespad=0.0)
    ax.set_title("Sedimentation speed against the knot type (mean $\\pm$ s.e. over "
                 "replicas; lines: fits over all 7)", fontsize=11)
    return fig


def main(argv=None) -> int:
    args = _parse(argv)
    sets = []
    for item in args.sets:
        label, _, path = item.rpartition("=") if "=" in item else ("", "", item)
        directory = Path(path)
        if not directory.is_dir():
            _fail(f"{item}: no such directory; give a sweep directory analysed by knotmm")
        sets.append((label or directory.name, directory))
    rows = [row for label, d in sets for row in read_set(label, d)]
    args.out.mkdir(parents=True, exist_ok=True)
    with (args.out / "table.csv").open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=COLUMNS)
        writer.writeheader()
        for row in rows:
            writer.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v)
                             for k, v in row.items()})
    per_set, fits = set_fits(rows)
    for label, f in per_set.items():
        fit, fit_c = f["ACN"], f["crossing_number"]
        v0 = next(r for r in rows if r["set"] == label and r["knot"] == "0_1")
        print(f"{label}: V/V0 = {fit['intercept']:.4f} + ({fit['slope']:.4f} +- "
              f"{fit['slope_se']:.4f}) ACN, R^2 = {fit['r2']:.3f} (n = {fit['n']}); "
              f"against the crossing number: slope {fit_c['slope']:.4f} +- "
              f"{fit_c['slope_se']:.4f}, R^2 = {fit_c['r2']:.3f}; V0 = {v0['V']:.3f} "
              f"+- {v0['V_se']:.3f} d/tau_d")
    acn_figure(rows, per_set).savefig(args.out / "v_over_v0_vs_acn.png")
    crossing_figure(rows, per_set).savefig(args.out / "v_over_v0_vs_crossing_number.png")
    with (args.out / "fits.csv").open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(fits[0]))
        writer.writeheader()
        for f in fits:
            writer.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in f.items()})
            print(f"  fit {f['set']}, V/V0 vs {f['x']}, {f['points']}: slope {f['slope']:.4f} "
                  f"+- {f['slope_se']:.4f}, intercept {f['intercept']:.3f} +- "
                  f"{f['intercept_se']:.3f}, R^2 = {f['r2']:.3f}, n = {f['n']}")
    (args.out / "tables.md").write_text(markdown(rows, fits))
    print(f"wrote table.csv, fits.csv, tables.md, v_over_v0_vs_acn.png and "
          f"v_over_v0_vs_crossing_number.png in {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
