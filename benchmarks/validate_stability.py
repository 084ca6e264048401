"""Validation: the stability limit of the fixed-step integrators on the study's chain.

For each fixed-step integrator, bisect the step size dt: a run is *stable* when a T(p,q)
chain (default T(2,3), N = 90, the study's parameters) simulated for ``--duration`` tau_d
(default 20) keeps every bond shorter than ``--max-bond`` d (default 1 d, against 0.6 d at
rest). The run stops at the first bond past the limit (``SimulationFault``), so unstable
steps are cheap. The result is the largest stable dt found and the smallest unstable one.

Run on demand (not part of the tests)::

    python benchmarks/validate_stability.py                 # heun, euler, midpoint at N = 90
    python benchmarks/validate_stability.py --beads 40 90 120 --duration 50
    python benchmarks/validate_stability.py --duration 500 --lo 0.02 --hi 0.05 --rel 0.02
    python benchmarks/validate_stability.py --quick         # a smoke run

The brackets are written as data (``benchmarks/results/validate_stability.json``, or
``--out``; see ``benchmarks/harness.py``).

Notes
-----
* Stability of an explicit method on the linearised dynamics ``dy/dt = -J y`` needs
  ``dt rho(J) <= beta`` with ``beta = 2`` (Euler, Heun, midpoint); rho changes as the chain
  reshapes, so the measured limit belongs to the trajectory of the given length.
* Near the limit an instability can grow slowly from round-off, and the chain's shape (so
  rho) changes during a run: a longer ``--duration`` usually lowers the limit, and when the
  run goes through a compact phase the outcome is no longer monotonic in dt (bisection then
  brackets one threshold among several). ``--check`` re-runs the bracket for 5x longer.
"""

from __future__ import annotations

import argparse
import time

import harness
import numpy as np

from knotmm.dynamics.registry import make
from knotmm.engine.simulation import Simulation
from knotmm.errors import SimulationFault
from knotmm.model.system import ChainModel
from knotmm.shapes import torus_knot


def is_stable(x0, name, dt, duration, max_bond, platform):
    """Run ``duration`` tau_d with fixed steps ``dt``; True if every bond stays < max_bond."""
    sim = Simulation(
        x0,
        ChainModel(),
        make(name, dt),
        platform=platform,
        max_bond_length=max_bond,
    )
    try:
        sim.run(duration)
    except SimulationFault:
        return False, sim.time
    return bool(sim.bond_lengths().max() < max_bond), sim.time


def bisect(x0, name, duration, max_bond, platform, lo=0.004, hi=0.2, rel=0.005, log=print):
    """Largest stable and smallest unstable dt, to relative precision ``rel``."""
    ok, _ = is_stable(x0, name, lo, duration, max_bond, platform)
    if not ok:
        raise RuntimeError(f"{name}: dt = {lo} is already unstable; lower --lo")
    ok, _ = is_stable(x0, name, hi, duration, max_bond, platform)
    if ok:
        raise RuntimeError(f"{name}: dt = {hi} is still stable; raise --hi")
    while hi / lo - 1 > rel:
        mid = np.sqrt(lo * hi)
        ok, reached = is_stable(x0, name, mid, duration, max_bond, platform)
        log(f"  {name:9s} dt = {mid:.5f}: {'stable' if ok else f'unstable at t = {reached:.2f}'}")
        if ok:
            lo = mid
        else:
            hi = mid
    return lo, hi


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--integrators", nargs="+", default=["heun", "euler", "midpoint"])
    parser.add_argument("--beads", nargs="+", type=int, default=[90])
    parser.add_argument("--p", type=int, default=2)
    parser.add_argument("--q", type=int, default=3)
    parser.add_argument("--duration", type=float, default=20.0, help="tau_d per trial run")
    parser.add_argument("--max-bond", type=float, default=1.0, help="stable: bonds below (d)")
    parser.add_argument("--platform", default="auto")
    parser.add_argument("--rel", type=float, default=0.005, help="relative bracket width")
    parser.add_argument("--lo", type=float, default=0.004, help="a stable dt (tau_d)")
    parser.add_argument("--hi", type=float, default=0.2, help="an unstable dt (tau_d)")
    parser.add_argument(
        "--check",
        action="store_true",
        help="re-run the stable end of each bracket for 5x the duration",
    )
    parser.add_argument("--quiet", action="store_true")
    parser.add_argument("--quick", action="store_true",
                        help="euler at N = 40, 2 tau_d, a coarse bracket (a smoke run); "
                             "nothing saved unless --out")
    parser.add_argument("--out", default=None,
                        help="result file (JSON); default benchmarks/results/"
                             "validate_stability.json; '-': do not save")
    args = parser.parse_args(argv)
    if args.quick:
        args.integrators, args.beads, args.duration, args.rel = ["euler"], [40], 2.0, 0.2
    info = harness.header()
    log = (lambda *a: None) if args.quiet else print

    rows = []
    for n in args.beads:
        x0 = torus_knot(args.p, args.q, n)
        for name in args.integrators:
            t0 = time.perf_counter()
            lo, hi = bisect(
                x0,
                name,
                args.duration,
                args.max_bond,
                args.platform,
                lo=args.lo,
                hi=args.hi,
                rel=args.rel,
                log=log,
            )
            long_ok = None
            if args.check:
                long_ok, _ = is_stable(
                    x0, name, lo, 5 * args.duration, args.max_bond, args.platform
                )
            rows.append((n, name, lo, hi, long_ok, time.perf_counter() - t0))

    print()
    print(
        f"Stability of fixed-step integrators: T({args.p},{args.q}), study parameters, "
        f"{args.duration:g} tau_d per trial, stable = bonds < {args.max_bond:g} d"
    )
    print(
        f"{'N':>5} {'integrator':>10} {'largest stable dt':>18} {'smallest unstable':>18}"
        f"{'  5x longer' if args.check else ''} {'wall (s)':>9}"
    )
    for n, name, lo, hi, long_ok, wall in rows:
        extra = f"  {'stable' if long_ok else 'UNSTABLE':>10}" if args.check else ""
        print(f"{n:>5} {name:>10} {lo:>18.5f} {hi:>18.5f}{extra} {wall:>9.1f}")
    results = {f"{n}/{name}": {"largest_stable": lo, "smallest_unstable": hi,
                               "five_times_longer_stable": long_ok, "wall": wall, "unit": "tau_d"}
               for n, name, lo, hi, long_ok, wall in rows}
    harness.save("validate_stability", args, results, machine_before=info)


if __name__ == "__main__":
    main()
