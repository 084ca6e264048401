"""Cost of one force + mobility evaluation: the compiled plugin against the Python engine.

For each N (a T(2,3) template) on the CPU platform (one thread), times

* ``python``  : ``knotmm.engine.simulation.Simulation.velocity`` (OpenMM forces through the Python
  API, then the numba RPY loop of :mod:`knotmm.dynamics.mobility`), per call;
* ``plugin``  : ``RPYIntegrator("euler").step(k)`` divided by ``k``: one Euler step is one
  evaluation (forces asked for in C++, the C++ RPY loop) plus the position update;
* ``plugin2`` : the same with the plugin's pair loop on two threads (from N = 256 up);

and, with ``--run`` (default 5 tau_d), the wall time of a whole rk23 run from the template
(tolerance 1e-4): ``knotmm.engine.simulation.Simulation.run`` against
``RPYIntegrator.stepTo``, which
adds the Python engine's per-stage numpy work to the comparison (one run each, after the
evaluation timings).

Each figure is the median over ``--repeats`` repeats; within a repeat the engines and sizes
are interleaved, so slow phases of a shared machine hit all of them alike. The ratio
``python / plugin`` is printed per N. Run on demand (not a test)::

    python benchmarks/bench_plugin.py
    python benchmarks/bench_plugin.py --beads 40 90 --repeats 5
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np

_CONTEXTS = []


def _python_engine(x):
    from knotmm.dynamics.deterministic import Euler
    from knotmm.engine.simulation import Simulation

    sim = Simulation(x, integrator=Euler(1e-4), platform="CPU", threads=1)
    return lambda: sim.velocity(sim.positions)


def _plugin(x, threads, method="euler"):
    import openmm

    from knotmm.model.system import chain_system as build_system
    from knotmm.plugin import RPYIntegrator

    integ = RPYIntegrator(1e-5, method, threads=threads)
    ctx = openmm.Context(build_system(x), integ, openmm.Platform.getPlatformByName("CPU"),
                         {"Threads": "1"})
    ctx.setPositions(x)
    _CONTEXTS.append(ctx)  # the Context must live as long as the timer
    return integ


_CLOCK = time.perf_counter


def _time_calls(fn, calls):
    t0 = _CLOCK()
    for _ in range(calls):
        fn()
    return (_CLOCK() - t0) / calls


def _time_steps(integ, steps):
    t0 = _CLOCK()
    integ.step(steps)
    return (_CLOCK() - t0) / steps


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--beads", type=int, nargs="+", default=[40, 90, 240, 480, 1000])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--budget", type=float, default=0.15,
                        help="seconds per timing (sets the number of calls)")
    parser.add_argument("--clock", choices=["wall", "cpu"], default="wall",
                        help="wall: elapsed time; cpu: this process's CPU time (steadier on a "
                             "shared machine; meaningless for the two-thread column)")
    parser.add_argument("--run", type=float, default=5.0,
                        help="tau_d of the whole-run comparison (0: skip it)")
    args = parser.parse_args(argv)
    global _CLOCK
    _CLOCK = time.perf_counter if args.clock == "wall" else time.process_time

    from knotmm.plugin import available, load_error
    from knotmm.shapes import torus_knot

    if not available():
        raise SystemExit(load_error())
    engines = {}
    for n in args.beads:
        x = torus_knot(2, 3, n)
        engines[n] = {"python": _python_engine(x), "plugin": _plugin(x, 1)}
        if n >= 256:
            engines[n]["plugin2"] = _plugin(x, 2)
    # calibrate the number of calls per timing, and warm up (numba compile, OpenMM set-up)
    calls = {}
    for n, e in engines.items():
        for name, obj in e.items():
            once = (_time_calls(obj, 3) if name == "python" else _time_steps(obj, 3))
            calls[n, name] = max(3, int(args.budget / max(once, 1e-7)))
    samples = {key: [] for key in calls}
    for _ in range(args.repeats):
        for n, e in engines.items():
            for name, obj in e.items():
                k = calls[n, name]
                t = _time_calls(obj, k) if name == "python" else _time_steps(obj, k)
                samples[n, name].append(t)

    print(f"# cores: {os.cpu_count()}, load average: {os.getloadavg()[0]:.2f}; "
          f"medians of {args.repeats} interleaved repeats; {args.clock} clock; CPU platform, "
          f"1 OpenMM thread")
    print(f"{'N':>6} {'python [ms]':>12} {'plugin [ms]':>12} {'plugin 2 thr':>13} "
          f"{'python/plugin':>14} {'python/plugin2':>15}")
    for n in args.beads:
        py = statistics.median(samples[n, "python"]) * 1e3
        pl = statistics.median(samples[n, "plugin"]) * 1e3
        if (n, "plugin2") in samples:
            pl2 = statistics.median(samples[n, "plugin2"]) * 1e3
            extra = f"{pl2:13.4f} {py / pl:14.2f} {py / pl2:15.2f}"
        else:
            extra = f"{'-':>13} {py / pl:14.2f} {'-':>15}"
        print(f"{n:6d} {py:12.4f} {pl:12.4f} {extra}")
    if args.run > 0:
        print(f"\nwhole rk23 run of {args.run:g} tau_d ({args.clock} s; evaluations):")
        for n in args.beads:
            py_s, py_ev, pl_s, pl_ev = _whole_run(torus_knot(2, 3, n), args.run)
            print(f"{n:6d} python {py_s:8.3f} s ({py_ev} ev)   plugin {pl_s:8.3f} s ({pl_ev} ev)"
                  f"   ratio {py_s / pl_s:6.2f}")
    return samples


def _whole_run(x, duration):
    from knotmm.dynamics.deterministic import RK23
    from knotmm.engine.simulation import Simulation

    sim = Simulation(x, integrator=RK23(0.01), platform="CPU", threads=1)
    t0 = _CLOCK()
    sim.run(duration)
    py_s = _CLOCK() - t0
    integ = _plugin(x, 1, "rk23")
    integ.setStepSize(0.01)
    t0 = _CLOCK()
    integ.stepTo(duration)
    pl_s = _CLOCK() - t0
    return py_s, sim.n_evaluations, pl_s, integ.getNumForceEvaluations()


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
