"""Validation: the adaptive Brownian default against a small fixed step (swirl, speed).

Issue 20 asks that at Pe = 10 and 50 the swirl period and the sedimentation speed of the
defaults (``run.integrator = "auto"``, i.e. ``ito_heun_adaptive``) equal those of
``ito_heun`` at dt = 0.001 tau_d within the replicas' standard error. For every Peclet
number and integrator this script makes one ``knotmm run`` of K replicas (``run.replicas``,
the same base seed for both integrators, so replica k of each has the same start), then
``knotmm analyze`` on a fixed window, and compares the replica means of ``tau_swirl`` and
``sedimentation_velocity``: the difference, its standard error (both sides' standard errors
in quadrature) and the difference in units of that error. Wall times are whole commands.

T(2,3) at N = 60 (the flat torus and its swirl persist over 60 tau_d at Pe >= 10 at this N:
``examples/peclet_persistence``), the study's model (no segment repulsion), gravity 1:

    python benchmarks/validate_brownian_observables.py --peclet 10 50 --replicas 8 \
        --duration 60 --window 10 60
    python benchmarks/validate_brownian_observables.py --quick      # a smoke run

Each run directory is kept under ``--work`` (default: a temporary directory). The
comparisons are written as data (``benchmarks/results/validate_brownian_observables.json``,
or ``--out``; see ``benchmarks/harness.py``).
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import harness


def run_set(work: Path, pe: float, spec: str, args) -> dict:
    """One replicated run and its analysis; the replica means and errors, and the wall time."""
    spec_step, _, tolerance = spec.partition("/")
    name, _, step = spec_step.partition(":")
    out = work / (f"pe{pe:g}_{name}_{step or 'auto'}" + (f"_tol{tolerance}" if tolerance else "")
                  + f"_seed{args.seed}")
    cmd = [sys.executable, "-m", "knotmm.cli", "run", "--out", str(out), "--overwrite",
           "--no-progress", "--duration", str(args.duration), "--beads", str(args.beads),
           "--set", f"run.peclet={pe}", "--set", f"run.seed={args.seed}",
           "--set", f"run.replicas={args.replicas}", "--set", f"run.integrator={name}",
           "--set", f"knot.perturbation={args.perturbation}",
           "--set", f"output.frame_interval={args.frame_interval}",
           "--set", "model.segment_repulsion=false"]
    if step:
        cmd += ["--set", f"run.timestep={step}"]
    if tolerance:
        cmd += ["--set", f"run.tolerance={tolerance}"]
    t0 = time.perf_counter()
    if args.reuse and (out / "replicas.json").is_file():
        proc = subprocess.CompletedProcess(cmd, 0)  # analysed before: read it again
    else:
        proc = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        return dict(spec=spec, pe=pe, ok=False, wall=wall,
                    message=(proc.stderr.strip().splitlines() or ["?"])[-1][:200])
    subprocess.run([sys.executable, "-m", "knotmm.cli", "analyze", str(out), "--no-plots",
                    "--knot-samples", "0", "--from", str(args.window[0]),
                    "--to", str(args.window[1])], capture_output=True, text=True, check=True)
    points = json.loads((out / "replicas.json").read_text())["points"]
    stats = next(iter(points.values()))["statistics"]
    row = dict(spec=spec, pe=pe, ok=True, wall=wall)
    for key in ("tau_swirl", "sedimentation_velocity", "swirl_detected"):
        s = stats.get(key, {})
        row[key] = (s.get("mean"), s.get("std_error"), s.get("n"), s.get("values"))
    return row


def compare(a: dict, b: dict, key: str) -> str:
    ma, ea, na, _ = a[key]
    mb, eb, nb, _ = b[key]
    if None in (ma, mb, ea, eb):
        return f"{key}: not measured (n = {na} / {nb})"
    err = math.hypot(ea, eb)
    z = (ma - mb) / err if err > 0 else float("inf")
    return (f"{key}: {ma:.4f} +- {ea:.4f} (n = {na}) vs {mb:.4f} +- {eb:.4f} (n = {nb}); "
            f"difference {ma - mb:+.4f} +- {err:.4f} = {z:+.2f} standard errors")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--peclet", type=float, nargs="+", default=[10.0, 50.0])
    parser.add_argument("--beads", type=int, default=60)
    parser.add_argument("--duration", type=float, default=60.0)
    parser.add_argument("--window", type=float, nargs=2, default=[10.0, 60.0],
                        metavar=("T0", "T1"), help="analysis window, tau_d")
    parser.add_argument("--replicas", type=int, default=8)
    parser.add_argument("--frame-interval", type=float, default=0.25, help="tau_d")
    parser.add_argument("--seed", type=int, default=2020)
    parser.add_argument("--perturbation", type=float, default=0.01)
    parser.add_argument("--integrators", nargs=2, default=["auto", "ito_heun:0.001"],
                        help="NAME, NAME:STEP or NAME/TOLERANCE (d); the first is compared "
                             "with the second")
    parser.add_argument("--work", type=Path, help="keep the run directories here")
    parser.add_argument("--reuse", action="store_true",
                        help="a set already run and analysed in --work is not run again "
                             "(its wall time is then not measured)")
    parser.add_argument("--quick", action="store_true",
                        help="Pe = 10, 2 replicas of N = 40 for 3 tau_d (a smoke run); "
                             "nothing saved unless --out")
    parser.add_argument("--out", default=None,
                        help="result file (JSON); default benchmarks/results/"
                             "validate_brownian_observables.json; '-': do not save")
    args = parser.parse_args(argv)
    if args.quick:
        args.peclet, args.beads, args.replicas = [10.0], 40, 2
        args.duration, args.window, args.frame_interval = 3.0, [1.0, 3.0], 0.1
    info = harness.header()
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        work = args.work or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        for pe in args.peclet:
            rows = [run_set(work, pe, spec, args) for spec in args.integrators]
            results[f"{pe:g}"] = rows
            for row in rows:
                state = "finished" if row["ok"] else f"FAILED: {row['message']}"
                print(f"Pe = {pe:g}, {row['spec']}: {args.replicas} replicas, wall "
                      f"{row['wall']:.1f} s, {state}", flush=True)
            if all(r["ok"] for r in rows):
                for key in ("tau_swirl", "sedimentation_velocity"):
                    print(f"  Pe = {pe:g}, " + compare(rows[0], rows[1], key), flush=True)
                det = [r["swirl_detected"][3] for r in rows]
                print(f"  swirl detected per replica: {det[0]} / {det[1]}", flush=True)
    harness.save("validate_brownian_observables", args, results, machine_before=info)


if __name__ == "__main__":
    main()
