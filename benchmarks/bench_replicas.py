"""K replicas in one ``knotmm run`` against K single runs one after another.

Both sides are whole commands (``python -m knotmm.cli run``, subprocesses, the plugin engine;
T(2,3) at the defaults), so each side pays what a user pays: start-up, template, files. The
two sides alternate ``--repeats`` times so that the machine's load hits both alike; the
report gives the median wall time of each side and the median of the per-repeat ratios.
Issue 21's targets: at most 0.4x at Pe = inf (goal 0.2x) and 0.6x at Pe = 2, for K = 8,
N = 90, 40 tau_d:

    python benchmarks/bench_replicas.py --replicas 8 --beads 90 --duration 40 --repeats 3
    python benchmarks/bench_replicas.py --replicas 8 --beads 90 --duration 40 --repeats 3 \
        --peclet 2
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def _command(out: Path, args, extra: list[str]) -> list[str]:
    cmd = [sys.executable, "-m", "knotmm.cli", "run", "--out", str(out), "--overwrite",
           "--no-progress", "-q", "--duration", str(args.duration), "--beads", str(args.beads)]
    if args.peclet is not None:
        cmd += ["--set", f"run.peclet={args.peclet}"]
    return cmd + extra


def _timed(cmd: list[str]) -> float:
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        sys.exit(f"failed ({proc.returncode}): {' '.join(cmd)}\n{proc.stderr}")
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--replicas", type=int, default=8)
    parser.add_argument("--beads", type=int, default=90)
    parser.add_argument("--duration", type=float, default=40.0)
    parser.add_argument("--peclet", type=float, default=None)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    singles, sets, ratios = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        from knotmm.replicas import replica_seeds

        seeds = replica_seeds(1, args.replicas)
        for r in range(args.repeats):
            t_single = sum(_timed(_command(work / f"single_{k}", args,
                                           ["--set", f"run.seed={s}"]))
                           for k, s in enumerate(seeds))
            t_set = _timed(_command(work / "set", args,
                                    ["--set", f"run.replicas={args.replicas}"]))
            singles.append(t_single)
            sets.append(t_set)
            ratios.append(t_set / t_single)
            print(f"repeat {r}: {args.replicas} single runs {t_single:.2f} s, one run of "
                  f"{args.replicas} replicas {t_set:.2f} s, ratio {t_set / t_single:.3f}")
    print(f"median: single runs {statistics.median(singles):.2f} s, replicas "
          f"{statistics.median(sets):.2f} s, ratio {statistics.median(ratios):.3f} "
          f"(K = {args.replicas}, N = {args.beads}, {args.duration:g} tau_d, Pe = "
          f"{args.peclet if args.peclet is not None else 'inf'})")


if __name__ == "__main__":
    main()
