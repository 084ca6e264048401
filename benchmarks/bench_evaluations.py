"""Cost of one force + mobility evaluation against N, and where it goes (issue 12, target d).

For T(2,3) templates of N beads, median microseconds per call of

* Python engine (CPU platform, one thread): ``velocity`` = ``Simulation.velocity``; its
  pieces ``forces`` = ``Simulation.forces`` (set positions, OpenMM computes, copy out) and
  ``mobility`` = ``rpy_velocities`` (knotmm's numba RPY loop, all N^2 pairs, vectorised);
  ``rest`` = velocity - forces - mobility (Python glue);
* plugin (``knotmm.plugin.RPYIntegrator("euler")`` bound to the same System on the CPU
  platform, one thread): ``step`` = one Euler step (forces asked for in C++, the C++ RPY
  loop, the position update); ``no-force`` = the same step on a System of N particles
  without forces (RPY loop + update + OpenMM's fixed cost per force call);
  ``forces`` = step - no-force;
* numba program (``benchmarks/numba_chain.py``): ``velocity``; ``forces`` (bonded O(N) +
  steric O(N^2) half loop, no neighbour list; ``steric`` alone is also shown) and
  ``mobility`` (O(N^2) half loop, scalar).

Positions stay the same from call to call (the plugin's steps of 1e-5 tau_d move the beads
by about 1e-4 d in all), so OpenMM rebuilds no neighbour list; a run's cost per evaluation is
somewhat higher. Within a repeat all sizes and engines are interleaved; medians over repeats.
Run on its own or through ``bench_targets.py --targets d``::

    python benchmarks/bench_evaluations.py --beads 40 90 240 --repeats 5
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

_KEEP = []  # Contexts must outlive their timers


def _numba_chain():
    if "numba_chain" not in sys.modules:
        spec = importlib.util.spec_from_file_location(
            "numba_chain", Path(__file__).resolve().parent / "numba_chain.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules["numba_chain"] = module  # numba's cache looks the module up by name
        spec.loader.exec_module(module)
    return sys.modules["numba_chain"]


def _python_timers(x) -> dict:
    from knotmm.dynamics.deterministic import Euler
    from knotmm.dynamics.mobility import rpy_velocities
    from knotmm.engine.simulation import Simulation

    sim = Simulation(x, integrator=Euler(1e-4), platform="CPU", threads=1)
    f = sim.forces(x)
    out = np.empty_like(x)
    return {
        "velocity": lambda: sim.velocity(x),
        "forces": lambda: sim.forces(x),
        "mobility": lambda: rpy_velocities(x, f, out=out),
    }


def _plugin_step(system, x):
    import openmm

    from knotmm.plugin import RPYIntegrator

    integ = RPYIntegrator(1e-5, "euler", threads=1)
    ctx = openmm.Context(system, integ, openmm.Platform.getPlatformByName("CPU"),
                         {"Threads": "1"})
    ctx.setPositions(x)
    _KEEP.append(ctx)
    return lambda: integ.step(1)


def _plugin_timers(x) -> dict:
    import openmm

    from knotmm.model.system import chain_system

    empty = openmm.System()
    for _ in range(len(x)):
        empty.addParticle(1.0)
    return {"step": _plugin_step(chain_system(x), x), "no-force": _plugin_step(empty, x)}


def _numba_timers(x) -> dict:
    nc = _numba_chain()
    p = nc.parameters()
    f = np.empty_like(x)
    v = np.empty_like(x)
    nc.forces(x, p, f)
    return {
        "velocity": lambda: nc.velocity(x, p, f, v),
        "forces": lambda: nc.forces(x, p, f),
        "steric": lambda: nc.steric_forces(x, p, f),
        "mobility": lambda: nc.mobility(x, f, v),
    }


def _per_call(fn, calls) -> float:
    t0 = time.perf_counter()
    for _ in range(calls):
        fn()
    return (time.perf_counter() - t0) / calls


def evaluation_table(beads, repeats=3, budget=0.2, plugin=True) -> dict:
    """Median seconds per call of every timer, by N; prints the table. Returns the samples."""
    from knotmm.shapes import torus_knot

    if plugin:
        from knotmm.plugin import available, load_error

        if not available():
            print(f"  plugin not measured: {load_error()}")
            plugin = False
    timers = {}
    for n in beads:
        x = torus_knot(2, 3, n)
        groups = {"python": _python_timers(x), "numba": _numba_timers(x)}
        if plugin:
            groups["plugin"] = _plugin_timers(x)
        for engine, fns in groups.items():
            for piece, fn in fns.items():
                timers[n, engine, piece] = fn
    calls = {}
    for key, fn in timers.items():  # warm up (compilation, OpenMM set-up) and calibrate
        fn()
        calls[key] = max(2, int(budget / max(_per_call(fn, 2), 1e-7)))
    samples = {key: [] for key in timers}
    for _ in range(repeats):
        for key, fn in timers.items():
            samples[key].append(_per_call(fn, calls[key]))
    med = {key: statistics.median(v) * 1e6 for key, v in samples.items()}
    print(f"\n(d) microseconds per evaluation (medians of {repeats}; CPU platform, one thread; "
          f"load average {os.getloadavg()[0]:.2f})")
    print(f"{'N':>5} | {'python':>8} {'forces':>8} {'mobil.':>8} {'rest':>6} | "
          f"{'plugin':>8} {'forces':>8} {'no-force':>8} | {'numba':>8} {'forces':>8} "
          f"{'steric':>8} {'mobil.':>8} | {'py/pl':>6} {'py/nb':>6} {'pl/nb':>6}")
    for n in beads:
        py = [med[n, "python", k] for k in ("velocity", "forces", "mobility")]
        nb = [med[n, "numba", k] for k in ("velocity", "forces", "steric", "mobility")]
        if plugin:
            step, noforce = med[n, "plugin", "step"], med[n, "plugin", "no-force"]
            pl = f"{step:8.1f} {step - noforce:8.1f} {noforce:8.1f}"
            ratios = f"{py[0] / step:6.2f} {py[0] / nb[0]:6.2f} {step / nb[0]:6.2f}"
        else:
            pl = f"{'-':>8} {'-':>8} {'-':>8}"
            ratios = f"{'-':>6} {py[0] / nb[0]:6.2f} {'-':>6}"
        print(f"{n:5d} | {py[0]:8.1f} {py[1]:8.1f} {py[2]:8.1f} {py[0] - py[1] - py[2]:6.1f} | "
              f"{pl} | {nb[0]:8.1f} {nb[1]:8.1f} {nb[2]:8.1f} {nb[3]:8.1f} | {ratios}")
    return {f"{n}/{engine}/{piece}": v for (n, engine, piece), v in samples.items()}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--beads", type=int, nargs="+", default=[40, 90, 240, 480, 1000, 2000])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--budget", type=float, default=0.2,
                        help="seconds per timing (sets the number of calls)")
    parser.add_argument("--no-plugin", action="store_true")
    args = parser.parse_args(argv)
    evaluation_table(args.beads, args.repeats, args.budget, plugin=not args.no_plugin)


if __name__ == "__main__":
    main()
