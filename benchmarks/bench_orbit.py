"""Cost of ``knotmm orbit``: the orbit and 10 Floquet multipliers of T(2,3) against N.

Issue 14's target: N = 60, orbit and 10 multipliers within 15 minutes on 2 cores. For each N
a deterministic run of ``--duration`` tau_d is made once (not timed), then
``knotmm.orbit.orbit_of_run(run, modes=10)`` is timed ``--repeats`` times; the table gives
the median wall time, the process CPU time, the number of flow integrations (one period
each) and the wall time per integration::

    python benchmarks/bench_orbit.py                      # N = 40 60 90 120
    python benchmarks/bench_orbit.py --beads 60 --repeats 3
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path


def main() -> None:
    from knotmm.config import RunConfig
    from knotmm.orbit import orbit_of_run
    from knotmm.workflow import run

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--beads", type=int, nargs="+", default=[40, 60, 90, 120])
    parser.add_argument("--duration", type=float, default=120.0)
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--modes", type=int, default=10)
    args = parser.parse_args()
    print(f"{'N':>4} {'period':>8} {'flows':>6} {'wall s':>8} {'cpu s':>8} {'s/flow':>7} "
          f"{'|mu1|':>7}")
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.beads:
            run_dir = Path(tmp) / f"N{n}"
            cfg = RunConfig.from_dict({"knot": {"beads": n}, "run": {"duration": args.duration},
                                       "output": {"frame_interval": 0.25}})
            run(cfg, run_dir, progress=False)
            walls, cpus = [], []
            for k in range(args.repeats):
                w0, c0 = time.perf_counter(), time.process_time()
                s = orbit_of_run(run_dir, modes=args.modes, out=Path(tmp) / f"o{n}_{k}").summary
                walls.append(time.perf_counter() - w0)
                cpus.append(time.process_time() - c0)
            wall, cpu = statistics.median(walls), statistics.median(cpus)
            flows = s["flow_integrations"]
            print(f"{n:>4} {s['period']:>8.4f} {flows:>6} {wall:>8.1f} {cpu:>8.1f} "
                  f"{wall / flows:>7.3f} {s['floquet_moduli'][0]:>7.4f}", flush=True)


if __name__ == "__main__":
    main()
