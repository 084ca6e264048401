"""What the integrators cost: deterministic and Brownian steps, adaptive and fixed, both engines.

Four measurements, one sub-command each (T(2,3) templates, the study's parameters; cases
interleaved, medians, ratios as medians of the per-repetition ratios;
``benchmarks/harness.py``):

``deterministic``
    A whole rk23 run of ``--duration`` tau_d from the template (tolerance 1e-4) in this
    process: the Python engine (``Simulation.run``) against the plugin
    (``RPYIntegrator.stepTo``), which adds the Python engine's per-stage numpy work to the
    comparison of one evaluation (``bench_forces.py engines``); ``--clock cpu`` for this
    process's CPU time.
``brownian``
    One Brownian step (gravity 0, Pe 2, Cholesky noise, CPU platform with one thread,
    BLAS/LAPACK on one thread): the numba + LAPACK yardstick ``numba_brownian.py``, the
    Python engine and the plugin engine take ``--steps`` steps from the same start, for each
    scheme (``ito_heun`` at 0.002 tau_d, ``leimkuhler_matthews`` at 0.01). Then where a step's
    time goes (CPU microseconds per call, each piece timed alone): numba and Python engine
    ``forces`` (the Python engine's cycles through 64 consecutive positions of a Brownian run,
    so the CPU platform rebuilds its neighbour list as in a run; ``forces fixed`` repeats one),
    ``mobility``, ``matrix`` (dense RPY), ``cholesky`` (LAPACK ``dpotrf``), ``L xi``, ``rest``;
    plugin ``step``, ``still`` (kT = 1e-12: every noise sample drawn, beads still), ``det``
    (kT = 0), ``no-force``, ``noise`` = still - det, ``motion`` = step - still, ``forces`` =
    det / evaluations - no-force, ``cholesky`` / ``cholesky builtin`` (the plugin's
    factorisation alone). ``--noise lanczos`` gives both engines Lanczos noise (the numba
    program keeps its Cholesky) and skips the pieces.
``adaptive``
    Whole ``knotmm run`` commands (plugin engine, gravity as given), one per integrator and
    seed, interleaved by seed: runs finished, median wall time, steps, rejections, and the
    wall-time ratio of the first integrator to each other one over the seeds both finished.
``platforms``
    Seconds per accepted plugin step on each platform the plugin has a kernel on (Reference,
    CPU with one thread, OpenCL, CUDA), ``--methods`` rk23 and ito_heun_adaptive (kT = 1,
    ``--noise`` Lanczos), N beads as rings of 100 (one ring below 200), device platforms in
    ``--precision``; the ratio of each platform to Reference.
``stiff``
    ``knotmm run --duration 40`` with ``model.bending_stiffness = 5000`` against ``= 5`` (N =
    90, ``run.integrator = "auto"``, plus each ``--stiff-reference`` integrator). A stiff run
    longer than ``--stiff-timeout`` is stopped; its cost is then extrapolated from the
    simulated time it reached and reported as such.

Run on demand (not part of the tests)::

    python benchmarks/bench_steps.py deterministic --beads 40 90 240 480 --clock cpu
    python benchmarks/bench_steps.py brownian                      # both schemes, about 1 min
    python benchmarks/bench_steps.py brownian --schemes ito_heun --beads 400 --noise lanczos \\
        --steps 20 --burn 0.01
    python benchmarks/bench_steps.py adaptive --peclet 1 --beads 90 --duration 30 \\
        --seeds 1 2 3 --cases ito_heun_adaptive ito_heun:0.002 leimkuhler_matthews:0.01
    python benchmarks/bench_steps.py stiff --repeats 3
    python benchmarks/bench_steps.py platforms --beads 90 3000 --steps 3
    python benchmarks/bench_steps.py brownian --quick     # any sub-command: a smoke run
"""

from __future__ import annotations

import csv
import os
import statistics
import sys
import tempfile
import time
from functools import partial
from pathlib import Path

import harness
import numpy as np

#: Brownian scheme -> its step (tau_d) in ``brownian``.
STEPS = {"ito_heun": 0.002, "leimkuhler_matthews": 0.01}
#: Force + mobility evaluations per step, and noise samples per step.
COUNTS = {"ito_heun": (2, 1), "leimkuhler_matthews": (1, 1)}
#: The pieces are timed in CPU time (less disturbed by other jobs on a shared machine).
CLOCK = time.process_time


# -- deterministic --------------------------------------------------------------------------
def cmd_deterministic(args):
    import openmm

    from knotmm.dynamics.deterministic import RK23
    from knotmm.engine.simulation import Simulation
    from knotmm.model.system import chain_system
    from knotmm.plugin import RPYIntegrator

    clock = time.process_time if args.clock == "cpu" else time.perf_counter
    evaluations = {}

    def python_run(n):
        sim = Simulation(harness.template(n), integrator=RK23(0.01), platform="CPU", threads=1)
        t0 = clock()
        sim.run(args.duration)
        evaluations[f"{n}/python"] = sim.n_evaluations
        return clock() - t0

    def plugin_run(n):
        x = harness.template(n)
        integ = RPYIntegrator(0.01, "rk23", threads=1)
        ctx = openmm.Context(chain_system(x), integ, openmm.Platform.getPlatformByName("CPU"),
                             {"Threads": "1"})
        ctx.setPositions(x)
        t0 = clock()
        integ.stepTo(args.duration)
        evaluations[f"{n}/plugin"] = integ.getNumForceEvaluations()
        del ctx
        return clock() - t0

    cases = {}
    for n in args.beads:
        cases[f"{n}/python"] = partial(python_run, n)
        cases[f"{n}/plugin"] = partial(plugin_run, n)
    plugin_run(args.beads[0])  # warm-up: numba, OpenMM kernels
    python_run(args.beads[0])
    samples = harness.interleave(cases, args.repeats)
    summary = harness.summarize(samples, unit=f"{args.clock} s per run")
    print(f"\nwhole rk23 run of {args.duration:g} tau_d ({args.clock} s; evaluations)")
    ratios = {}
    for n in args.beads:
        py, pl = summary[f"{n}/python"]["median"], summary[f"{n}/plugin"]["median"]
        ratios[n] = harness.ratio(samples, f"{n}/python", f"{n}/plugin")
        print(f"{n:6d} python {py:8.3f} s ({evaluations[f'{n}/python']} ev)   plugin "
              f"{pl:8.3f} s ({evaluations[f'{n}/plugin']} ev)   ratio {ratios[n]:6.2f}")
    return summary, samples, {"evaluations": evaluations, "python_over_plugin": ratios}


# -- brownian -------------------------------------------------------------------------------
def _config(scheme, args, engine):
    from knotmm.config import RunConfig

    return RunConfig.from_dict({
        "knot": {"beads": args.beads},
        "model": {"gravity": 0.0},
        "run": {"peclet": args.peclet, "integrator": scheme, "timestep": STEPS[scheme],
                "seed": args.seed, "platform": "CPU", "engine": engine, "noise": args.noise},
    })


def python_pieces(sim, budget, trajectory) -> dict:
    """CPU microseconds per call of the Python engine's pieces of a Brownian step."""
    import scipy.linalg

    from knotmm.dynamics.mobility import rpy_matrix, rpy_velocities

    per_call = partial(harness.load_yardstick("numba_brownian").per_call, clock=CLOCK)
    x = sim.positions.copy()
    k = [0]

    def moving():  # consecutive positions of a run: the CPU platform rebuilds its list
        k[0] = (k[0] + 1) % len(trajectory)
        sim.forces(trajectory[k[0]])

    f = sim.forces(x)
    out = np.empty_like(x)
    m = rpy_matrix(x)
    lower = scipy.linalg.cholesky(m, lower=True, check_finite=False)
    rng = np.random.default_rng(0)
    return {
        "forces": per_call(moving, budget),
        "forces fixed": per_call(lambda: sim.forces(x), budget),
        "mobility": per_call(lambda: rpy_velocities(x, f, out=out), budget),
        "matrix": per_call(lambda: rpy_matrix(x), budget),
        "cholesky": per_call(
            lambda: scipy.linalg.cholesky(m, lower=True, check_finite=False), budget),
        "L xi": per_call(lambda: lower @ rng.standard_normal(m.shape[0]), budget),
    }


def plugin_pieces(sim, scheme, args, budget) -> dict:
    """CPU microseconds per call of the plugin's pieces of a Brownian step."""
    import openmm

    from knotmm.dynamics.mobility import rpy_matrix
    from knotmm.model.system import chain_system
    from knotmm.plugin import RPYIntegrator, rpyplugin

    per_call = partial(harness.load_yardstick("numba_brownian").per_call, clock=CLOCK)
    x = sim.positions.copy()
    cpu = openmm.Platform.getPlatformByName("CPU")
    keep = []

    def stepper(system, method, kt):
        """One step of a fresh Context (from the run's positions) per call."""
        integ = RPYIntegrator(STEPS[scheme], method, kT=kt, seed=1, threads=1)
        ctx = openmm.Context(system, integ, cpu, {"Threads": "1"})
        ctx.setPositions(x)
        keep.append(ctx)
        return lambda: integ.step(1)

    empty = openmm.System()
    for _ in range(len(x)):
        empty.addParticle(1.0)
    system = chain_system(x, sim.model)
    a = rpy_matrix(x)
    return {
        "step": per_call(stepper(system, scheme, 1.0 / args.peclet), budget),
        "still": per_call(stepper(system, scheme, 1e-12), budget),
        "det": per_call(stepper(system, scheme, 0.0), budget),
        "no-force": per_call(stepper(empty, "euler", 0.0), budget),
        "cholesky": per_call(lambda: rpyplugin.choleskyFactor(a, False), budget),
        "cholesky builtin": per_call(lambda: rpyplugin.choleskyFactor(a, True), budget),
    }


def brownian_scheme(scheme, args) -> tuple[dict, dict, dict]:
    from knotmm.engine.simulation import Simulation

    nb = harness.load_yardstick("numba_brownian")
    dt, kt = STEPS[scheme], 1.0 / args.peclet
    engines = ["python", "plugin"]
    sims = {e: Simulation.from_config(_config(scheme, args, e), engine=e) for e in engines}
    x0 = sims["python"].positions.copy()
    params = nb.parameters(gravity=0.0)
    state = {"numba": nb.run(scheme, x0, params, kt, dt, int(round(args.burn / dt)), args.seed),
             "repeat": 0}
    for sim in sims.values():
        sim.run(args.burn)
    steps = args.steps

    def timed(fn):
        t0, c0 = time.perf_counter(), time.process_time()
        n = fn()
        n = steps if n is None else n
        return {"wall": 1e6 * (time.perf_counter() - t0) / n,
                "cpu": 1e6 * (time.process_time() - c0) / n}

    def numba_case():
        state["repeat"] += 1

        def go():
            state["numba"] = nb.run(scheme, state["numba"], params, kt, dt, steps,
                                    args.seed + state["repeat"])
        return timed(go)

    def engine_case(sim):
        def go():
            n0 = sim.currentStep
            sim.run(steps * dt)
            return sim.currentStep - n0
        return timed(go)

    cases = {"numba": numba_case}
    cases.update({e: partial(engine_case, sims[e]) for e in engines})
    load0 = os.getloadavg()[0]
    samples = harness.interleave(cases, args.repeats)
    loads = (load0, os.getloadavg()[0])
    wall = harness.summarize(samples, baseline="numba", key="wall", unit="wall us per step")
    cpu = harness.summarize(samples, baseline="numba", key="cpu", unit="cpu us per step")
    print(f"\n{scheme}, dt = {dt:g} tau_d, T(2,3) N = {args.beads}, Pe = {args.peclet:g}, "
          f"gravity 0, {args.noise} noise, {steps} steps per run; load "
          f"{min(loads):.2f}-{max(loads):.2f}")
    print(f"  {'':<7} {'wall':>8} {'cpu':>8} us/step  {'wall/numba':>10} {'cpu/numba':>10} "
          f"{'tau_d/s':>8}  runs (wall/cpu)")
    rates = {}
    for k in cases:
        spread = ", ".join(f"{s['wall']:.0f}/{s['cpu']:.0f}" for s in samples[k])
        rates[k] = dt / (1e-6 * wall[k]["median"])  # simulated tau_d per wall second
        print(f"  {k:<7} {wall[k]['median']:8.0f} {cpu[k]['median']:8.0f}          "
              f"{wall[k]['ratio']:10.2f} {cpu[k]['ratio']:10.2f} {rates[k]:8.2f}  ({spread})")
    summary = {f"{scheme}/{k}/wall": v for k, v in wall.items()}
    summary.update({f"{scheme}/{k}/cpu": v for k, v in cpu.items()})
    extra = {"tau_d_per_wall_second": rates, "load": loads}
    if args.noise != "cholesky" or args.no_pieces:
        return summary, {f"{scheme}/{k}": v for k, v in samples.items()}, extra
    n_eval, n_noise = COUNTS[scheme]
    trajectory = [state["numba"]]
    for k in range(63):
        trajectory.append(nb.run(scheme, trajectory[-1], params, kt, dt, 1, k))
    pieces = {"numba": nb.profile(state["numba"], params, args.budget, clock=CLOCK),
              "python": python_pieces(sims["python"], args.budget, trajectory)}
    for k in ("numba", "python"):
        pc = pieces[k]
        used = n_eval * (pc["forces"] + pc["mobility"]) + n_noise * (
            pc["matrix"] + pc["cholesky"] + pc["L xi"])
        pc["rest"] = cpu[k]["median"] - used
        print(f"  {k:<7} cpu us/call: " + ", ".join(f"{n} {t:.0f}" for n, t in pc.items())
              + f"  (x{n_eval} forces, mobility; x{n_noise} matrix, cholesky, L xi)")
    pc = pieces["plugin"] = plugin_pieces(sims["plugin"], scheme, args, args.budget)
    pc["noise"] = pc["still"] - pc["det"]
    pc["motion"] = pc["step"] - pc["still"]
    pc["forces"] = pc["det"] / n_eval - pc["no-force"]
    print("  plugin  cpu us/call: " + ", ".join(f"{n} {t:.0f}" for n, t in pc.items()))
    extra["pieces_cpu_us"] = pieces
    return summary, {f"{scheme}/{k}": v for k, v in samples.items()}, extra


def cmd_brownian(args):
    from threadpoolctl import threadpool_limits

    summary, samples, extra = {}, {}, {}
    with threadpool_limits(args.blas_threads):
        for scheme in args.schemes:
            s, m, e = brownian_scheme(scheme, args)
            summary.update(s)
            samples.update(m)
            extra[scheme] = e
    return summary, samples, extra


# -- whole runs -----------------------------------------------------------------------------
def _facts(out: Path) -> dict:
    from knotmm.config import read_toml

    if (out / "run.toml").is_file():
        return read_toml(out / "run.toml").get("knotmm", {})
    return {}


def cmd_adaptive(args):
    work = args.work
    rows = []

    def case(spec):
        seed = args.seeds[sum(r["spec"] == spec for r in rows) % len(args.seeds)]
        name, _, step = spec.partition(":")
        out = work / f"{name}_{step or 'auto'}_{seed}"
        sets = [f"run.peclet={args.peclet}", f"run.seed={seed}", f"model.gravity={args.gravity}",
                f"run.integrator={name}",
                f"model.segment_repulsion={'true' if args.segments else 'false'}"]
        if step:
            sets.append(f"run.timestep={step}")
        r = harness.knotmm_run(out, args.duration, sets, ["--beads", str(args.beads)],
                               check=False)
        facts = _facts(out)
        rows.append(dict(spec=spec, seed=seed, wall=r["wall"], ok=r["rc"] == 0,
                         steps=facts.get("steps"), rejected=facts.get("rejected_steps"),
                         time=facts.get("time_reached"),
                         message="" if r["rc"] == 0 else r["last"][:160]))
        return rows[-1]

    # one repetition per seed; within it every integrator, the order reversed every other one
    harness.interleave({spec: partial(case, spec) for spec in args.cases}, len(args.seeds))
    print(f"Pe = {args.peclet:g}, N = {args.beads}, gravity {args.gravity:g}, "
          f"{args.duration:g} tau_d, segment repulsion {'on' if args.segments else 'off'}")
    first, summary = args.cases[0], {}
    for spec in args.cases:
        mine = [r for r in rows if r["spec"] == spec]
        done = [r for r in mine if r["ok"]]
        row = {"finished": len(done), "runs": len(mine), "unit": "s"}
        line = f"  {spec:28s} finished {len(done)}/{len(mine)}"
        if done:
            row.update(median=statistics.median(r["wall"] for r in done),
                       steps=statistics.median(r["steps"] or 0 for r in done),
                       rejected=statistics.median(r["rejected"] or 0 for r in done))
            line += (f", wall {row['median']:.2f} s (median), steps {row['steps']:.0f}, "
                     f"rejected {row['rejected']:.0f}")
        if spec != first:
            pairs = [(a["wall"], b["wall"]) for a in rows for b in mine
                     if a["spec"] == first and a["seed"] == b["seed"] and a["ok"] and b["ok"]]
            if pairs:
                row["ratio"] = statistics.median(a / b for a, b in pairs)
                row["baseline"] = first
                line += f"; {first} / this: {row['ratio']:.2f} (median of {len(pairs)})"
        summary[spec] = row
        print(line)
        for r in mine:
            if not r["ok"]:
                print(f"    seed {r['seed']}: {r['message']}")
    return summary, {spec: [r for r in rows if r["spec"] == spec] for spec in args.cases}, {}


def _reached_time(path: Path) -> float:
    """Simulated time of the last row of a run's observables.csv (0 if none)."""
    try:
        with open(path) as fh:
            rows = list(csv.DictReader(fh))
        return float(rows[-1]["time"]) if rows else 0.0
    except (OSError, KeyError, ValueError):
        return 0.0


def cmd_stiff(args):
    work = args.work
    variants = harness.parse_variants(args.variant, args.sets)
    jobs = {}

    def run(sets, timeout=None):
        r = harness.knotmm_run(work / "run", args.duration, sets, timeout=timeout)
        r["reached"] = _reached_time(work / "run" / "observables.csv")
        return r

    for name, sets in variants:
        jobs[f"A=5[{name}]"] = partial(run, [*sets, "model.bending_stiffness=5"])
        jobs[f"A=5000[{name}]"] = partial(run, [*sets, "model.bending_stiffness=5000"],
                                          args.stiff_timeout)
        for method in args.stiff_reference:
            jobs[f"A=5000 {method}[{name}]"] = partial(
                run, [*sets, "model.bending_stiffness=5000", f'run.integrator="{method}"'],
                args.stiff_timeout)
    print(f"\nN = 90, {args.duration:g} tau_d: bending_stiffness 5000 vs 5 (stiff runs stopped "
          f"after {args.stiff_timeout:g} s)")
    samples = harness.interleave(jobs, args.repeats, log=print)
    summary = {}
    for name, _ in variants:
        soft_key = f"A=5[{name}]"
        soft = statistics.median(s["wall"] for s in samples[soft_key])
        for key in [k for k in jobs if k.startswith("A=5000") and k.endswith(f"[{name}]")]:
            stiff = samples[key]
            if any(s["rc"] == "timeout" for s in stiff):
                # the cost grows linearly in simulated time (steps set by stability) after
                # start-up; the whole soft run stands in for the start-up: a low estimate
                est = statistics.median(
                    soft + (s["wall"] - soft) * args.duration / s["reached"]
                    if s["rc"] == "timeout" and s["reached"] > 0 else s["wall"] for s in stiff)
                reached = statistics.median(s["reached"] for s in stiff)
                summary[key] = {"extrapolated": est, "ratio": est / soft, "unit": "s",
                                "reached": reached, "baseline": soft_key}
                print(f"  {key} / {soft_key}: stopped after {args.stiff_timeout:g} s at t = "
                      f"{reached:g} tau_d (median): ratio > {args.stiff_timeout / soft:.1f}x; "
                      f"extrapolated {est:.0f} s = {est / soft:.1f}x (target <= 6x)")
            else:
                row = harness.summarize({key: stiff, soft_key: samples[soft_key]},
                                        baseline=soft_key, key="wall")[key]
                row["cpu_ratio"] = harness.ratio(samples, key, soft_key, key="cpu")
                summary[key] = row
                print(f"  {key} / {soft_key}: {row['median']:.2f} / {soft:.2f} s wall = "
                      f"{row['ratio']:.2f}x (cpu {row['cpu_ratio']:.2f}x; target <= 6x)")
                print(f"    {stiff[-1]['last']}")
        summary[soft_key] = harness.summarize({soft_key: samples[soft_key]}, key="wall")[soft_key]
    return summary, samples, {"variants": variants}


# -- platforms ------------------------------------------------------------------------------
def _rings(n: int, per_ring: int = 100):
    """``n`` beads as T(2,3) rings of ``per_ring`` beads side by side (one ring below 2 rings'
    worth), with their layout."""
    from knotmm.model.layout import ChainLayout

    if n < 2 * per_ring:
        return harness.template(n), ChainLayout.ring(n)
    k = n // per_ring
    side = int(np.ceil(np.sqrt(k)))
    ring = harness.template(per_ring)
    gap = 2.0 * np.abs(ring[:, :2]).max() + 2.0  # the rings' width and 2 d between them
    x = np.vstack([ring + [gap * (i % side), gap * (i // side), 0.0] for i in range(k)])
    return x, ChainLayout((per_ring,) * k, (True,) * k)


def cmd_platforms(args):
    """Seconds per accepted plugin step on each platform the plugin has a kernel on."""
    import openmm

    from knotmm.engine.engines import plugin_platforms
    from knotmm.model.system import chain_system
    from knotmm.plugin import RPYIntegrator

    names = [n for n in (args.platforms or plugin_platforms()) if n in plugin_platforms()]
    properties = {"CPU": {"Threads": "1"}, "Reference": {}}
    contexts = {}

    def make(name, n, method):
        x, layout = _rings(n)
        kwargs = {"threads": 1}
        if method != "rk23":
            kwargs.update(kT=1.0, seed=1, noise=args.noise, error_tolerance=args.tolerance)
        integ = RPYIntegrator(0.001 if method != "rk23" else 0.01, method, **kwargs)
        props = properties.get(name, {"Precision": args.precision})
        ctx = openmm.Context(chain_system(x, layout=layout), integ,
                             openmm.Platform.getPlatformByName(name), props)
        ctx.setPositions(x)
        integ.step(2)  # kernels compiled, caches warm
        return integ, ctx

    def timed(key, steps):
        integ, _ = contexts[key]
        before = integ.getNumAcceptedSteps()
        t0 = time.perf_counter()
        integ.step(steps)
        return (time.perf_counter() - t0) / (integ.getNumAcceptedSteps() - before)

    cases = {}
    for n in args.beads:
        for method in args.methods:
            for name in names:
                key = f"{n}/{method}/{name}"
                contexts[key] = make(name, n, method)
                cases[key] = partial(timed, key, args.steps)
    samples = harness.interleave(cases, args.repeats)
    summary = harness.summarize(samples, unit="s per step")
    ratios = {}
    print(f"\nseconds per accepted step ({args.precision} on device platforms)")
    for n in args.beads:
        for method in args.methods:
            base = f"{n}/{method}/Reference"
            line = [f"{n:6d} {method:18s}"]
            for name in names:
                key = f"{n}/{method}/{name}"
                line.append(f"{name} {summary[key]['median'] * 1e3:9.3f} ms")
                if name != "Reference" and base in samples:
                    ratios[key] = harness.ratio(samples, key, base)
                    line.append(f"(x{ratios[key]:.2f} of Reference)")
            print("  ".join(line))
    return summary, samples, {"over_reference": ratios, "platforms": names}


# -- command line ---------------------------------------------------------------------------
def main(argv=None):
    import argparse

    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="command", required=True)

    s = sub.add_parser("deterministic", help="a whole rk23 run: Python engine against plugin")
    harness.add_options(s, repeats=3)
    s.add_argument("--beads", type=int, nargs="+", default=[40, 90, 240, 480])
    s.add_argument("--duration", type=float, default=5.0, help="tau_d per run")
    s.add_argument("--clock", choices=["wall", "cpu"], default="wall")
    s.set_defaults(func=cmd_deterministic)

    s = sub.add_parser("brownian", help="a Brownian step: numba, Python engine, plugin")
    harness.add_options(s, repeats=3)
    s.add_argument("--schemes", nargs="+", default=list(STEPS), choices=list(STEPS))
    s.add_argument("--beads", type=int, default=90)
    s.add_argument("--peclet", type=float, default=2.0)
    s.add_argument("--seed", type=int, default=1)
    s.add_argument("--steps", type=int, default=1000, help="steps per timed run")
    s.add_argument("--burn", type=float, default=0.2, help="tau_d before timing")
    s.add_argument("--budget", type=float, default=0.5, help="s per piece timing")
    s.add_argument("--blas-threads", type=int, default=1)
    s.add_argument("--noise", default="cholesky", choices=["cholesky", "lanczos"],
                   help="the engines' noise (the numba program's is Cholesky)")
    s.add_argument("--no-pieces", action="store_true", help="skip where a step's time goes")
    s.set_defaults(func=cmd_brownian)

    s = sub.add_parser("adaptive", help="whole Brownian runs: adaptive against fixed steps")
    harness.add_options(s, ["ito_heun_adaptive", "ito_heun:0.002"], repeats=1)
    s.add_argument("--peclet", type=float, default=1.0)
    s.add_argument("--beads", type=int, default=90)
    s.add_argument("--gravity", type=float, default=1.0)
    s.add_argument("--duration", type=float, default=30.0)
    s.add_argument("--segments", action="store_true", help="segment repulsion on")
    s.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3],
                   help="one repetition per seed (--repeats is not used)")
    s.set_defaults(func=cmd_adaptive)

    s = sub.add_parser("stiff", help="bending_stiffness 5000 against 5, whole runs")
    harness.add_options(s, repeats=3)
    s.add_argument("--duration", type=float, default=40.0)
    s.add_argument("--stiff-timeout", type=float, default=120.0,
                   help="seconds after which a stiff run is stopped")
    s.add_argument("--stiff-reference", nargs="*", default=["rkc2"],
                   help="integrators to run the stiff case with as well")
    s.add_argument("--set", dest="sets", action="append", default=[], metavar="TABLE.KEY=VALUE")
    s.add_argument("--variant", action="append", default=[], metavar="NAME:K=V[;K=V]")
    s.set_defaults(func=cmd_stiff)

    s = sub.add_parser("platforms", help="a plugin step on each platform it has a kernel on")
    harness.add_options(s, repeats=3)
    s.add_argument("--beads", type=int, nargs="+", default=[90, 3000])
    s.add_argument("--methods", nargs="+", default=["rk23", "ito_heun_adaptive"])
    s.add_argument("--platforms", nargs="*", default=None,
                   help="default: every platform the plugin has a kernel on")
    s.add_argument("--precision", default="double", choices=["mixed", "double"])
    s.add_argument("--noise", default="lanczos", choices=["cholesky", "lanczos"])
    s.add_argument("--tolerance", type=float, default=1e-4,
                   help="ito_heun_adaptive's error tolerance, in d")
    s.add_argument("--steps", type=int, default=5, help="steps per timed sample")
    s.set_defaults(func=cmd_platforms)

    args = p.parse_args(argv)
    if args.quick:
        args.repeats = 1
        quick = {"deterministic": dict(beads=[40], duration=0.5),
                 "brownian": dict(steps=20, burn=0.01, budget=0.02,
                                  schemes=["leimkuhler_matthews"]),
                 "adaptive": dict(beads=40, duration=0.5, seeds=[1]),
                 "stiff": dict(duration=0.5, stiff_timeout=20.0, stiff_reference=[]),
                 "platforms": dict(beads=[40], steps=2)}
        for key, value in quick[args.command].items():
            setattr(args, key, value)
    info = harness.header(args)
    with tempfile.TemporaryDirectory(prefix="knotmm-bench-") as tmp:
        args.work = Path(tmp)
        cases, samples, extra = args.func(args)
    harness.save(f"bench_steps {args.command}", args, cases, samples, extra, info)
    return 0


if __name__ == "__main__":
    sys.exit(main())
