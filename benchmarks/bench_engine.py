"""Cost of the engine: one velocity evaluation split into its parts, and a full default run.

For each N (a T(2,3) template), times

* ``forces``   : ``Simulation.forces`` (OpenMM: set positions, compute, copy out)
* ``mobility`` : ``rpy_velocities`` (the numba RPY loop) on those forces
* ``velocity`` : ``Simulation.velocity`` (both, plus knotmm's Python glue)
* ``overhead`` : velocity - forces - mobility

as medians over ``--repeats`` timings of ``--inner`` calls each, on each platform asked for.
Then the ratio full evaluation / mobility alone at N = 120, and the wall time of
``knotmm run --duration 500`` (default T(2,3), N = 90; a subprocess, start-up included),
median of ``--runs``, also with the knot-type checks off and on the Reference platform, and
the start-up cost alone (a run of one frame).

Targets from the issue: a full evaluation at N = 120 at most 2x the mobility loop alone;
the 500 tau_d run under 10 s on 2 cores.

Run on demand (not part of the tests)::

    python benchmarks/bench_engine.py
    python benchmarks/bench_engine.py --beads 90 120 --platforms CPU --runs 1

Timings are wall clock; on a shared machine they are noisy, so medians are reported.
"""

from __future__ import annotations

import argparse
import os
import platform as _platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

from knotmm.dynamics.mobility import rpy_velocities
from knotmm.engine.simulation import Simulation
from knotmm.knots.writhe import writhe
from knotmm.shapes import torus_knot


def _median_time(fn, repeats, inner):
    fn()  # warm up (numba compile, OpenMM kernels)
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(inner):
            fn()
        samples.append((time.perf_counter() - t0) / inner)
    return statistics.median(samples)


def evaluation_costs(n, platform, repeats, inner, threads=1):
    """Median seconds per call of forces, mobility and velocity for a T(2,3) of n beads."""
    x = torus_knot(2, 3, n)
    sim = Simulation(x, platform=platform, threads=threads)
    f = sim.forces(x)
    t_forces = _median_time(lambda: sim.forces(x), repeats, inner)
    t_mobility = _median_time(lambda: rpy_velocities(x, f), repeats, inner)
    t_velocity = _median_time(lambda: sim.velocity(x), repeats, inner)
    return {
        "platform": sim.platform_name,
        "forces": t_forces,
        "mobility": t_mobility,
        "velocity": t_velocity,
        "overhead": t_velocity - t_forces - t_mobility,
    }


def cli_run_time(duration, runs, extra=()):
    """Median wall time (s) of `knotmm run --duration D` in a subprocess, and its summary."""
    exe = shutil.which("knotmm")
    cmd = [exe] if exe else [sys.executable, "-m", "knotmm.cli.main"]
    times, summary = [], ""
    for _ in range(runs):
        out = tempfile.mkdtemp(prefix="knotmm-bench-")
        try:
            t0 = time.perf_counter()
            proc = subprocess.run(
                [*cmd, "run", "--duration", str(duration), "--out", out, "--no-progress", *extra],
                capture_output=True,
                text=True,
                check=False,
            )
            times.append(time.perf_counter() - t0)
            if proc.returncode != 0:
                raise RuntimeError(f"knotmm run failed: {proc.stderr.strip()}")
            summary = proc.stdout.strip()
        finally:
            shutil.rmtree(out, ignore_errors=True)
    return statistics.median(times), times, summary


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--beads", nargs="+", type=int, default=[40, 90, 120, 240, 480])
    parser.add_argument(
        "--platforms",
        nargs="+",
        default=["auto", "Reference"],
        help="OpenMM platforms to time (auto = what a run uses)",
    )
    parser.add_argument("--repeats", type=int, default=7, help="timings per median")
    parser.add_argument(
        "--inner", type=int, default=0, help="calls per timing (default: about 20 ms worth)"
    )
    parser.add_argument("--threads", type=int, default=1, help="CPU platform threads")
    parser.add_argument(
        "--mobility-threads", type=int, default=2, help="threads of the threaded RPY loop"
    )
    parser.add_argument("--duration", type=float, default=500.0, help="tau_d of the CLI run")
    parser.add_argument("--runs", type=int, default=3, help="CLI runs (median); 0 skips")
    parser.add_argument(
        "--skip-variants",
        action="store_true",
        help="time only the default CLI run (not the variants)",
    )
    parser.add_argument(
        "--frame-duration",
        type=float,
        default=0.5,
        help="tau_d of the start-up run (one frame interval)",
    )
    args = parser.parse_args(argv)

    print(
        f"knotmm engine benchmark: {_platform.processor() or _platform.machine()}, "
        f"{os.cpu_count()} CPUs visible, load average {os.getloadavg()[0]:.2f} "
        f"(shared machines give noisy timings: medians of {args.repeats})"
    )
    print()
    header = (
        f"{'N':>5} {'platform':>9} {'forces':>10} {'mobility':>10} {'overhead':>10} "
        f"{'velocity':>10} {'vel/mob':>8}"
    )
    print("one velocity evaluation, microseconds per call")
    print(header)
    results = {}
    for plat in args.platforms:
        for n in args.beads:
            inner = args.inner or max(5, int(20000 / max(n, 1) ** 1.2))
            c = evaluation_costs(n, plat, args.repeats, inner, args.threads)
            results[(plat, n)] = c
            print(
                f"{n:>5} {c['platform']:>9} {c['forces'] * 1e6:>10.1f} "
                f"{c['mobility'] * 1e6:>10.1f} {c['overhead'] * 1e6:>10.1f} "
                f"{c['velocity'] * 1e6:>10.1f} {c['velocity'] / c['mobility']:>8.2f}",
                flush=True,
            )
    print()
    print(f"RPY pair loop on {args.mobility_threads} threads (run.mobility_threads), "
          "microseconds per call")
    for n in args.beads:
        x = torus_knot(2, 3, n)
        f = np.random.default_rng(n).normal(size=x.shape)
        inner = args.inner or max(5, int(20000 / max(n, 1) ** 1.2))
        one = _median_time(lambda x=x, f=f: rpy_velocities(x, f), args.repeats, inner)
        many = _median_time(
            lambda x=x, f=f: rpy_velocities(x, f, threads=args.mobility_threads),
            args.repeats,
            inner,
        )
        print(f"{n:>5} {one * 1e6:>10.1f} -> {many * 1e6:>10.1f}  ({one / many:.2f}x)")
    print()
    print("writhe (numba double sum, used by analysis and the templates), ms per call")
    for n in args.beads:
        x = torus_knot(2, 3, n)
        inner = max(3, int(2e6 / n**2))
        print(f"{n:>5} {_median_time(lambda x=x: writhe(x), args.repeats, inner) * 1e3:>10.3f}")
    print()
    for plat in args.platforms:
        if (plat, 120) in results:
            c = results[(plat, 120)]
            ratio = c["velocity"] / c["mobility"]
            print(
                f"N = 120, {c['platform']}: full evaluation / mobility alone = {ratio:.2f} "
                f"(target <= 2)"
            )
    if args.runs > 0:
        print()
        med, times, summary = cli_run_time(args.duration, args.runs)
        print(
            f"knotmm run --duration {args.duration:g} (default T(2,3), N = 90): median "
            f"{med:.2f} s over {args.runs} runs "
            f"({', '.join(f'{t:.2f}' for t in times)} s; target < 10 s)"
        )
        print(f"  last summary: {summary}")
        if not args.skip_variants:
            variants = [
                ("knot-type checks off", ["--set", "run.topology_check_interval=0"]),
                (
                    "knot-type checks off, Reference platform",
                    ["--set", "run.topology_check_interval=0", "--set", "run.platform=Reference"],
                ),
            ]
            for label, extra in variants:
                med, times, summary = cli_run_time(args.duration, args.runs, extra)
                print(f"  {label}: median {med:.2f} s ({', '.join(f'{t:.2f}' for t in times)} s)")
        start, _, _ = cli_run_time(args.frame_duration, args.runs)
        print(
            f"  start-up alone (knotmm run --duration {args.frame_duration:g}): "
            f"median {start:.2f} s"
        )
    return 0


if __name__ == "__main__":
    np.seterr(all="raise")
    sys.exit(main())
