"""Equilibrium accuracy and cost of the Brownian integrators against a Monte Carlo (issue 20).

For T(2,3), N = 60, gravity 0, Python engine, at each Peclet number: ``AdaptiveItoHeun`` at
several tolerances and the fixed-step ``ItoHeun`` at dt = 0.001 and 0.002 run for
``--duration`` tau_d (the first ``--burn-in`` discarded); the bond-length standard deviation,
the mean cosine of the angle between successive bonds and the mean ``|r_{i+2} - r_i|`` are
compared with a Metropolis Monte Carlo of the same energy (``tests/dynamics/mc_reference.py``),
with block-jackknife errors on both sides. Also reported: accepted and rejected steps per
tau_d and wall time per tau_d.

Usage::

    python benchmarks/bench_brownian_equilibrium.py run --out results.jsonl [--pe 1 2] ...
    python benchmarks/bench_brownian_equilibrium.py report results.jsonl [more.jsonl ...]

``run`` appends one JSON line per (Pe, scheme) run (the per-sample series included, so that
the report can be redone, with each sample's knot type); ``report`` computes the Monte Carlo
references, kept in a knot type, and prints a row for each knot type a run spent at least
``--min-span`` tau_d in (bonds can pass through each other: at Pe <~ 1 the trefoil unties
within about 10 tau_d, at Pe = 2 within tens to hundreds, and the knot type shifts <cos> by
about 1 %). Each Pe is judged in the type of ``JUDGED_KNOT`` (unknot for Pe <= 1, trefoil for
Pe >= 2); other rows are shown in parentheses. Unknot samples start ``SETTLE`` tau_d after the
first one (the chain opens up slowly after untying).
Run it single-threaded (``OMP_NUM_THREADS=1``) for comparable wall times.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "tests"), str(HERE.parent / "tests" / "dynamics")]

import mc_reference as mc  # noqa: E402
from test_brownian_equilibrium import (  # noqa: E402
    JUDGED_KNOT,
    TARGETS,
    compare,
    sample_brownian,
    select_samples,
)

PECLETS = (0.5, 1.0, 2.0, 10.0)
SCHEMES = ("adaptive:0.005", "adaptive:0.01", "adaptive:0.02", "adaptive:0.05",
           "ito:0.001", "ito:0.002")


def make_integrator(scheme: str, peclet: float, seed: int):
    from knotmm.dynamics.adaptive_brownian import AdaptiveItoHeun
    from knotmm.dynamics.brownian import ItoHeun

    kind, value = scheme.split(":")
    if kind == "adaptive":
        return AdaptiveItoHeun(0.002, peclet=peclet, seed=seed, noise="cholesky",
                               tolerance=float(value))
    return ItoHeun(float(value), peclet=peclet, seed=seed, noise="cholesky")


def cmd_run(args):
    for pe in args.pe:
        for scheme in args.schemes:
            integ = make_integrator(scheme, pe, args.seed)
            record = {"pe": pe, "scheme": scheme, "seed": args.seed}
            try:
                dyn = sample_brownian(integ, args.duration, args.burn_in, args.sample_every,
                                     identify_every=args.identify_every)
            except AssertionError as exc:
                record.update(fail=str(exc), accepted=integ.n_accepted,
                              rejected=integ.n_rejected)
            else:
                record.update(accepted=dyn["accepted"], rejected=dyn["rejected"],
                              wall=dyn["wall"], duration=dyn["duration"],
                              burn_in=dyn["burn_in"], sample_every=dyn["sample_every"],
                              series=dyn["series"].tolist(),
                              labels=[str(v) for v in dyn["labels"]])
            with open(args.out, "a") as fh:
                fh.write(json.dumps(record) + "\n")
            print(pe, scheme, {k: v for k, v in record.items() if k not in ("series", "labels")},
                  flush=True)


def cmd_report(args):
    records = []
    for path in args.files:
        with open(path) as fh:
            records += [json.loads(line) for line in fh if line.strip()]
    rows = []
    for r in records:
        if "fail" in r:
            continue
        for knot in ("3_1", "0_1"):
            span = len(select_samples(r, knot)) * r.get("sample_every", 0.05)
            if span >= args.min_span:
                rows.append((r, knot, span))
    refs = {}
    cache = {}
    if args.mc_cache and Path(args.mc_cache).exists():
        cache = json.loads(Path(args.mc_cache).read_text())
    for pe, knot in sorted({(r["pe"], knot) for r, knot, _ in rows}):
        t0 = time.perf_counter()
        key = f"{pe:g}|{knot}|{args.mc_sweeps}|{args.mc_seed}"
        if key not in cache:
            cache[key] = mc.reference(1.0 / pe, knot=knot, sweeps=args.mc_sweeps,
                                      seed=args.mc_seed)
            if args.mc_cache:
                Path(args.mc_cache).write_text(json.dumps(cache))
        refs[pe, knot] = ref = cache[key]
        print(f"MC Pe = {pe:g} (kT = {1 / pe:g}), knot {knot}: "
              + ", ".join(f"{k} = {ref[k][0]:.5f} +- {ref[k][1]:.5f}" for k in mc.DERIVED)
              + f"; acceptance {ref['acceptance']:.3f}, {time.perf_counter() - t0:.0f} s",
              flush=True)
    print()
    print("| Pe | scheme | knot (tau_d compared) | bond sd dev (%) | <cos> dev (%) "
          "| <r13> dev (%) | accepted/tau_d | rejected/tau_d | wall s/tau_d | meets 2/1/1 % |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in records:
        if "fail" in r:
            print(f"| {r['pe']:g} | {r['scheme']} | | failed: {r['fail']} | | | | | | no |")
    for r, knot, span in sorted(rows, key=lambda row: (row[0]["pe"], row[0]["scheme"], row[1])):
        cmp = compare(r, refs[r["pe"], knot], knot=knot)
        cells = [f"{100 * c[4]:+.2f} +- {100 * c[5]:.2f}" for c in cmp.values()]
        ok = all(abs(c[4]) < TARGETS[k] for k, c in cmp.items())
        judged = JUDGED_KNOT.get(r["pe"]) == knot
        total = r["duration"]
        verdict = ("yes" if ok else "NO") if judged else f"({'yes' if ok else 'no'})"
        print(f"| {r['pe']:g} | {r['scheme']} (seed {r['seed']}) | {knot} ({span:.0f}) | "
              + " | ".join(cells)
              + f" | {r['accepted'] / total:.0f} | {r['rejected'] / total:.1f}"
              f" | {r['wall'] / total:.2f} | {verdict} |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    run = sub.add_parser("run")
    run.add_argument("--out", required=True)
    run.add_argument("--pe", type=float, nargs="+", default=list(PECLETS))
    run.add_argument("--schemes", nargs="+", default=list(SCHEMES))
    run.add_argument("--duration", type=float, default=200.0)
    run.add_argument("--burn-in", type=float, default=5.0)
    run.add_argument("--sample-every", type=float, default=0.05)
    run.add_argument("--seed", type=int, default=1)
    run.add_argument("--identify-every", type=float, default=2.0)
    rep = sub.add_parser("report")
    rep.add_argument("files", nargs="+")
    rep.add_argument("--mc-sweeps", type=int, default=400_000)
    rep.add_argument("--mc-seed", type=int, default=1)
    rep.add_argument("--mc-cache", help="JSON file that keeps the Monte Carlo references")
    rep.add_argument("--min-span", type=float, default=10.0,
                     help="least tau_d of a knot type in a run for a row")
    args = ap.parse_args(argv)
    if args.cmd == "run":
        cmd_run(args)
    else:
        cmd_report(args)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
