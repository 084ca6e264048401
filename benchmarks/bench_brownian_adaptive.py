"""ito_heun_adaptive against the fixed-step Brownian integrators: survival and wall time.

Each case is a whole ``knotmm run`` (the plugin engine; T(2,3), gravity as given), one
subprocess per run, interleaved by seed so that the machine's load hits every integrator
alike. For each integrator: how many runs finished, the median wall time, steps and
rejections, and the wall-time ratio to the reference integrator over the runs that both
finished. Example (issue 20's target, Pe = 1, N = 90, 30 tau_d, three seeds):

    python benchmarks/bench_brownian_adaptive.py --peclet 1 --beads 90 --duration 30 \
        --seeds 1 2 3 --integrators ito_heun_adaptive ito_heun:0.002 leimkuhler_matthews:0.01
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from knotmm.config import read_toml


def one_run(work: Path, spec: str, seed: int, args) -> dict:
    name, _, step = spec.partition(":")
    out = work / f"{name}_{step or 'auto'}_{seed}"
    cmd = [sys.executable, "-m", "knotmm.cli", "run", "--out", str(out), "--overwrite",
           "--no-progress", "--duration", str(args.duration), "--beads", str(args.beads),
           "--set", f"run.peclet={args.peclet}", "--set", f"run.seed={seed}",
           "--set", f"model.gravity={args.gravity}", "--set", f"run.integrator={name}",
           "--set", f"model.segment_repulsion={'true' if args.segments else 'false'}"]
    if step:
        cmd += ["--set", f"run.timestep={step}"]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    facts = {}
    if (out / "run.toml").is_file():
        facts = read_toml(out / "run.toml").get("knotmm", {})
    return dict(spec=spec, seed=seed, wall=wall, ok=proc.returncode == 0,
                steps=facts.get("steps"), rejected=facts.get("rejected_steps"),
                time=facts.get("time_reached"),
                message=proc.stderr.strip().splitlines()[-1][:160] if proc.returncode else "")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--peclet", type=float, default=1.0)
    parser.add_argument("--beads", type=int, default=90)
    parser.add_argument("--gravity", type=float, default=1.0)
    parser.add_argument("--duration", type=float, default=30.0)
    parser.add_argument("--segments", action="store_true", help="segment repulsion on")
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    parser.add_argument("--integrators", nargs="+",
                        default=["ito_heun_adaptive", "ito_heun:0.002"],
                        help="NAME or NAME:STEP; the first is compared with the others")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        rows = [one_run(Path(tmp), spec, seed, args)
                for seed in args.seeds for spec in args.integrators]
    print(f"Pe = {args.peclet:g}, N = {args.beads}, gravity {args.gravity:g}, "
          f"{args.duration:g} tau_d, segment repulsion {'on' if args.segments else 'off'}")
    first = args.integrators[0]
    for spec in args.integrators:
        mine = [r for r in rows if r["spec"] == spec]
        done = [r for r in mine if r["ok"]]
        line = f"  {spec:28s} finished {len(done)}/{len(mine)}"
        if done:
            line += (f", wall {statistics.median(r['wall'] for r in done):.2f} s (median), "
                     f"steps {statistics.median(r['steps'] or 0 for r in done):.0f}, "
                     f"rejected {statistics.median(r['rejected'] or 0 for r in done):.0f}")
        if spec != first:
            pairs = [(a["wall"], b["wall"]) for a in rows for b in mine
                     if a["spec"] == first and a["seed"] == b["seed"] and a["ok"] and b["ok"]]
            if pairs:
                ratios = [a / b for a, b in pairs]
                line += (f"; {first} / this: {statistics.median(ratios):.2f} "
                         f"(median of {len(pairs)})")
        print(line)
        for r in mine:
            if not r["ok"]:
                print(f"    seed {r['seed']}: {r['message']}")


if __name__ == "__main__":
    main()
