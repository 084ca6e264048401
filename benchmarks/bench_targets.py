"""The speed targets of issue 12, measured as ratios, back to back and interleaved.

Targets (section "Targets" of issue 12; ``benchmarks/README.md`` has the results):

``a`` whole ``knotmm run`` of T(2,3), N = 90, 400 tau_d against ``benchmarks/numba_chain.py``
      (the same model, fixed-step Heun, dt = 0.02) for 400 tau_d, both whole processes
      (interpreter start, imports and numba compilation counted). The numba program runs
      with a warm cache (compiled once before timing, ``NUMBA_CACHE_DIR`` in a temporary
      folder) and, as a second column, cold (a fresh cache folder each time). knotmm's own
      numba kernels are cached in its package. Target <= 0.8x, goal 0.5x.
``b`` ``knotmm run --duration 0.5`` against ``python -c "import openmm, numba, mdtraj"``.
      Target <= 1.5x.
``c`` ``knotmm run --duration 40`` with ``model.bending_stiffness = 5000`` against ``= 5``
      (N = 90, ``run.integrator = "auto"`` unless a ``--set`` says otherwise). Target <= 6x,
      goal 2x. A stiff run longer than ``--stiff-timeout`` is stopped; its cost is then
      extrapolated from the simulated time it reached (``observables.csv``) and reported as
      such, with the timeout as a lower bound. ``--stiff-reference rkc2`` adds the same stiff
      run with that integrator (what ``auto`` could pick).
``d`` cost of one force + mobility evaluation against N (T(2,3) templates) for the Python
      engine (``Simulation.velocity``; CPU platform, one thread), the compiled plugin
      (``RPYIntegrator("euler").step``: one evaluation and the position update) and the
      numba program, each split into its pieces: Python engine ``forces``
      (``Simulation.forces``: OpenMM round trip) and ``mobility`` (``rpy_velocities``);
      plugin ``no-force`` (the same step on a System without forces: the RPY loop, the update
      and OpenMM's fixed cost per force call) and ``forces`` = full - no-force; numba
      ``forces`` (bonded + O(N^2) steric loop) and ``mobility``. Positions do not change
      between calls (no neighbour-list rebuilds; a run's cost per evaluation is higher).

Every ``knotmm`` command gets the ``--set`` keys of each ``--variant`` (default: one variant
without keys), e.g. to compare the engines once ``run.engine`` exists::

    python benchmarks/bench_targets.py
    python benchmarks/bench_targets.py --targets a b --repeats 5
    python benchmarks/bench_targets.py --variant python:run.engine=python \\
        --variant plugin:run.engine=plugin --targets a b c
    python benchmarks/bench_targets.py --targets d --beads 40 90 240

Each figure is the median of ``--repeats`` repeats; within a repeat the commands alternate
(their order is reversed every other repeat), so slow phases of a shared machine hit all of
them alike. Wall time is the primary measure; the children's CPU time (user + system, from
``getrusage``) is printed beside it, since it is steadier on a loaded machine. ``--json``
writes every sample.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
NUMBA_CHAIN = HERE / "numba_chain.py"
IMPORTS = "import openmm, numba, mdtraj"


# -- subprocess timing ----------------------------------------------------------------------
def _knotmm_exe() -> list[str]:
    exe = shutil.which("knotmm") or str(Path(sys.executable).parent / "knotmm")
    return [exe]


def timed(cmd, env=None, timeout=None) -> dict:
    """Run ``cmd``; wall seconds, children's CPU seconds, return code, last output line."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env=env)
    try:
        out, _ = proc.communicate(timeout=timeout)
        rc = proc.returncode
    except subprocess.TimeoutExpired:
        wall = time.perf_counter() - t0
        proc.terminate()  # knotmm stops after the current step and keeps its files
        try:
            out, _ = proc.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            out, _ = proc.communicate()
        rc = "timeout"
    else:
        wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    lines = [ln for ln in (out or "").splitlines() if ln.strip()]
    return {"wall": wall, "cpu": cpu, "rc": rc, "last": lines[-1] if lines else ""}


def knotmm_run(workdir: Path, duration: float, sets, timeout=None) -> dict:
    out = workdir / "run"
    cmd = _knotmm_exe() + ["run", "--duration", f"{duration:g}", "--out", str(out),
                           "--overwrite", "--no-progress"]
    for key in sets:
        cmd += ["--set", key]
    result = timed(cmd, timeout=timeout)
    result["reached"] = _reached_time(out / "observables.csv")
    if result["rc"] not in (0, "timeout"):
        raise SystemExit(f"knotmm run failed ({' '.join(cmd)}):\n{result['last']}")
    return result


def _reached_time(path: Path) -> float:
    """Simulated time of the last row of a run's observables.csv (0 if none)."""
    try:
        with open(path) as fh:
            rows = list(csv.DictReader(fh))
        return float(rows[-1]["time"]) if rows else 0.0
    except (OSError, KeyError, ValueError):
        return 0.0


def numba_run(start: Path, duration: float, cache_dir: Path, params=()) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_dir))
    cmd = [sys.executable, str(NUMBA_CHAIN), "--start", str(start), "--duration",
           f"{duration:g}", "--dt", "0.02", *params]
    result = timed(cmd, env=env)
    if result["rc"] != 0:
        raise SystemExit(f"numba_chain failed:\n{result['last']}")
    return result


def _interleave(jobs: dict, repeats: int) -> dict:
    """Run each named job once per repeat, in an order reversed every other repeat."""
    samples = {name: [] for name in jobs}
    names = list(jobs)
    for r in range(repeats):
        for name in (names if r % 2 == 0 else names[::-1]):
            samples[name].append(jobs[name]())
            print(f"  [{r + 1}/{repeats}] {name}: {samples[name][-1]['wall']:.2f} s wall, "
                  f"{samples[name][-1]['cpu']:.2f} s cpu", flush=True)
    return samples


def _med(samples, key="wall") -> float:
    return statistics.median(s[key] for s in samples)


def _ratio_line(label, num, den, target=None) -> str:
    rw, rc = _med(num) / _med(den), _med(num, "cpu") / _med(den, "cpu")
    verdict = ""
    if target is not None:
        verdict = f"  target <= {target:g}x: {'met' if rw <= target else 'MISSED'}"
    return (f"{label}: {_med(num):.2f} / {_med(den):.2f} s wall = {rw:.2f}x "
            f"(cpu {_med(num, 'cpu'):.2f} / {_med(den, 'cpu'):.2f} s = {rc:.2f}x){verdict}")


# -- targets ---------------------------------------------------------------------------------
def target_a(work: Path, variants, repeats, duration=400.0) -> dict:
    from knotmm.shapes import torus_knot

    start = work / "start.npy"
    np.save(start, torus_knot(2, 3, 90))
    warm = work / "numba_cache_warm"
    numba_run(start, 0.0, warm)  # fills the cache; not timed
    cold_count = [0]

    def cold():
        cold_count[0] += 1
        return numba_run(start, duration, work / f"numba_cache_cold{cold_count[0]}")

    jobs = {f"knotmm[{name}]": (lambda s=sets: knotmm_run(work, duration, s))
            for name, sets in variants}
    jobs["numba (warm cache)"] = lambda: numba_run(start, duration, warm)
    jobs["numba (cold cache)"] = cold
    print(f"\n(a) T(2,3), N = 90, {duration:g} tau_d: knotmm run vs numba_chain (heun 0.02)")
    samples = _interleave(jobs, repeats)
    for name, _ in variants:
        k = samples[f"knotmm[{name}]"]
        print("  " + k[-1]["last"])
        for ref in ("numba (warm cache)", "numba (cold cache)"):
            print("  " + _ratio_line(f"knotmm[{name}] / {ref}", k, samples[ref], 0.8))
    print("  numba: " + samples["numba (warm cache)"][-1]["last"])
    return samples


def target_b(work: Path, variants, repeats) -> dict:
    jobs = {f"knotmm[{name}]": (lambda s=sets: knotmm_run(work, 0.5, s))
            for name, sets in variants}
    jobs["imports"] = lambda: timed([sys.executable, "-c", IMPORTS])
    print(f"\n(b) knotmm run --duration 0.5 vs python -c \"{IMPORTS}\"")
    samples = _interleave(jobs, repeats)
    for name, _ in variants:
        print("  " + _ratio_line(f"knotmm[{name}] / imports", samples[f"knotmm[{name}]"],
                                 samples["imports"], 1.5))
    return samples


def target_c(work: Path, variants, repeats, timeout, references, duration=40.0) -> dict:
    jobs = {}
    for name, sets in variants:
        jobs[f"A=5[{name}]"] = (
            lambda s=sets: knotmm_run(work, duration, s + ["model.bending_stiffness=5"]))
        jobs[f"A=5000[{name}]"] = (
            lambda s=sets: knotmm_run(work, duration, s + ["model.bending_stiffness=5000"],
                                      timeout=timeout))
        for method in references:
            jobs[f"A=5000 {method}[{name}]"] = (
                lambda s=sets, m=method: knotmm_run(
                    work, duration,
                    s + ["model.bending_stiffness=5000", f'run.integrator="{m}"'],
                    timeout=timeout))
    print(f"\n(c) N = 90, {duration:g} tau_d: bending_stiffness 5000 vs 5 "
          f"(stiff runs stopped after {timeout:g} s)")
    samples = _interleave(jobs, repeats)
    for name, _ in variants:
        soft = samples[f"A=5[{name}]"]
        for key in [f"A=5000[{name}]"] + [f"A=5000 {m}[{name}]" for m in references]:
            stiff = samples[key]
            for s in stiff:
                s["timed_out"] = s["rc"] == "timeout"
                if s["timed_out"] and s["reached"] > 0:
                    # the cost grows linearly in simulated time (steps set by stability)
                    # after start-up; the whole soft run stands in for the start-up, so
                    # this estimate is low rather than high
                    s["extrapolated"] = _med(soft) + (s["wall"] - _med(soft)) * duration / s[
                        "reached"]
            if any(s["timed_out"] for s in stiff):
                reached = statistics.median(s["reached"] for s in stiff)
                est = statistics.median(s.get("extrapolated", s["wall"]) for s in stiff)
                verdict = "met (extrapolated)" if est / _med(soft) <= 6 else "MISSED"
                print(f"  {key} / A=5[{name}]: stopped after {timeout:g} s at t = {reached:g} "
                      f"of {duration:g} tau_d (median): ratio > {timeout / _med(soft):.1f}x; "
                      f"extrapolated {est:.0f} s = {est / _med(soft):.1f}x  target <= 6x: "
                      f"{verdict}")
            else:
                print("  " + _ratio_line(f"{key} / A=5[{name}]", stiff, soft, 6.0))
                print("    " + stiff[-1]["last"])
        print("    soft: " + soft[-1]["last"])
    return samples


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--targets", nargs="+", default=["a", "b", "c", "d"],
                        choices=["a", "b", "c", "d"])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--set", dest="sets", action="append", default=[],
                        metavar="TABLE.KEY=VALUE",
                        help="--set for every knotmm command (of the default variant)")
    parser.add_argument("--variant", action="append", default=[], metavar="NAME:K=V[;K=V]",
                        help="a named set of --set keys; repeatable; replaces the default")
    parser.add_argument("--duration", type=float, default=400.0, help="(a): tau_d")
    parser.add_argument("--stiff-timeout", type=float, default=120.0,
                        help="(c): seconds after which a stiff run is stopped")
    parser.add_argument("--stiff-reference", nargs="*", default=["rkc2"],
                        help="(c): integrators to run the stiff case with as well")
    parser.add_argument("--beads", type=int, nargs="+",
                        default=[40, 90, 240, 480, 1000, 2000], help="(d): N")
    parser.add_argument("--budget", type=float, default=0.2,
                        help="(d): seconds per timing (sets the number of calls)")
    parser.add_argument("--json", help="write all samples here")
    args = parser.parse_args(argv)

    variants = [("default", list(args.sets))]
    if args.variant:
        variants = []
        for text in args.variant:
            name, _, keys = text.partition(":")
            variants.append((name, list(args.sets) + [k for k in keys.split(";") if k]))
    header = {"date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
              "cpus": os.cpu_count(), "load_before": os.getloadavg(), "variants": variants}
    print(f"# {header['date']}; {header['cpus']} CPUs; load average "
          f"{' '.join(f'{v:.2f}' for v in header['load_before'])}; medians of "
          f"{args.repeats}; variants: {variants}", flush=True)
    results = {"header": header}
    work = Path(tempfile.mkdtemp(prefix="knotmm-bench-"))
    try:
        if "a" in args.targets:
            results["a"] = target_a(work, variants, args.repeats, args.duration)
        if "b" in args.targets:
            results["b"] = target_b(work, variants, args.repeats)
        if "c" in args.targets:
            results["c"] = target_c(work, variants, args.repeats, args.stiff_timeout,
                                    args.stiff_reference)
        if "d" in args.targets:
            from bench_evaluations import evaluation_table  # a sibling script (sys.path)

            results["d"] = evaluation_table(args.beads, args.repeats, args.budget)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    header["load_after"] = os.getloadavg()
    print(f"# load average after: {' '.join(f'{v:.2f}' for v in header['load_after'])}")
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1, default=str))
    return results


if __name__ == "__main__":
    sys.path.insert(0, str(HERE))
    main()
