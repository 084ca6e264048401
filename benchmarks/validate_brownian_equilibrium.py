"""Validation: the Brownian integrators' equilibrium against Boltzmann and a Monte Carlo.

Not a timing (wall times are reported beside the numbers): whether the integrators sample
the Boltzmann distribution of knotmm's energy. Three sub-commands:

``boltzmann``
    A T(2,3) chain (default N = 90, the study's parameters, gravity 0, Pe 2) runs through the
    Python engine for ``--duration`` tau_d after ``--burn`` tau_d for each ``NAME:DT``
    (default: ito_heun at 0.002 and 0.01 tau_d, leimkuhler_matthews at 0.005, 0.01 and 0.02),
    and the script prints ``bond``: the bond-length variance over the Boltzmann value of the
    stretching energy, ``p(l) ~ l^2 exp(-B (l - l0)^2 / (2 kT))`` (bending depends on angles
    only; the ring closure and steric contacts change it by an estimated < 0.1 % at N = 90),
    with the standard error from ``--blocks`` time blocks; ``com``: the mean square
    displacement of the centre of mass over ``--lag`` tau_d over ``6 kT D_K lag``, ``D_K =
    tr(sum_ij mu_ij) / (3 N^2)`` the Kirkwood short-time mobility averaged over the run's
    frames (the long-time value is a little lower for a flexible ring); ``com_lm``: the
    value the Leimkuhler-Matthews scheme should show instead, ``1 - dt / (2 lag)`` (each frame
    holds half a kick, :class:`knotmm.dynamics.brownian.LeimkuhlerMatthews`); ``s/tau_d``:
    wall seconds per simulated tau_d, the median of ``--repeats`` short runs.
``run``
    For T(2,3), N = 60, gravity 0, Python engine, at each Peclet number: ``AdaptiveItoHeun``
    at several tolerances and the fixed-step ``ItoHeun`` at dt = 0.001 and 0.002 run for
    ``--duration`` tau_d (the first ``--burn-in`` discarded); one JSON line per (Pe, scheme)
    is appended to ``--out`` (the per-sample series included, with each sample's knot type,
    so that the report can be redone).
``report``
    The bond-length standard deviation, the mean cosine of the angle between successive
    bonds and the mean ``|r_{i+2} - r_i|`` of ``run``'s files against a Metropolis Monte
    Carlo of the same energy (``tests/dynamics/mc_reference.py``), with block-jackknife
    errors on both sides; accepted and rejected steps and wall time per tau_d. The Monte
    Carlo keeps one knot type; a row is printed for each knot type a run spent at least
    ``--min-span`` tau_d in (bonds can pass through each other: at Pe <~ 1 the trefoil unties
    within about 10 tau_d, at Pe = 2 within tens to hundreds, and the knot type shifts <cos>
    by about 1 %). Each Pe is judged in the type of ``JUDGED_KNOT`` (unknot for Pe <= 1,
    trefoil for Pe >= 2); other rows are shown in parentheses. Unknot samples start
    ``SETTLE`` tau_d after the first one (the chain opens up slowly after untying).

Usage (single-threaded, ``OMP_NUM_THREADS=1``, for comparable wall times)::

    python benchmarks/validate_brownian_equilibrium.py boltzmann            # 5-10 min
    python benchmarks/validate_brownian_equilibrium.py boltzmann --runs leimkuhler_matthews:0.01
    python benchmarks/validate_brownian_equilibrium.py run --out eq.jsonl --pe 1 2
    python benchmarks/validate_brownian_equilibrium.py report eq.jsonl --mc-cache mc.json
    python benchmarks/validate_brownian_equilibrium.py boltzmann --quick    # a smoke run
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent / "tests"), str(HERE.parent / "tests" / "dynamics")]

import harness  # noqa: E402
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


BOLTZMANN_RUNS = ("ito_heun:0.002", "ito_heun:0.01", "leimkuhler_matthews:0.005",
                  "leimkuhler_matthews:0.01", "leimkuhler_matthews:0.02")


# -- boltzmann ------------------------------------------------------------------------------
def boltzmann_bond_variance(stiffness, rest, kt):
    """Variance of ``l`` under ``l^2 exp(-B (l - l0)^2 / (2 kT))``, by quadrature, in d^2."""
    sd = math.sqrt(kt / stiffness)
    grid = np.linspace(max(0.0, rest - 12 * sd), rest + 12 * sd, 200_001)
    w = grid**2 * np.exp(-stiffness * (grid - rest) ** 2 / (2 * kt))
    mean = np.sum(w * grid) / np.sum(w)
    return float(np.sum(w * (grid - mean) ** 2) / np.sum(w))


def chain_config(name, dt, args):
    from knotmm.config import RunConfig

    return RunConfig.from_dict({
        "knot": {"beads": args.beads},
        "model": {"gravity": 0.0},
        "run": {"peclet": args.peclet, "integrator": name, "timestep": dt, "seed": args.seed,
                "platform": args.platform, "engine": "python", "noise": "cholesky"},
    })


def measure(name, dt, args) -> dict:
    """Bond-length variance over Boltzmann's and centre-of-mass diffusion over Kirkwood's."""
    from knotmm.dynamics.mobility import rpy_matrix
    from knotmm.engine.simulation import Simulation
    from knotmm.errors import SimulationFault

    cfg = chain_config(name, dt, args)
    sim = Simulation.from_config(cfg)
    kt = 1.0 / args.peclet
    every = max(1, round(args.frame / dt))
    try:
        sim.run(args.burn)
        n_frames = int(round(args.duration / (every * dt)))
        bonds = np.empty((n_frames, args.beads))
        com = np.empty((n_frames, 3))
        dk = []
        for k in range(n_frames):
            sim.step(every)
            bonds[k] = sim.bond_lengths()
            com[k] = sim.positions.mean(axis=0)
            if k % max(1, n_frames // 200) == 0:
                m = rpy_matrix(sim.positions)
                dk.append(sum(m[c::3, c::3].sum() for c in range(3)) / (3 * args.beads**2))
    except SimulationFault as exc:
        return {"name": name, "dt": dt, "fault": str(exc)[:90], "time": sim.time}
    ref = boltzmann_bond_variance(cfg["model.bond_stiffness"], cfg["model.bond_length"], kt)
    lag = max(1, round(args.lag / (every * dt)))
    d_k = float(np.mean(dk))
    bond_blocks, com_blocks = [], []
    for block in np.array_split(np.arange(n_frames), args.blocks):
        bond_blocks.append(bonds[block].var() / ref)
        c = com[block]
        disp = c[lag:] - c[:-lag]
        com_blocks.append(np.mean(np.sum(disp**2, axis=1)) / (6 * kt * d_k * lag * every * dt))

    def se(v):
        return float(np.std(v, ddof=1) / math.sqrt(len(v)))

    return {"name": name, "dt": dt, "bond": float(np.mean(bond_blocks)), "bond_se": se(bond_blocks),
            "com": float(np.mean(com_blocks)), "com_se": se(com_blocks),
            "com_lm": 1 - dt / (2 * lag * every * dt), "d_k": d_k,
            "bond_sd": float(bonds.std()), "ref_sd": math.sqrt(ref)}


def cost(name, dt, args) -> float:
    """Median wall seconds per simulated tau_d of ``--repeats`` runs of ``--cost-duration``."""
    from knotmm.engine.simulation import Simulation

    times = []
    for _ in range(args.repeats):
        sim = Simulation.from_config(chain_config(name, dt, args))
        t0 = time.perf_counter()
        sim.run(args.cost_duration)
        times.append((time.perf_counter() - t0) / args.cost_duration)
    return statistics.median(times)


def cmd_boltzmann(args):
    info = harness.header()
    print(f"T(2,3), N = {args.beads}, Pe = {args.peclet:g}, gravity 0, {args.platform}, "
          f"{args.duration:g} tau_d after {args.burn:g}")
    print(f"{'integrator':<22}{'dt':>7}{'bond':>16}{'com':>16}{'com_lm':>8}{'s/tau_d':>9}")
    results = {}
    for spec in args.runs:
        name, dt = spec.split(":")
        r = results[spec] = measure(name, float(dt), args)
        if "fault" in r:
            print(f"{name:<22}{float(dt):>7g}  unstable at t = {r['time']:.3g}: {r['fault']}")
            continue
        r["s_per_tau_d"] = c = cost(name, float(dt), args)
        print(f"{name:<22}{r['dt']:>7g}{r['bond']:>9.4f} +-{r['bond_se']:.4f}"
              f"{r['com']:>9.3f} +-{r['com_se']:.3f}{r['com_lm']:>8.3f}{c:>9.3f}", flush=True)
    harness.save("validate_brownian_equilibrium boltzmann", args, results, machine_before=info)


# -- run, report ----------------------------------------------------------------------------
def make_integrator(scheme: str, peclet: float, seed: int):
    from knotmm.dynamics.adaptive_brownian import AdaptiveItoHeun
    from knotmm.dynamics.brownian import ItoHeun

    kind, value = scheme.split(":")
    if kind == "adaptive":
        return AdaptiveItoHeun(0.002, peclet=peclet, seed=seed, noise="cholesky",
                               tolerance=float(value), max_timestep=0.05)  # as measured
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
    bz = sub.add_parser("boltzmann", help="bond variance and COM diffusion on the study's chain")
    harness.add_options(bz, repeats=3)
    bz.add_argument("--runs", nargs="+", default=list(BOLTZMANN_RUNS), help="NAME:DT ...")
    bz.add_argument("--beads", type=int, default=90)
    bz.add_argument("--peclet", type=float, default=2.0)
    bz.add_argument("--seed", type=int, default=1)
    bz.add_argument("--platform", default="CPU")
    bz.add_argument("--burn", type=float, default=5.0, help="tau_d before measuring")
    bz.add_argument("--duration", type=float, default=100.0, help="tau_d measured")
    bz.add_argument("--frame", type=float, default=0.02, help="tau_d between frames")
    bz.add_argument("--lag", type=float, default=0.5, help="COM lag, tau_d")
    bz.add_argument("--blocks", type=int, default=10)
    bz.add_argument("--cost-duration", type=float, default=2.0,
                    help="tau_d of each cost run (--repeats of them, median)")
    run = sub.add_parser("run", help="Brownian runs against which report compares")
    run.add_argument("--out", required=True, help="JSON lines file, appended to")
    run.add_argument("--pe", type=float, nargs="+", default=list(PECLETS))
    run.add_argument("--schemes", nargs="+", default=list(SCHEMES))
    run.add_argument("--duration", type=float, default=200.0)
    run.add_argument("--burn-in", type=float, default=5.0)
    run.add_argument("--sample-every", type=float, default=0.05)
    run.add_argument("--seed", type=int, default=1)
    run.add_argument("--identify-every", type=float, default=2.0)
    run.add_argument("--quick", action="store_true", help="one short run (a smoke run)")
    rep = sub.add_parser("report", help="run's files against the Monte Carlo")
    rep.add_argument("files", nargs="+")
    rep.add_argument("--mc-sweeps", type=int, default=400_000)
    rep.add_argument("--mc-seed", type=int, default=1)
    rep.add_argument("--mc-cache", help="JSON file that keeps the Monte Carlo references")
    rep.add_argument("--min-span", type=float, default=10.0,
                     help="least tau_d of a knot type in a run for a row")
    rep.add_argument("--quick", action="store_true",
                     help="a short Monte Carlo and every row (a smoke run)")
    args = ap.parse_args(argv)
    if args.cmd == "boltzmann":
        if args.quick:
            args.runs, args.beads, args.burn, args.duration = args.runs[3:4], 40, 0.1, 1.0
            args.repeats, args.cost_duration, args.blocks, args.lag = 1, 0.2, 2, 0.1
        cmd_boltzmann(args)
    elif args.cmd == "run":
        if args.quick:
            args.pe, args.schemes, args.duration, args.burn_in = [10.0], [SCHEMES[2]], 3.0, 0.2
            args.identify_every = None
        cmd_run(args)
    else:
        if args.quick:
            args.mc_sweeps, args.min_span = 2000, 1.0
        cmd_report(args)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
