"""Aggregate the Peclet-persistence sweep: per point, mean +- standard error over replicas.

    python examples/peclet_persistence/aggregate.py sweeps/peclet_persistence \
        [--out examples/peclet_persistence/results] [--no-dcd]

Reads every run directory of the sweep directory(ies): ``run.toml`` (the point's keys, the
status, the knot-type checks made during the run) and ``analysis.json`` (written by the
sweep's analysis of each point). A point is ``(knot.beads, model.segment_repulsion,
run.peclet)``; its replicas are the run directories that differ only in ``replica=K``.
Runs that are not finished, or whose analysis failed, are listed as missing.

Measures per run (model units: d, tau_d)

``torus_fraction``
    Fraction of all frames that meet the flat-torus criterion of
    :mod:`knotmm.analysis.body` (analysis key ``torus_fraction``).
``lifetime``
    Length of the first stretch of flat-torus frames from t = 0 (analysis key
    ``body_frame.first_torus_lifetime``). A run that is a flat torus in every frame
    (``torus_fraction == 1``) is *censored*: its lifetime is only known to exceed the run's
    duration, and it is never averaged as a number.
``lifetime_smooth`` (needs the DCD; ``--no-dcd`` skips it)
    First time at which fewer than half of the frames of a sliding 5 tau_d window meet the
    criterion (single noisy frames do not end it); censored in the same way.
``flips_per_100``
    Flips of the torus per 100 tau_d: crossings of 90 degrees by the angle between the
    body-frame normal (followed continuously) and +z (``body_frame.flips_per_100_tau``).
    The normal is followed in every frame, toroidal or not; ``turn_over_45`` counts the
    runs whose normal turned by more than 45 degrees between two frames (their flip count is
    unreliable, README of knotmm). ``flips_winding_per_100`` is the cross-check of the
    ``tilt`` key: flips counted over the frames with planar winding >= 1 only.
``tau_ratio``
    Body-frame swirl period ``tau_swirl_body`` over the deterministic one: the mean over the
    Pe = inf replicas of the same N and the same segment repulsion. Null when no swirl is
    detected (analysis key ``swirl_detected``).
``knot_changes``
    Changes of knot type seen by the checks made during the run (``run.toml``
    ``knot_type_changes``, one check every ``run.topology_check_interval``); also whether
    the analysis' bisection found any change (``knot_type_changed_at``).

Per point: mean, standard error (std / sqrt(n), ddof = 1) and n over the replicas with a
value. Writes into ``--out``: ``runs.csv`` (one row per run), ``points.csv`` (one row per
point), ``table.md`` and ``shape.md`` (the README's tables; ``shape.md`` gives the
medians over each run of the criterion's ratios, averaged over replicas) and one PNG per
measure (each measure against Pe, one line per N, panels for segment repulsion on and off;
Pe = inf drawn at the right end).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import re
from pathlib import Path

import numpy as np

from knotmm.config import read_toml

#: Sliding window of the smoothed lifetime, tau_d, and the toroidal share that ends it.
SMOOTH_WINDOW = 5.0
SMOOTH_LEVEL = 0.5
#: The claim's tests per point (README): torus present, swirl persists.
TORUS_PRESENT = 0.5  # mean torus fraction at least this
SWIRL_DETECTED = 0.75  # share of replicas with a detected swirl at least this
SWIRL_PERIOD_TOL = 0.2  # |tau_ratio - 1| at most this
PE_INF_X = 1000.0  # where Pe = inf is drawn on the log axis
#: Per-run columns from :func:`criterion_parts` that are also averaged per point.
PARTS = ("part_flat", "part_round", "part_hole", "part_winding", "flatness_median",
         "roundness_median", "winding_median")

_REPLICA = re.compile(r"(^|,)replica=\d+(?=,|$)")


def _mean_se(values) -> tuple[float, float, int]:
    """Mean, standard error (ddof = 1; nan for n < 2) and count of the finite values."""
    v = np.asarray([x for x in values if x is not None and math.isfinite(x)], dtype=float)
    if v.size == 0:
        return math.nan, math.nan, 0
    se = float(v.std(ddof=1) / math.sqrt(v.size)) if v.size > 1 else math.nan
    return float(v.mean()), se, int(v.size)


def first_stretch(times: np.ndarray, toroidal: np.ndarray) -> tuple[float, bool]:
    """Lifetime of the first toroidal stretch of a smoothed criterion, and whether censored.

    Parameters
    ----------
    times : ndarray, shape (n_frames,)
        In tau_d, evenly spaced.
    toroidal : ndarray of bool, shape (n_frames,)
        The flat-torus criterion per frame.

    Returns
    -------
    (float, bool)
        The time (tau_d, from t = 0) of the first frame whose centred window of
        :data:`SMOOTH_WINDOW` holds fewer than :data:`SMOOTH_LEVEL` toroidal frames, and
        False; or the run's duration and True when no such frame exists.
    """
    dt = float(times[1] - times[0])
    half = max(1, int(round(0.5 * SMOOTH_WINDOW / dt)))
    x = toroidal.astype(float)
    c = np.r_[0.0, np.cumsum(x)]
    idx = np.arange(len(x))
    lo, hi = np.maximum(idx - half, 0), np.minimum(idx + half + 1, len(x))
    share = (c[hi] - c[lo]) / (hi - lo)
    off = np.flatnonzero(share < SMOOTH_LEVEL)
    if off.size == 0:
        return float(times[-1] - times[0]), True
    return float(times[off[0]] - times[0]), False


def read_run(directory: Path, use_dcd: bool) -> dict:
    """One run's keys, status and measures (module docstring); ``status`` says if usable."""
    meta = read_toml(directory / "run.toml")
    facts = meta.get("knotmm", {})
    pe = float(meta["run"].get("peclet", math.inf))
    row = {
        "run": directory.name,
        "point": _REPLICA.sub("", directory.name).strip(","),
        "beads": int(meta["knot"]["beads"]),
        "repulsion": bool(meta.get("model", {}).get("segment_repulsion", False)),
        "peclet": pe,
        "seed": int(meta["run"].get("seed", 0)),
        "duration": float(meta["run"]["duration"]),
        "status": facts.get("status", "unknown"),
        "wall_time_s": facts.get("wall_time_s", math.nan),
    }
    if row["status"] != "finished":
        return row
    result = directory / "analysis.json"
    if result.is_file():
        a = json.loads(result.read_text())
        row["analysis"] = "analysis.json"
    else:
        a = whole_run_analysis(directory)
        row["analysis"] = "whole run from the DCD (no analysis.json)"
    body = a.get("body_frame") or {}
    changes = facts.get("knot_type_changes", [])
    frac = a.get("torus_fraction")
    row.update(
        torus_fraction=frac,
        # a censored lifetime is null in analysis.json; its lower bound stands in for the
        # restricted mean (analyses made before the key existed: torus fraction 1)
        lifetime=(body.get("first_torus_lifetime_lower_bound")
                  if body.get("first_torus_lifetime") is None
                  else body.get("first_torus_lifetime")),
        lifetime_censored=bool(body.get("first_torus_lifetime_censored",
                                        frac is not None and frac >= 1.0)),
        flips_per_100=body.get("flips_per_100_tau"),
        flips=(body.get("flips") or {}).get("count"),
        max_turn_deg=body.get("max_turn_deg"),
        flips_winding_per_100=100.0 * (a.get("tilt") or {}).get("flips", {}).get("count", 0)
        / row["duration"],
        inclination_median_deg=body.get("inclination_median_deg"),
        swirl_detected=bool(a.get("swirl_detected")),
        tau_swirl_body=a.get("tau_swirl_body") if a.get("swirl_detected") else None,
        knot_changes=len(changes),
        knot_checks=facts.get("knot_type_checks"),
        knot_changed_at=a.get("knot_type_changed_at"),
        time_reached=facts.get("time_reached"),
    )
    if use_dcd:
        from knotmm import load_run
        from knotmm.analysis.body import body_frame

        data = load_run(directory)
        frame = body_frame(data.positions, data.times)
        life, censored = first_stretch(frame.times, frame.toroidal)
        row.update(lifetime_smooth=life, lifetime_smooth_censored=censored)
        # the same criterion as analysis.json: an independent reading of its value
        row["torus_fraction_dcd"] = float(frame.toroidal.mean())
        row.update(criterion_parts(frame))
    return row


def criterion_parts(frame) -> dict:
    """Fraction of frames meeting each part of the flat-torus criterion, and its median values.

    Parameters
    ----------
    frame : knotmm.analysis.body.BodyFrame

    Returns
    -------
    dict
        ``part_flat`` (g1/g2 <= max_flatness), ``part_round`` (g2/g3 >= min_roundness),
        ``part_hole`` (hole fraction <= max_hole_fraction), ``part_winding`` (|winding| >=
        min_winding), and the medians ``flatness_median`` (g1/g2), ``roundness_median``
        (g2/g3), ``winding_median`` (|winding|) over the run.
    """
    from knotmm.analysis.body import TORUS_CRITERION as c

    g = frame.moments
    flat, round_ = g[:, 0] / g[:, 1], g[:, 1] / g[:, 2]
    wind = np.abs(frame.winding)
    return {
        "part_flat": float(np.mean(flat <= c["max_flatness"])),
        "part_round": float(np.mean(round_ >= c["min_roundness"])),
        "part_hole": float(np.mean(frame.hole_fraction <= c["max_hole_fraction"])),
        "part_winding": float(np.mean(wind >= c["min_winding"])),
        "flatness_median": float(np.median(flat)),
        "roundness_median": float(np.median(round_)),
        "winding_median": float(np.median(wind)),
    }


def whole_run_analysis(directory: Path) -> dict:
    """The whole-run keys of ``analysis.json`` computed from the DCD, without a window.

    For a run whose analysis failed: ``knotmm analyze`` looks for its window only before the
    first change of knot type and stops when fewer than 16 frames precede it (a strand
    passage within 7.5 tau_d at frame_interval 0.5), so such a run has no
    ``analysis.json`` at all. The torus fraction, the first toroidal stretch and the flips
    are whole-run quantities (:func:`knotmm.analysis.body.inclination_summary` without a
    window, the same functions the analysis calls); the swirl period is not measurable
    before the knot type changed, so ``swirl_detected`` is False here.
    """
    from knotmm import load_run
    from knotmm.analysis.body import body_frame, inclination_summary
    from knotmm.analysis.tilt import tilt_analysis

    data = load_run(directory)
    summary = inclination_summary(body_frame(data.positions, data.times))
    return {
        "torus_fraction": summary["torus_fraction"],
        "body_frame": summary,
        "tilt": tilt_analysis(data.positions, data.times).to_dict(),
        "swirl_detected": False,
        "tau_swirl_body": None,
        "knot_type_changed_at": None,
    }


def _expected(sweep_dir: Path) -> list[str]:
    """Run-directory names the sweep file plans (empty if it cannot be read)."""
    try:
        from knotmm.sweep import load_sweep_file

        return [p.name for p in load_sweep_file(sweep_dir / "sweep.toml").points]
    except Exception:  # noqa: BLE001 - only used to list what is missing
        return []


def _lifetime(rows, key: str) -> dict:
    """Censoring-aware summary: mean +- s.e. over ended runs, or a lower bound."""
    ended = [r[key] for r in rows if not r[f"{key}_censored"]]
    n_cens = len(rows) - len(ended)
    dur = min((r["duration"] for r in rows), default=math.nan)
    mean, se, n = _mean_se(ended)
    # restricted mean: censored runs counted at the duration (a lower bound of the mean)
    bound = float(np.mean([r[key] for r in rows])) if rows else math.nan
    if not rows:
        text = ""
    elif n_cens == len(rows):
        text = f"> {dur:g}"
    elif n_cens:
        text = f"{_fmt(mean, se, 1)} ({n_cens}/{len(rows)} > {dur:g})"
    else:
        text = _fmt(mean, se, 1)
    return {"mean": mean, "se": se, "n_ended": n, "n_censored": n_cens, "bound": bound,
            "text": text}


def _fmt(mean: float, se: float, decimals: int = 2) -> str:
    """``mean ± se`` with a fixed number of decimals (``n/a`` without a value)."""
    if not math.isfinite(mean):
        return "n/a"
    if not math.isfinite(se):
        return f"{mean:.{decimals}f}"
    return f"{mean:.{decimals}f} ± {se:.{decimals}f}"


def aggregate(rows: list[dict]) -> list[dict]:
    """One summary per point (module docstring), sorted by repulsion, N, Pe."""
    ok = [r for r in rows if r["status"] == "finished"]
    det: dict[tuple, tuple] = {}
    for key in {(r["beads"], r["repulsion"]) for r in ok}:
        taus = [r["tau_swirl_body"] for r in ok
                if (r["beads"], r["repulsion"]) == key and math.isinf(r["peclet"])]
        det[key] = _mean_se(taus)
    points = []
    for key in sorted({(r["repulsion"], r["beads"], r["peclet"]) for r in rows}):
        rep, n_beads, pe = key
        group = [r for r in ok if (r["repulsion"], r["beads"], r["peclet"]) == key]
        planned = [r for r in rows if (r["repulsion"], r["beads"], r["peclet"]) == key]
        p = {"repulsion": rep, "beads": n_beads, "peclet": pe, "replicas": len(group),
             "missing": len(planned) - len(group)}
        for name in ("torus_fraction", "flips_per_100", "flips_winding_per_100",
                     "inclination_median_deg", "knot_changes", *PARTS):
            if not group or name in group[0]:
                p[name], p[f"{name}_se"], _ = _mean_se([r[name] for r in group])
        p["knot_changed_runs"] = sum(
            1 for r in group if r["knot_changes"] or r["knot_changed_at"] is not None)
        p["swirl_detected"] = sum(r["swirl_detected"] for r in group)
        p["turn_over_45"] = sum(1 for r in group if (r["max_turn_deg"] or 0.0) > 45.0)
        d_mean, d_se, _ = det.get((n_beads, rep), (math.nan, math.nan, 0))
        p["tau_swirl_det"], p["tau_swirl_det_se"] = d_mean, d_se
        ratios = [r["tau_swirl_body"] / d_mean for r in group
                  if r["tau_swirl_body"] is not None and d_mean > 0]
        m, s, n = _mean_se(ratios)
        if n and math.isfinite(d_se) and not math.isinf(pe):
            s = math.hypot(s if math.isfinite(s) else 0.0, m * d_se / d_mean)
        p["tau_ratio"], p["tau_ratio_se"], p["tau_ratio_n"] = m, s, n
        for life in ("lifetime", "lifetime_smooth"):
            if group and life in group[0]:
                for k, v in _lifetime(group, life).items():
                    p[f"{life}_{k}"] = v
        p["torus_present"] = bool(group) and p["torus_fraction"] >= TORUS_PRESENT
        p["swirl_persists"] = (
            bool(group)
            and p["swirl_detected"] >= SWIRL_DETECTED * len(group)
            and math.isfinite(m) and abs(m - 1.0) <= SWIRL_PERIOD_TOL
        )
        p["claim_holds"] = p["torus_present"] and p["swirl_persists"]
        points.append(p)
    return points


def _pe_text(pe: float) -> str:
    return "inf" if math.isinf(pe) else f"{pe:g}"


def write_tables(rows: list[dict], points: list[dict], out: Path) -> None:
    """``runs.csv``, ``points.csv`` and ``table.md`` in ``out``."""
    for name, table in (("runs.csv", rows), ("points.csv", points)):
        fields: list[str] = []
        for r in table:
            fields += [k for k in r if k not in fields]
        with open(out / name, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=fields)
            w.writeheader()
            for r in table:
                w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v)
                            for k, v in r.items()})
    lines = [
        "| rep. | N | Pe | n | torus fraction | 1st torus lifetime | (smoothed) "
        "| flips / 100 tau_d | tau_swirl_body / det. (detected) | knot changes (runs) "
        "| torus and swirl persist |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for p in points:
        if not p["replicas"]:
            lines.append(f"| {'on' if p['repulsion'] else 'off'} | {p['beads']} | "
                         f"{_pe_text(p['peclet'])} | 0 | not run |  |  |  |  |  |  |")
            continue
        ratio = (_fmt(p["tau_ratio"], p["tau_ratio_se"])
                 + f" ({p['swirl_detected']}/{p['replicas']})")
        lines.append(
            f"| {'on' if p['repulsion'] else 'off'} | {p['beads']} | {_pe_text(p['peclet'])} "
            f"| {p['replicas']} | {_fmt(p['torus_fraction'], p['torus_fraction_se'])} "
            f"| {p.get('lifetime_text', '')} | {p.get('lifetime_smooth_text', '')} "
            f"| {_fmt(p['flips_per_100'], p['flips_per_100_se'], 1)} | {ratio} "
            f"| {_fmt(p['knot_changes'], p['knot_changes_se'], 1)} "
            f"({p['knot_changed_runs']}/{p['replicas']}) "
            f"| {'yes' if p['claim_holds'] else 'no'} |"
        )
    (out / "table.md").write_text("\n".join(lines) + "\n")
    if not any("part_flat" in p for p in points):
        return
    lines = [
        "| rep. | N | Pe | g1/g2 (flat <= 0.25) | g2/g3 (round >= 0.6) | planar winding "
        "| median inclination (deg) | flips / 100 tau_d, winding >= 1 "
        "| runs with a turn > 45 deg |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for p in points:
        if not p["replicas"]:
            continue
        lines.append(
            f"| {'on' if p['repulsion'] else 'off'} | {p['beads']} | {_pe_text(p['peclet'])} "
            f"| {_fmt(p['flatness_median'], p['flatness_median_se'])} "
            f"| {_fmt(p['roundness_median'], p['roundness_median_se'])} "
            f"| {_fmt(p['winding_median'], p['winding_median_se'])} "
            f"| {_fmt(p['inclination_median_deg'], p['inclination_median_deg_se'], 0)} "
            f"| {_fmt(p['flips_winding_per_100'], p['flips_winding_per_100_se'], 1)} "
            f"| {p['turn_over_45']}/{p['replicas']} |"
        )
    (out / "shape.md").write_text("\n".join(lines) + "\n")


def _x(pe: float) -> float:
    return PE_INF_X if math.isinf(pe) else pe


def plot_measure(points: list[dict], key: str, label: str, path: Path, lifetime=False,
                 hline=None) -> None:
    """One measure against Pe: panels repulsion on / off, a line per N, s.e. error bars."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(9, 3.6), sharey=True)
    beads = sorted({p["beads"] for p in points})
    colors = dict(zip(beads, ("C0", "C1", "C2", "C3", "C4"), strict=False))
    for ax, rep in zip(axes, (True, False), strict=True):
        for i, n_beads in enumerate(beads):
            sel = [p for p in points if p["beads"] == n_beads and p["repulsion"] == rep
                   and p["replicas"]]
            if not sel:
                continue
            shift = 1.0 + 0.06 * (i - 1)  # spread the lines a little along log Pe
            xs = np.array([_x(p["peclet"]) * shift for p in sel])
            mean = np.array([p[key if not lifetime else f"{key}_mean"] for p in sel], float)
            se = np.array([p[f"{key}_se"] for p in sel], float)
            finite = np.array([math.isfinite(p["peclet"]) for p in sel], dtype=bool)
            style = {"color": colors[n_beads], "capsize": 3}
            if lifetime:
                full = np.array([p[f"{key}_n_censored"] == 0 for p in sel], dtype=bool)
                bound = np.array([p[f"{key}_bound"] for p in sel], float)
                shown = np.where(full, mean, bound)
                ax.plot(xs[finite], shown[finite], "-", color=colors[n_beads], lw=1, alpha=0.6)
                ax.errorbar(xs[full], mean[full], yerr=np.nan_to_num(se[full]), fmt="o",
                            label=f"N = {n_beads}", **style)
                ax.plot(xs[~full], bound[~full], "^", mfc="none", color=colors[n_beads])
            else:  # Pe = inf is drawn apart, not joined to the finite Pe
                ax.errorbar(xs[finite], mean[finite], yerr=np.nan_to_num(se[finite]),
                            fmt="o-", label=f"N = {n_beads}", **style)
                ax.errorbar(xs[~finite], mean[~finite], yerr=np.nan_to_num(se[~finite]),
                            fmt="s", **style)
        if lifetime:
            ax.set_yscale("log")
        if hline is not None:
            ax.axhline(hline, color="0.6", lw=0.8, ls="--")
        ax.set_xscale("log")
        ticks = [2, 5, 10, 20, 50, 100, 200, PE_INF_X]
        ax.set_xticks(ticks, [f"{t:g}" for t in ticks[:-1]] + ["inf"])
        ax.minorticks_off()
        ax.set_xlabel("Pe = d F0 / kT")
        ax.set_title(f"segment repulsion {'on' if rep else 'off'}")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel(label)
    axes[0].legend(fontsize=8)
    if lifetime:
        fig.text(0.5, 0.01, "open triangles: some replicas still a flat torus at the end, "
                 "counted at the run's duration (a lower bound of the mean)",
                 ha="center", va="bottom", fontsize=8)
    fig.tight_layout(rect=(0, 0.05 if lifetime else 0, 1, 1))
    fig.savefig(path, dpi=90)
    plt.close(fig)


def check_replicas(sweep: Path, points: list[dict]) -> str | None:
    """Compare the torus fractions with ``replicas.json`` of ``knotmm analyze SWEEP_DIR``.

    Returns a one-line report, or None when the sweep directory has no ``replicas.json``.
    """
    path = sweep / "replicas.json"
    if not path.is_file():
        return None
    stats = json.loads(path.read_text())["points"]
    diffs = []
    for p in points:
        pe = "inf" if math.isinf(p["peclet"]) else str(p["peclet"])  # as the sweep names it
        name = (f"run.peclet={pe},knot.beads={p['beads']},"
                f"model.segment_repulsion={str(p['repulsion']).lower()}")
        theirs = stats.get(name, {}).get("statistics", {}).get("torus_fraction", {})
        if theirs.get("mean") is not None and p["replicas"]:
            diffs.append(abs(theirs["mean"] - p["torus_fraction"]))
    if not diffs:
        return f"{path}: no point in common"
    return (f"{path}: torus_fraction means of {len(diffs)} points agree within "
            f"{max(diffs):.3g}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("sweeps", nargs="+", type=Path, help="sweep directories")
    ap.add_argument("--out", type=Path, default=Path(__file__).parent / "results")
    ap.add_argument("--no-dcd", action="store_true",
                    help="skip the smoothed lifetime (reads every DCD)")
    args = ap.parse_args(argv)
    rows = []
    for sweep in args.sweeps:
        found = {p.name: p for p in sweep.iterdir() if (p / "run.toml").is_file()}
        for name in _expected(sweep):
            if name not in found:
                keys = dict(kv.split("=", 1) for kv in name.split(","))
                rows.append({"run": name, "point": _REPLICA.sub("", name).strip(","),
                             "beads": int(keys.get("knot.beads", 0)),
                             "repulsion": keys.get("model.segment_repulsion") == "true",
                             "peclet": float(keys.get("run.peclet", "inf")),
                             "status": "pending"})
        rows += [read_run(p, not args.no_dcd) for p in found.values()]
    args.out.mkdir(parents=True, exist_ok=True)
    points = aggregate(rows)
    rows.sort(key=lambda r: (not r["repulsion"], r["beads"], r["peclet"], r["run"]))
    write_tables(rows, points, args.out)
    plots = [("torus_fraction", "torus fraction (whole run)", {}),
             ("lifetime", "first flat-torus stretch (tau_d)", {"lifetime": True}),
             ("flips_per_100", "flips per 100 tau_d", {}),
             ("tau_ratio", "tau_swirl_body / deterministic", {"hline": 1.0}),
             ("knot_changes", "knot-type changes per run", {}),
             ("inclination_median_deg", "median inclination (deg)", {})]
    if not args.no_dcd:
        plots.insert(2, ("lifetime_smooth", "first torus stretch, 5 tau_d smoothing (tau_d)",
                         {"lifetime": True}))
    for key, label, kw in plots:
        plot_measure(points, key, label, args.out / f"{key}.png", **kw)
    for sweep in args.sweeps:
        report = check_replicas(sweep, points)
        if report:
            print(report)
    done = sum(r["status"] == "finished" for r in rows)
    print(f"{done} of {len(rows)} runs finished and analysed; wrote {args.out}")
    missing = [r for r in rows if r["status"] != "finished"]
    for r in missing[:12]:
        print(f"  missing: {r['run']} ({r['status']})")
    if len(missing) > 12:
        print(f"  ... and {len(missing) - 12} more (runs.csv, column status)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
