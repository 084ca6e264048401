"""Leading Floquet exponent of the swirling T(2,3) orbit against the number of beads.

For each N: a deterministic run (`knotmm run`, 120 tau_d), then `knotmm orbit` on it (orbit
from the middle of its steady window, 10 leading multipliers). Writes `exponent_vs_N.csv`
and `exponent_vs_N.png` into the output folder and prints a table with the wall time of
each orbit computation.

    python examples/orbit_stability/exponent_vs_N.py --out runs/orbit_stability
    python examples/orbit_stability/exponent_vs_N.py --beads 40 60 --out runs/quick
"""

from __future__ import annotations

import argparse
import cmath
import csv
import time
from pathlib import Path

from knotmm.plotstyle import label, plain_ticks

COLUMNS = ("beads", "period", "run_tau_swirl", "rotation_per_period", "tau_swirl_over_tau_sed",
           "tau_rot_over_tau_sed", "residual", "leading_modulus", "leading_angle",
           "leading_exponent", "unstable_multipliers", "second_modulus", "leading_mode",
           "flow_integrations", "orbit_wall_s", "run_wall_s")


def one(n: int, out: Path, duration: float) -> dict:
    from knotmm.config import RunConfig
    from knotmm.orbit import orbit_of_run
    from knotmm.workflow import run

    run_dir = out / f"N{n}"
    cfg = RunConfig.from_dict({"knot": {"beads": n}, "run": {"duration": duration},
                               "output": {"frame_interval": 0.25}})
    t0 = time.perf_counter()
    run(cfg, run_dir, overwrite=True, progress=False)
    t1 = time.perf_counter()
    s = orbit_of_run(run_dir, modes=10).summary
    t2 = time.perf_counter()
    mu = [complex(*m) for m in s["floquet_multipliers"] or []]
    return {
        "beads": n, "period": s["period"], "run_tau_swirl": s["run_tau_swirl"],
        "rotation_per_period": s["rotation_per_period"],
        "tau_swirl_over_tau_sed": s["tau_swirl_over_tau_sed"],
        "tau_rot_over_tau_sed": s["tau_rot_over_tau_sed"], "residual": s["residual"],
        "leading_modulus": abs(mu[0]) if mu else None,
        "leading_angle": abs(cmath.phase(mu[0])) if mu else None,
        "leading_exponent": s["leading_exponent"],
        "unstable_multipliers": s["unstable_multipliers"],
        "second_modulus": next((abs(m) for m in mu if abs(abs(m) - abs(mu[0])) > 1e-9), None),
        "leading_mode": s["leading_mode"], "flow_integrations": s["flow_integrations"],
        "orbit_wall_s": round(t2 - t1, 1), "run_wall_s": round(t1 - t0, 1),
    }


def plot_exponents(rows: list[dict], path: Path) -> Path:
    """``exponent_vs_N.png``: the leading exponent and the two largest multiplier moduli
    against N (rows as in ``exponent_vs_N.csv``)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 3.5), layout="constrained", dpi=110)
    FigureCanvasAgg(fig)
    a, b = fig.subplots(1, 2)
    n = [float(r["beads"]) for r in rows]
    a.plot(n, [float(r["leading_exponent"]) for r in rows], "o-")
    a.axhline(0, color="k", lw=0.8)
    a.set_ylabel(label("exponent"))
    b.plot(n, [float(r["leading_modulus"]) for r in rows], "o-", label=r"$|\mu_1|$")
    b.plot(n, [float(r["second_modulus"]) for r in rows], "s--", label=r"next $|\mu|$")
    b.axhline(1, color="k", lw=0.8)
    b.set_ylabel(r"Floquet multiplier $|\mu|$")
    b.legend(frameon=False)
    for ax in (a, b):
        ax.set_xlabel(label("knot.beads"))
        plain_ticks(ax)
    fig.savefig(path)
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--beads", type=int, nargs="+", default=[40, 60, 90, 120])
    parser.add_argument("--duration", type=float, default=120.0)
    parser.add_argument("--out", default="runs/orbit_stability")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for n in args.beads:
        rows.append(one(n, out, args.duration))
        r = rows[-1]
        print(f"N = {n}: T = {r['period']:.5g} (run {r['run_tau_swirl']:.5g}), |mu1| = "
              f"{r['leading_modulus']:.4f}, exponent {r['leading_exponent']:+.4g}/tau_d, "
              f"{r['leading_mode']}, orbit {r['orbit_wall_s']} s "
              f"({r['flow_integrations']} integrations)", flush=True)
    with open(out / "exponent_vs_N.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=COLUMNS)
        writer.writeheader()
        writer.writerows(rows)
    plot_exponents(rows, out / "exponent_vs_N.png")
    print(f"wrote exponent_vs_N.csv, exponent_vs_N.png in {out}")


if __name__ == "__main__":
    main()
