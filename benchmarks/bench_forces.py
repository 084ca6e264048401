"""What one force + mobility evaluation costs: OpenMM's forces, the RPY mobility, both engines.

Four measurements, one sub-command each (T(2,3) templates, CPU platform with one OpenMM
thread unless said otherwise; cases interleaved, medians, ratios as medians of the
per-repetition ratios; ``benchmarks/harness.py``):

``engines``
    Seconds per evaluation against N for the Python engine (``Simulation.velocity`` and its
    pieces: ``forces`` = ``Simulation.forces``, the OpenMM round trip; ``mobility`` =
    ``rpy_velocities``), the compiled plugin (``RPYIntegrator("euler").step``: one evaluation
    and the position update; ``no-force``: the same step on a System without forces, i.e. the
    RPY loop, the update and OpenMM's fixed cost per force call; ``plugin2``: its pair loop on
    two threads, from N = 256) and the numba yardstick ``numba_chain.py`` (``forces``: bonded
    + O(N^2) steric loop; ``mobility``). Positions stay fixed between calls (no
    neighbour-list rebuilds; a run's evaluation costs more). ``--clock cpu`` times this
    process's CPU time (steadier on a shared machine).
``split``
    The Python engine's evaluation split into forces, mobility and overhead on the platforms
    asked for (``auto``: what a run takes; ``Reference``), the ratio velocity / mobility, and
    the RPY pair loop on ``--mobility-threads`` threads against one.
``terms``
    Where OpenMM's time goes: ``setPositions`` + ``getState(getForces=True)`` (new positions
    each call) for a System with no force, with each of knotmm's four forces alone, with all
    four, and with the bending as ``HarmonicAngleForce``; the RPY loop; the lower bound that
    OpenMM's fixed cost puts on "velocity / mobility".
``layouts``
    The cost of an evaluation inside a run (the plugin's rk23 from the template, tolerance
    1e-4, ``--duration`` tau_d in a fresh Context per timing, so the beads move and the
    neighbour list is rebuilt as in a run) for Force layouts, platforms, platform properties
    and thread placements (``NAME@pin``: the caller and OpenMM's pool thread on one core).
    ``--check`` compares forces with the current System's and with finite differences,
    ``--bits`` trajectories with the current one; ``--list`` names the variants.

Run on demand (not part of the tests)::

    python benchmarks/bench_forces.py engines --beads 40 90 240 480 1000 2000
    python benchmarks/bench_forces.py split --beads 40 90 120 240 480
    python benchmarks/bench_forces.py terms --beads 120 --repeats 7
    python benchmarks/bench_forces.py layouts --beads 90 --repeats 9 --cases current current@pin
    python benchmarks/bench_forces.py engines --quick       # any sub-command: a smoke run
"""

from __future__ import annotations

import sys
import time

import harness
import numpy as np

_KEEP = []  # Contexts must outlive their timers


# -- engines --------------------------------------------------------------------------------
def _python_timers(x) -> dict:
    from knotmm.dynamics.deterministic import Euler
    from knotmm.dynamics.mobility import rpy_velocities
    from knotmm.engine.simulation import Simulation

    sim = Simulation(x, integrator=Euler(1e-4), platform="CPU", threads=1)
    _KEEP.append(sim)
    f = sim.forces(x)
    out = np.empty_like(x)
    return {"velocity": lambda: sim.velocity(x), "forces": lambda: sim.forces(x),
            "mobility": lambda: rpy_velocities(x, f, out=out)}


def _plugin_step(system, x, threads=1, method="euler", step=1e-5):
    import openmm

    from knotmm.plugin import RPYIntegrator

    integ = RPYIntegrator(step, method, threads=threads)
    ctx = openmm.Context(system, integ, openmm.Platform.getPlatformByName("CPU"),
                         {"Threads": "1"})
    ctx.setPositions(x)
    _KEEP.append(ctx)
    return integ


def _empty_system(n):
    import openmm

    system = openmm.System()
    for _ in range(n):
        system.addParticle(1.0)
    return system


def _plugin_timers(x, two_threads: bool) -> dict:
    from knotmm.model.system import chain_system

    out = {"step": _plugin_step(chain_system(x), x).step,
           "no-force": _plugin_step(_empty_system(len(x)), x).step}
    if two_threads:
        out["step 2 threads"] = _plugin_step(chain_system(x), x, threads=2).step
    return {k: (lambda s=s: s(1)) for k, s in out.items()}


def _numba_timers(x) -> dict:
    nc = harness.load_yardstick("numba_chain")
    p = nc.parameters()
    f, v = np.empty_like(x), np.empty_like(x)
    nc.forces(x, p, f)
    return {"velocity": lambda: nc.velocity(x, p, f, v), "forces": lambda: nc.forces(x, p, f),
            "steric": lambda: nc.steric_forces(x, p, f), "mobility": lambda: nc.mobility(x, f, v)}


def _timed_cases(timers: dict, budget: float, clock) -> dict:
    cases = {}
    for key, fn in timers.items():  # warm up (compilation, OpenMM set-up) and calibrate
        calls = harness.calibrate(fn, budget, clock=clock)
        cases[key] = lambda fn=fn, calls=calls: harness.per_call(fn, calls, clock)
    return cases


def cmd_engines(args) -> tuple[dict, dict, dict]:
    from knotmm.plugin import available, load_error

    plugin = "plugin" in args.cases and available()
    if "plugin" in args.cases and not plugin:
        print(f"# plugin not measured: {load_error()}")
    timers = {}
    for n in args.beads:
        x = harness.template(n)
        groups = {}
        if "python" in args.cases:
            groups["python"] = _python_timers(x)
        if plugin:
            groups["plugin"] = _plugin_timers(x, n >= 256 and args.plugin_threads)
        if "numba" in args.cases:
            groups["numba"] = _numba_timers(x)
        for engine, fns in groups.items():
            for piece, fn in fns.items():
                timers[f"{n}/{engine}/{piece}"] = fn
    clock = time.process_time if args.clock == "cpu" else time.perf_counter
    samples = harness.interleave(_timed_cases(timers, args.budget, clock), args.repeats)
    cases = harness.summarize(samples, unit="s per evaluation")
    med = {k: v["median"] * 1e6 for k, v in cases.items()}
    print(f"\nmicroseconds per evaluation ({args.clock} clock)")
    print(f"{'N':>5} | {'python':>8} {'forces':>8} {'mobil.':>8} {'rest':>6} | {'plugin':>8} "
          f"{'forces':>8} {'no-force':>8} {'2 thr':>8} | {'numba':>8} {'forces':>8} "
          f"{'mobil.':>8} | {'py/pl':>6} {'py/nb':>6} {'pl/nb':>6}")
    ratios = {}

    def cell(key, width=8):
        return f"{med[key]:{width}.1f}" if key in med else f"{'-':>{width}}"

    def rat(a, b):
        if a in samples and b in samples:
            ratios[f"{a} / {b}"] = r = harness.ratio(samples, a, b)
            return f"{r:6.2f}"
        return f"{'-':>6}"

    for n in args.beads:
        py, pl, nb = f"{n}/python/", f"{n}/plugin/", f"{n}/numba/"
        rest = (f"{med[py + 'velocity'] - med[py + 'forces'] - med[py + 'mobility']:6.1f}"
                if py + "velocity" in med else f"{'-':>6}")
        plf = (f"{med[pl + 'step'] - med[pl + 'no-force']:8.1f}" if pl + "step" in med
               else f"{'-':>8}")
        print(f"{n:5d} | {cell(py + 'velocity')} {cell(py + 'forces')} {cell(py + 'mobility')} "
              f"{rest} | {cell(pl + 'step')} {plf} {cell(pl + 'no-force')} "
              f"{cell(pl + 'step 2 threads')} | {cell(nb + 'velocity')} {cell(nb + 'forces')} "
              f"{cell(nb + 'mobility')} | {rat(py + 'velocity', pl + 'step')} "
              f"{rat(py + 'velocity', nb + 'velocity')} {rat(pl + 'step', nb + 'velocity')}")
    return cases, samples, {"ratios": ratios}


# -- split ----------------------------------------------------------------------------------
def cmd_split(args) -> tuple[dict, dict, dict]:
    from knotmm.dynamics.mobility import rpy_velocities
    from knotmm.engine.simulation import Simulation

    timers, names = {}, {}
    for plat in args.platforms:
        for n in args.beads:
            x = harness.template(n)
            sim = Simulation(x, platform=plat, threads=args.threads)
            _KEEP.append(sim)
            names[plat] = sim.platform_name
            f = sim.forces(x)
            timers[f"{plat}/{n}/forces"] = lambda s=sim, x=x: s.forces(x)
            timers[f"{plat}/{n}/mobility"] = lambda x=x, f=f: rpy_velocities(x, f)
            timers[f"{plat}/{n}/velocity"] = lambda s=sim, x=x: s.velocity(x)
    for n in args.beads:
        x = harness.template(n)
        f = np.random.default_rng(n).normal(size=x.shape)
        timers[f"loop/{n}/1"] = lambda x=x, f=f: rpy_velocities(x, f)
        timers[f"loop/{n}/{args.mobility_threads}"] = (
            lambda x=x, f=f: rpy_velocities(x, f, threads=args.mobility_threads))
    samples = harness.interleave(_timed_cases(timers, args.budget, time.perf_counter),
                                 args.repeats)
    cases = harness.summarize(samples, unit="s per call")
    med = {k: v["median"] * 1e6 for k, v in cases.items()}
    print("\none velocity evaluation (Python engine), microseconds per call")
    print(f"{'N':>5} {'platform':>9} {'forces':>10} {'mobility':>10} {'overhead':>10} "
          f"{'velocity':>10} {'vel/mob':>8}")
    for plat in args.platforms:
        for n in args.beads:
            k = f"{plat}/{n}/"
            fo, mo, ve = med[k + "forces"], med[k + "mobility"], med[k + "velocity"]
            print(f"{n:>5} {names[plat]:>9} {fo:>10.1f} {mo:>10.1f} {ve - fo - mo:>10.1f} "
                  f"{ve:>10.1f} {ve / mo:>8.2f}")
    m = args.mobility_threads
    print(f"\nRPY pair loop on {m} threads (run.mobility_threads), microseconds per call")
    speedups = {}
    for n in args.beads:
        speedups[n] = harness.ratio(samples, f"loop/{n}/1", f"loop/{n}/{m}")
        print(f"{n:>5} {med[f'loop/{n}/1']:>10.1f} -> {med[f'loop/{n}/{m}']:>10.1f}  "
              f"({speedups[n]:.2f}x)")
    return cases, samples, {"platforms": names, "mobility_speedup": speedups}


# -- terms ----------------------------------------------------------------------------------
def _context(x, forces, threads):
    import openmm

    system = _empty_system(x.shape[0])
    for force in forces:
        system.addForce(force)
    context = openmm.Context(system, openmm.VerletIntegrator(0.01),
                             openmm.Platform.getPlatformByName("CPU"), {"Threads": str(threads)})
    context.setPositions(x)
    return context


def harmonic_bend(n, model):
    """The bending term as OpenMM's ``HarmonicAngleForce`` (knotmm's is a ``CustomAngleForce``)."""
    import openmm

    force = openmm.HarmonicAngleForce()
    for i in range(n):
        force.addAngle((i - 1) % n, i, (i + 1) % n, np.pi, model.bending_stiffness)
    return force


def cmd_terms(args) -> tuple[dict, dict, dict]:
    from knotmm.dynamics.mobility import rpy_velocities
    from knotmm.model.forces import bend_force, bond_force, gravity_force, steric_force
    from knotmm.model.parameters import ChainModel

    model = ChainModel()
    all_cases, all_samples, extra = {}, {}, {}
    for n in args.beads:
        x = harness.template(n)
        four = [bond_force(n, model), bend_force(n, model), steric_force(n, model),
                gravity_force(n, model)]
        variants = {"no forces": [], "bond alone": [bond_force(n, model)],
                    "bend alone": [bend_force(n, model)],
                    "steric alone": [steric_force(n, model)],
                    "gravity alone": [gravity_force(n, model)], "knotmm (all four)": four,
                    "all four, HarmonicAngleForce": [bond_force(n, model), harmonic_bend(n, model),
                                                     steric_force(n, model),
                                                     gravity_force(n, model)]}
        contexts = {name: _context(x, forces, args.threads) for name, forces in variants.items()}
        a = contexts["knotmm (all four)"].getState(getForces=True).getForces(asNumpy=True)._value
        b = contexts["all four, HarmonicAngleForce"].getState(getForces=True)
        deviation = float(np.abs(a - b.getForces(asNumpy=True)._value).max())
        # New positions every call, as in a run (the CPU platform redoes its neighbour list
        # and float copies after setPositions; the same positions again would skip that work).
        jitter = [x + 1e-6 * k for k in range(2)]
        toggle = [0]

        def call(context, jitter=jitter, toggle=toggle):
            toggle[0] ^= 1
            context.setPositions(jitter[toggle[0]])
            context.getState(getForces=True)

        fns = {name: (lambda c=c: call(c)) for name, c in contexts.items()}
        f = a.copy()
        fns["RPY mobility loop"] = lambda x=x, f=f: rpy_velocities(x, f)
        for fn in fns.values():
            fn()  # warm up
        samples = harness.interleave(
            {k: (lambda fn=fn: harness.per_call(fn, args.inner)) for k, fn in fns.items()},
            args.repeats)
        cases = harness.summarize(samples, baseline="knotmm (all four)",
                                  unit="s per call")
        med = {k: v["median"] * 1e6 for k, v in cases.items()}
        print(f"\nN = {n}, microseconds per call")
        for name, us in med.items():
            print(f"  {name:<30} {us:8.1f}")
        angle = 1 / cases["all four, HarmonicAngleForce"]["ratio"]
        floor = (med["no forces"] + med["RPY mobility loop"]) / med["RPY mobility loop"]
        print(f"  CustomAngleForce / HarmonicAngleForce, whole System: {angle:.3f} "
              f"(largest force difference {deviation:.1e} F0)")
        print(f"  lower bound of velocity / mobility (empty System + loop): {floor:.2f}")
        all_cases.update({f"{n}/{k}": v for k, v in cases.items()})
        all_samples.update({f"{n}/{k}": v for k, v in samples.items()})
        extra[n] = {"custom_over_harmonic": angle, "force_difference": deviation,
                    "velocity_over_mobility_floor": floor}
    return all_cases, all_samples, extra


# -- layouts --------------------------------------------------------------------------------
def cmd_layouts(args) -> tuple[dict, dict, dict]:
    import force_layouts as fl

    from knotmm.model.parameters import ChainModel

    if args.list:
        print("\n".join(fl.VARIANTS))
        return {}, {}, {}
    names = list(dict.fromkeys(["current", *args.cases]))
    model = ChainModel()
    all_cases, all_samples, extra = {}, {}, {}
    for n in args.beads:
        x = harness.template(n)
        if args.check:
            print(f"\nN = {n}: forces and energy against the current System (Reference "
                  f"platform; 4 shapes along the run and 3 with steric contacts): max |dF| / "
                  f"max |F|, max |dE| / |E|; forces against central differences of the "
                  f"variant's energy (h = 1e-5 d, 12 coordinates), / max |F|")
            checks = fl.check_forces(names, x, model, args.duration)
            for name, (df, de, fd) in checks.items():
                print(f"  {name:24s} {df:9.2e} {de:9.2e} {fd:9.2e}")
            extra[f"{n}/check"] = checks
        if args.bits:
            for label, start in (("the template", x),
                                 ("a thin-tube template (steric contacts)",
                                  harness.template(n, minor_radius=0.26))):
                print(f"\nN = {n}: positions after {args.duration:g} tau_d from {label} against "
                      f"current (CPU variants) or reference (Reference variants): max |dx| [d], "
                      f"evaluations (variant / baseline)")
                bits = fl.check_bits(names, start, model, args.duration)
                for name, (dx, ev, ev0) in bits.items():
                    print(f"  {name:24s} {dx:9.2e} {ev:6d} {ev0:6d}")
                extra[f"{n}/bits/{label}"] = bits
        for name in names:  # warm-up: loading, JIT of custom expressions
            fl.time_variant(name, x, model, min(0.5, args.duration))
        evals = {}

        def case(name, x=x, evals=evals):
            per, evals[name] = fl.time_variant(name, x, model, args.duration)
            return per

        samples = harness.interleave({name: (lambda k=name: case(k)) for name in names},
                                     args.repeats)
        cases = harness.summarize(samples, baseline="current", unit="s per evaluation")
        print(f"\nN = {n}: microseconds per evaluation inside a run (rk23 from the template, "
              f"{args.duration:g} tau_d a timing)")
        print(f"  {'variant':24s} {'median':>8} {'min':>8} {'max':>8} {'ratio':>6} {'evals':>6}")
        for name in names:
            c = cases[name]
            print(f"  {name:24s} {c['median'] * 1e6:8.1f} {c['min'] * 1e6:8.1f} "
                  f"{c['max'] * 1e6:8.1f} {c['ratio']:6.2f} {evals[name]:6d}")
        all_cases.update({f"{n}/{k}": v for k, v in cases.items()})
        all_samples.update({f"{n}/{k}": v for k, v in samples.items()})
        extra[f"{n}/evaluations"] = dict(evals)
    return all_cases, all_samples, extra


# -- command line ---------------------------------------------------------------------------
def main(argv=None):
    import argparse

    import force_layouts

    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="command", required=True)

    s = sub.add_parser("engines", help="Python engine, plugin and numba against N")
    harness.add_options(s, ["python", "plugin", "numba"], repeats=3)
    s.add_argument("--beads", type=int, nargs="+", default=list(harness.SIZES["large"]))
    s.add_argument("--budget", type=float, default=0.2, help="seconds per timing")
    s.add_argument("--clock", choices=["wall", "cpu"], default="wall")
    s.add_argument("--no-plugin-threads", dest="plugin_threads", action="store_false",
                   help="skip the plugin's two-thread pair loop (N >= 256)")
    s.set_defaults(func=cmd_engines)

    s = sub.add_parser("split", help="the Python engine's evaluation: forces, mobility, rest")
    harness.add_options(s, repeats=7)
    s.add_argument("--beads", type=int, nargs="+", default=[40, 90, 120, 240, 480])
    s.add_argument("--platforms", nargs="+", default=["auto", "Reference"])
    s.add_argument("--threads", type=int, default=1, help="CPU platform threads")
    s.add_argument("--mobility-threads", type=int, default=2)
    s.add_argument("--budget", type=float, default=0.02, help="seconds per timing")
    s.set_defaults(func=cmd_split)

    s = sub.add_parser("terms", help="OpenMM's cost per force term")
    harness.add_options(s, repeats=7)
    s.add_argument("--beads", type=int, nargs="+", default=[40, 90, 120, 240])
    s.add_argument("--inner", type=int, default=300, help="calls per timing")
    s.add_argument("--threads", type=int, default=1, help="CPU platform threads")
    s.set_defaults(func=cmd_terms)

    s = sub.add_parser("layouts", help="an evaluation inside a run, per Force layout/platform")
    harness.add_options(s, force_layouts.DEFAULT, repeats=5)
    s.set_defaults(func=cmd_layouts)
    s.add_argument("--beads", type=int, nargs="+", default=[90, 240])
    s.add_argument("--duration", type=float, default=8.0, help="tau_d per timing")
    s.add_argument("--check", action="store_true", help="compare forces first")
    s.add_argument("--bits", action="store_true", help="compare trajectories first")
    s.add_argument("--list", action="store_true", help="name the variants")

    args = p.parse_args(argv)
    if args.quick:
        args.repeats = 1
        args.beads = [40] if args.command != "layouts" else [90]
        if hasattr(args, "budget"):
            args.budget = 0.01
        if hasattr(args, "inner"):
            args.inner = 20
        if args.command == "split":
            args.platforms = ["auto"]
        if args.command == "layouts":
            args.duration = 0.5
            args.cases = ["current", "current@pin", "reference"]
    info = harness.header(args)
    cases, samples, extra = args.func(args)
    if cases:
        harness.save(f"bench_forces {args.command}", args, cases, samples, extra, info)
    return 0


if __name__ == "__main__":
    sys.exit(main())
