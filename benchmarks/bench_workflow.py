"""What whole commands cost: a run against numba, start-up, replicas, sweeps, reporting, orbit.

Six measurements, one sub-command each (T(2,3) at the defaults unless said otherwise; cases
interleaved, medians, ratios as medians of the per-repetition ratios; wall time and the
children's CPU time; ``benchmarks/harness.py``):

``run``
    ``knotmm run --duration D`` (a subprocess: start-up, template, reports and files counted)
    for each ``--variant NAME:KEY=VALUE[;KEY=VALUE]`` (``--set`` keys; default: the defaults),
    and with ``--numba`` the numba yardstick ``numba_chain.py`` (fixed-step Heun, dt = 0.02)
    for D tau_d from the same template, as a whole process, with a warm numba cache (compiled
    once before timing) and a cold one (a fresh cache folder each time); with ``--peclet PE
    --numba-brownian SCHEME:DT`` every run at ``run.peclet = PE`` against the Brownian
    yardstick ``numba_brownian.py`` (warm cache) at that Peclet number, scheme and step.
``startup``
    ``knotmm run --duration 0.5`` against ``python -c "import openmm, numba, mdtraj"``.
``replicas``
    One ``knotmm run`` of K replicas (``run.replicas = K``) against K single runs with the
    replicas' seeds one after another; the ratio per repetition and its median.
``sweep``
    ``knotmm sweep`` of ``--points`` values of the bending stiffness with ``seeds = K``: each
    point's replicas stepped together (``run.replica_stepping = "auto"``) against one run per
    replica (``"one_after_another"``), local workers as ``knotmm sweep`` picks them.
``reporting``
    What one output frame of a plugin-engine run costs (N = 90, CPU platform), per call:
    energies (one ``getGroupEnergies`` call against ``setPositions`` and a ``getState`` per
    force group), a DCD frame (``DCDReporter`` against OpenMM's ``DCDFile.writeModel``), an
    observables row, a checkpoint and its parts; with ``--run T`` the time inside
    ``Simulation._report`` per frame in whole ``knotmm run --duration T`` runs in this
    process.
``orbit``
    ``knotmm.orbit.orbit_of_run(run, modes=10)`` on a deterministic run of ``--duration``
    tau_d (made once, not timed): wall and CPU time, flow integrations (one period each) and
    the time per integration, against N.

Run on demand (not part of the tests)::

    python benchmarks/bench_workflow.py run --duration 400 --numba            # target (a)
    python benchmarks/bench_workflow.py run --duration 10 --peclet 2 \\
        --numba-brownian euler_maruyama:0.002                                 # issue 33
    python benchmarks/bench_workflow.py run --duration 500 --variant default: \\
        --variant checks-off:run.topology_check_interval=0 \\
        --variant reference:run.topology_check_interval=0;run.platform=\\"Reference\\"
    python benchmarks/bench_workflow.py startup --repeats 5                   # target (b)
    python benchmarks/bench_workflow.py replicas --replicas 8 --beads 90 --duration 40
    python benchmarks/bench_workflow.py sweep --points 2 --seeds 8 --beads 40 --peclet 2
    python benchmarks/bench_workflow.py reporting --calls 300
    python benchmarks/bench_workflow.py orbit --beads 40 60 90 120
    python benchmarks/bench_workflow.py startup --quick     # any sub-command: a smoke run
"""

from __future__ import annotations

import io
import os
import statistics
import sys
import tempfile
import time
from functools import partial
from pathlib import Path
from types import SimpleNamespace

import harness
import numpy as np

IMPORTS = "import openmm, numba, mdtraj"


def _walls(samples, summary_key="wall") -> dict:
    out = harness.summarize(samples, key=summary_key)
    for name in samples:
        out[name]["cpu"] = statistics.median(s["cpu"] for s in samples[name])
    return out


def _ratio_line(samples, num, den, target=None) -> str:
    rw, rc = harness.ratio(samples, num, den, "wall"), harness.ratio(samples, num, den, "cpu")
    verdict = f"  target <= {target:g}x: {'met' if rw <= target else 'MISSED'}" if target else ""
    return f"{num} / {den}: {rw:.2f}x wall, {rc:.2f}x cpu{verdict}"


# -- run, startup ---------------------------------------------------------------------------
def numba_run(start: Path, duration: float, cache_dir: Path) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_dir))
    cmd = [sys.executable, str(harness.HERE / "numba_chain.py"), "--start", str(start),
           "--duration", f"{duration:g}", "--dt", "0.02"]
    result = harness.timed(cmd, env=env)
    if result["rc"] != 0:
        raise SystemExit(f"numba_chain failed:\n{result['last']}")
    return result


def numba_brownian_run(start: Path, duration: float, scheme: str, peclet: float,
                       cache_dir: Path) -> dict:
    """``numba_brownian.py`` (``SCHEME:DT``) for ``duration`` tau_d at ``peclet``, timed as a
    whole process."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_dir))
    name, _, dt = scheme.partition(":")
    cmd = [sys.executable, str(harness.HERE / "numba_brownian.py"), "--start", str(start),
           "--duration", f"{duration:g}", "--scheme", name, "--peclet", f"{peclet:g}"]
    result = harness.timed(cmd + (["--dt", dt] if dt else []), env=env)
    if result["rc"] != 0:
        raise SystemExit(f"numba_brownian failed:\n{result['last']}")
    return result


def cmd_run(args):
    work = args.work
    if args.numba_brownian and args.peclet is None:
        raise SystemExit("--numba-brownian needs --peclet (the Peclet number of both programs)")
    common = list(args.sets) + ([] if args.peclet is None else [f"run.peclet={args.peclet:g}"])
    variants = harness.parse_variants(args.variant, common)
    jobs = {f"knotmm[{name}]": partial(harness.knotmm_run, work / "run", args.duration, sets)
            for name, sets in variants}
    if args.numba:
        start = work / "start.npy"
        np.save(start, harness.template(90))
        warm = work / "numba_cache_warm"
        numba_run(start, 0.0, warm)  # fills the cache; not timed
        cold = [0]

        def cold_run():
            cold[0] += 1
            return numba_run(start, args.duration, work / f"numba_cache_cold{cold[0]}")

        jobs["numba (warm cache)"] = partial(numba_run, start, args.duration, warm)
        jobs["numba (cold cache)"] = cold_run
    yardstick = f"numba_brownian {args.numba_brownian} (warm cache)"
    if args.numba_brownian:
        start = work / "start.npy"
        np.save(start, harness.template(90))
        warm = work / "numba_brownian_cache"
        numba_brownian_run(start, 0.0, args.numba_brownian, args.peclet, warm)  # not timed
        jobs[yardstick] = partial(numba_brownian_run, start, args.duration,
                                  args.numba_brownian, args.peclet, warm)
    print(f"\nknotmm run --duration {args.duration:g} (T(2,3), N = 90"
          + (f", Pe = {args.peclet:g})" if args.peclet is not None else ")")
          + (" against numba_chain.py (heun 0.02)" if args.numba else "")
          + (f" against numba_brownian.py ({args.numba_brownian})" if args.numba_brownian
             else ""))
    samples = harness.interleave(jobs, args.repeats, log=print)
    summary = _walls(samples)
    for name in samples:
        print(f"  {name}: median {summary[name]['median']:.2f} s wall, "
              f"{summary[name]['cpu']:.2f} s cpu; last: {samples[name][-1]['last']}")
    ratios = {}
    if args.numba:
        for name, _ in variants:
            for ref in ("numba (warm cache)", "numba (cold cache)"):
                line = _ratio_line(samples, f"knotmm[{name}]", ref, 0.8)
                ratios[f"knotmm[{name}] / {ref}"] = harness.ratio(
                    samples, f"knotmm[{name}]", ref, "wall")
                print("  " + line)
    if args.numba_brownian:
        for name, _ in variants:
            ratios[f"knotmm[{name}] / {yardstick}"] = harness.ratio(
                samples, f"knotmm[{name}]", yardstick, "wall")
            print("  " + _ratio_line(samples, f"knotmm[{name}]", yardstick))
    if not (args.numba or args.numba_brownian) and len(variants) > 1:
        first = f"knotmm[{variants[0][0]}]"
        for name, _ in variants[1:]:
            ratios[f"knotmm[{name}] / {first}"] = harness.ratio(samples, f"knotmm[{name}]",
                                                                first, "wall")
            print("  " + _ratio_line(samples, f"knotmm[{name}]", first))
    return summary, samples, {"ratios": ratios, "variants": variants}


def cmd_startup(args):
    work = args.work
    variants = harness.parse_variants(args.variant, args.sets)
    jobs = {f"knotmm[{name}]": partial(harness.knotmm_run, work / "run", 0.5, sets)
            for name, sets in variants}
    jobs["imports"] = partial(harness.timed, [sys.executable, "-c", IMPORTS])
    print(f'\nknotmm run --duration 0.5 against python -c "{IMPORTS}"')
    samples = harness.interleave(jobs, args.repeats, log=print)
    summary = _walls(samples)
    ratios = {}
    for name, _ in variants:
        ratios[name] = harness.ratio(samples, f"knotmm[{name}]", "imports", "wall")
        print("  " + _ratio_line(samples, f"knotmm[{name}]", "imports", 1.5))
    return summary, samples, {"ratios": ratios, "variants": variants}


# -- replicas -------------------------------------------------------------------------------
def cmd_replicas(args):
    from knotmm.replicas import replica_seeds

    work = args.work
    common = ([] if args.peclet is None else [f"run.peclet={args.peclet}"]) + list(args.set)
    extra = ["-q", "--beads", str(args.beads)]
    seeds = replica_seeds(1, args.replicas)

    def singles():
        runs = [harness.knotmm_run(work / f"single_{k}", args.duration,
                                   [*common, f"run.seed={s}"], extra)
                for k, s in enumerate(seeds)]
        return {"wall": sum(r["wall"] for r in runs), "cpu": sum(r["cpu"] for r in runs)}

    def replicated(stepping):
        def go():
            return harness.knotmm_run(work / f"set_{stepping}", args.duration,
                                      [*common, f"run.replicas={args.replicas}",
                                       f"run.replica_stepping={stepping}"], extra)
        return go

    k = args.replicas
    together, apart = f"{k} replicas together", f"{k} replicas one after another"
    samples = harness.interleave({f"{k} single runs": singles,
                                  together: replicated("together"),
                                  apart: replicated("one_after_another")},
                                 args.repeats, log=print)
    summary = _walls(samples)
    ratios = {name: harness.ratio(samples, name, f"{k} single runs", "wall")
              for name in (together, apart)}
    print(f"median: {k} single runs {summary[f'{k} single runs']['median']:.2f} s, "
          f"together {summary[together]['median']:.2f} s (ratio {ratios[together]:.3f}), "
          f"one after another {summary[apart]['median']:.2f} s (ratio {ratios[apart]:.3f}) "
          f"(N = {args.beads}, {args.duration:g} tau_d, Pe = "
          f"{args.peclet if args.peclet is not None else 'inf'})")
    return summary, samples, {"ratio": ratios[together], "ratio_one_after_another": ratios[apart]}


# -- sweep ----------------------------------------------------------------------------------
def cmd_sweep(args):
    work = args.work
    stiffness = ", ".join(f"{3.0 * (i + 1):g}" for i in range(args.points))
    peclet = "" if args.peclet is None else f"peclet = {args.peclet}\n"
    sweep_file = work / "sweep.toml"
    sweep_file.write_text(
        f"[knot]\nbeads = {args.beads}\n[run]\nduration = {args.duration}\n{peclet}"
        f"topology_check_interval = 0.0\n[sweep]\n\"model.bending_stiffness\" = [{stiffness}]\n"
        f"seeds = {args.seeds}\nknot_samples = 0\nplots = false\n")

    def sweep(stepping):
        def go():
            out = work / f"sweep_{stepping}"
            cmd = [*harness.knotmm_command(), "sweep", str(sweep_file), "--out", str(out),
                   "--set", f"run.replica_stepping={stepping}"]
            if out.exists():
                import shutil

                shutil.rmtree(out)
            result = harness.timed(cmd)
            result["last"] = result["last"].replace(str(out), "OUT")
            if result["rc"] != 0:
                raise SystemExit(f"knotmm sweep failed:\n{result['last']}")
            return result
        return go

    together, apart = "replicas of a point together", "one run per replica"
    samples = harness.interleave({together: sweep("auto"), apart: sweep("one_after_another")},
                                 args.repeats, log=print)
    summary = _walls(samples)
    ratio = harness.ratio(samples, together, apart, "wall")
    print(f"median: {args.points} points x {args.seeds} seeds, together "
          f"{summary[together]['median']:.2f} s, one run per replica "
          f"{summary[apart]['median']:.2f} s (ratio {ratio:.3f}) (N = {args.beads}, "
          f"{args.duration:g} tau_d, Pe = {args.peclet if args.peclet is not None else 'inf'})")
    return summary, samples, {"ratio": ratio}


# -- reporting ------------------------------------------------------------------------------
def _median_call(fn, calls: int) -> float:
    """Median seconds of one ``fn()`` over ``calls`` calls."""
    times = []
    for _ in range(calls):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def call_costs(work: Path, calls: int) -> dict:
    import openmm.app
    from openmm import unit

    from knotmm.engine.reporters import DCDReporter, ObservablesReporter
    from knotmm.engine.simulation import Simulation

    sim = Simulation(harness.template(90), platform="CPU", engine="plugin")
    sim.run(5.0)
    out = {"energies (plugin, one call)": _median_call(sim.energies, calls),
           "energies (4 x getState)": _median_call(lambda: sim.energies(sim.positions), calls)}
    dcd = DCDReporter(work / "a.dcd", 0.5, sim.topology)
    frame = SimpleNamespace(positions=sim.positions)
    out["dcd frame (DCDReporter)"] = _median_call(lambda: dcd.report(frame, None), calls)
    dcd.close()
    with open(work / "b.dcd", "wb") as fh:
        openmm_dcd = openmm.app.DCDFile(fh, sim.topology, 0.5)
        out["dcd frame (DCDFile.writeModel)"] = _median_call(
            lambda: openmm_dcd.writeModel(sim.positions * unit.nanometer), calls)
    obs = ObservablesReporter(work / "o.csv", 0.5)
    out["observables row"] = _median_call(lambda: obs.report(sim, None), calls)
    obs.close()
    few = max(calls // 10, 5)
    out["checkpoint (saveCheckpoint)"] = _median_call(
        lambda: sim.saveCheckpoint(work / "c.npz", {"frames": 1}), few)
    out["  Context.createCheckpoint"] = _median_call(sim.context.createCheckpoint, few)
    state = dict(np.load(work / "c.npz"))
    out["  np.savez into memory"] = _median_call(lambda: np.savez(io.BytesIO(), **state), few)
    out["  the rest (file, fsync, rename)"] = (out["checkpoint (saveCheckpoint)"]
                                               - out["  Context.createCheckpoint"]
                                               - out["  np.savez into memory"])
    return out


def whole_runs(work: Path, duration: float, runs: int) -> list[dict]:
    """Whole ``knotmm run`` commands in this process; time inside ``Simulation._report``."""
    from knotmm.cli.main import main
    from knotmm.engine.simulation import Simulation

    spent = [0.0, 0]
    report = Simulation._report

    def timed(self, reporters):
        t = time.perf_counter()
        try:
            return report(self, reporters)
        finally:
            spent[0] += time.perf_counter() - t
            spent[1] += 1

    Simulation._report = timed
    rows = []
    try:
        for _ in range(runs):
            spent[:] = [0.0, 0]
            load = os.getloadavg()[0]
            t = time.perf_counter()
            code = main(["run", "--duration", f"{duration:g}", "--out", str(work / "run"),
                         "--overwrite", "--no-progress", "-q"])
            rows.append({"wall": time.perf_counter() - t, "report": spent[0],
                         "frames": spent[1], "load": load, "code": code})
    finally:
        Simulation._report = report
    return rows


def cmd_reporting(args):
    work = args.work
    costs = call_costs(work, args.calls)
    print(f"per call, median of {args.calls}:")
    for name, seconds in costs.items():
        print(f"  {name:<34} {1e3 * seconds:8.3f} ms")
    summary = {name: {"median": s, "unit": "s per call", "n": args.calls}
               for name, s in costs.items()}
    rows = []
    if args.run > 0:
        rows = whole_runs(work, args.run, args.repeats)
        for r in rows:
            print(f"knotmm run --duration {args.run:g}: wall {r['wall']:.2f} s, reporting "
                  f"{r['report']:.3f} s = {1e3 * r['report'] / max(r['frames'], 1):.3f} ms "
                  f"x {r['frames']} frames (load {r['load']:.2f}, exit {r['code']})")
        per_frame = [r["report"] / max(r["frames"], 1) for r in rows]
        summary["report per frame in a run"] = {"median": statistics.median(per_frame),
                                                "n": len(rows), "unit": "s per frame"}
        print(f"median: wall {statistics.median(r['wall'] for r in rows):.2f} s, "
              f"reporting {1e3 * statistics.median(per_frame):.3f} ms per frame")
    return summary, {"whole runs": rows}, {}


# -- orbit ----------------------------------------------------------------------------------
def cmd_orbit(args):
    from knotmm.config import RunConfig
    from knotmm.orbit import orbit_of_run
    from knotmm.workflow import run

    work = args.work
    print(f"{'N':>4} {'period':>8} {'flows':>6} {'wall s':>8} {'cpu s':>8} {'s/flow':>7} "
          f"{'|mu1|':>7}")
    summary, samples = {}, {}
    for n in args.beads:
        run_dir = work / f"N{n}"
        cfg = RunConfig.from_dict({"knot": {"beads": n}, "run": {"duration": args.duration},
                                   "output": {"frame_interval": 0.25}})
        run(cfg, run_dir, progress=False)
        facts = {}

        def one(n=n, run_dir=run_dir, facts=facts):
            w0, c0 = time.perf_counter(), time.process_time()
            s = orbit_of_run(run_dir, modes=args.modes,
                             out=work / f"o{n}_{len(facts)}").summary
            facts.update(s)
            return {"wall": time.perf_counter() - w0, "cpu": time.process_time() - c0}

        samples[str(n)] = harness.interleave({str(n): one}, args.repeats)[str(n)]
        row = _walls({str(n): samples[str(n)]})[str(n)]
        flows = facts["flow_integrations"]
        row.update(period=facts["period"], flow_integrations=flows,
                   per_integration=row["median"] / flows,
                   floquet_modulus=facts["floquet_moduli"][0])
        summary[str(n)] = row
        print(f"{n:>4} {row['period']:>8.4f} {flows:>6} {row['median']:>8.1f} {row['cpu']:>8.1f} "
              f"{row['per_integration']:>7.3f} {row['floquet_modulus']:>7.4f}", flush=True)
    return summary, samples, {}


# -- command line ---------------------------------------------------------------------------
def main(argv=None):
    import argparse

    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="command", required=True)

    def variants(s):
        s.add_argument("--set", dest="sets", action="append", default=[],
                       metavar="TABLE.KEY=VALUE", help="--set for every knotmm command")
        s.add_argument("--variant", action="append", default=[], metavar="NAME:K=V[;K=V]",
                       help="a named set of --set keys; repeatable; replaces the default")

    s = sub.add_parser("run", help="a whole knotmm run (and the numba program)")
    harness.add_options(s, repeats=3)
    s.add_argument("--duration", type=float, default=400.0, help="tau_d")
    s.add_argument("--numba", action="store_true", help="against numba_chain.py")
    s.add_argument("--peclet", type=float, default=None,
                   help="run.peclet of every knotmm run (and the numba_brownian program's)")
    s.add_argument("--numba-brownian", metavar="SCHEME[:DT]", default=None,
                   help="against numba_brownian.py with this scheme and step (needs --peclet)")
    variants(s)
    s.set_defaults(func=cmd_run)

    s = sub.add_parser("startup", help="knotmm run --duration 0.5 against the imports")
    harness.add_options(s, repeats=5)
    variants(s)
    s.set_defaults(func=cmd_startup)

    s = sub.add_parser("replicas", help="K replicas in one run against K single runs")
    harness.add_options(s, repeats=3)
    s.add_argument("--replicas", type=int, default=8)
    s.add_argument("--beads", type=int, default=90)
    s.add_argument("--duration", type=float, default=40.0)
    s.add_argument("--peclet", type=float, default=None)
    s.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="a run-file key for every run (singles and sets alike), repeatable")
    s.set_defaults(func=cmd_replicas)

    s = sub.add_parser("sweep", help="a sweep's seeds stepped together against one run each")
    harness.add_options(s, repeats=3)
    s.add_argument("--points", type=int, default=2)
    s.add_argument("--seeds", type=int, default=8)
    s.add_argument("--beads", type=int, default=40)
    s.add_argument("--duration", type=float, default=10.0)
    s.add_argument("--peclet", type=float, default=2.0)
    s.set_defaults(func=cmd_sweep)

    s = sub.add_parser("reporting", help="what one output frame costs")
    harness.add_options(s, repeats=3)
    s.add_argument("--calls", type=int, default=200)
    s.add_argument("--run", type=float, default=400.0,
                   help="tau_d of the whole runs (--repeats of them); 0: none")
    s.set_defaults(func=cmd_reporting)

    s = sub.add_parser("orbit", help="knotmm orbit (orbit + Floquet multipliers) against N")
    harness.add_options(s, repeats=1)
    s.add_argument("--beads", type=int, nargs="+", default=[40, 60, 90, 120])
    s.add_argument("--duration", type=float, default=120.0, help="tau_d of the run")
    s.add_argument("--modes", type=int, default=10)
    s.set_defaults(func=cmd_orbit)

    args = p.parse_args(argv)
    if args.quick:
        args.repeats = 1
        quick = {"run": dict(duration=1.0), "startup": {},
                 "replicas": dict(replicas=2, beads=40, duration=1.0),
                 "sweep": dict(points=1, seeds=2, beads=30, duration=8.0),
                 "reporting": dict(calls=10, run=1.0), "orbit": dict(beads=[40], modes=2)}
        for key, value in quick[args.command].items():
            setattr(args, key, value)
    info = harness.header(args)
    with tempfile.TemporaryDirectory(prefix="knotmm-bench-") as tmp:
        args.work = Path(tmp)
        cases, samples, extra = args.func(args)
    harness.save(f"bench_workflow {args.command}", args, cases, samples, extra, info)
    return 0


if __name__ == "__main__":
    sys.exit(main())
