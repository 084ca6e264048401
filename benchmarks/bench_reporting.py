"""What one output frame costs in a plugin-engine run (T(2,3), N = 90, CPU platform).

Per call, median of ``--calls`` calls after a short run (each line: the way knotmm does it
now, and the way it did it before, where that differs):

* ``energies``  : ``Simulation.energies()`` (plugin engine: one
  ``RPYIntegrator.getGroupEnergies`` call) against ``Simulation.energies(positions)`` (a
  ``setPositions`` and one ``getState(getEnergy=True, groups={g})`` per force group, the
  Python engine's path and the plugin engine's before);
* ``dcd frame`` : ``knotmm.engine.reporters.DCDReporter.report`` against OpenMM's
  ``DCDFile.writeModel`` (the same bytes);
* ``observables row`` : ``ObservablesReporter.report`` (energies, centre of mass, longest bond,
  CSV row, flush);
* ``checkpoint`` : ``Simulation.saveCheckpoint`` and its parts: ``Context.createCheckpoint``,
  ``np.savez`` into memory, and the rest (temporary file, fsync, rename).

With ``--run T`` (default 400; 0: skip) it also times whole runs of ``T`` tau_d through
``knotmm run`` in this process (``--runs`` of them; start-up of the first one included in
none of the figures): the time inside ``Simulation._report`` per frame, the run's wall time
and the load average. Run on demand (not a test)::

    python benchmarks/bench_reporting.py
    python benchmarks/bench_reporting.py --calls 300 --run 0
"""

from __future__ import annotations

import argparse
import io
import os
import statistics
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np


def per_call(fn, calls: int) -> float:
    """Median seconds of one ``fn()`` over ``calls`` calls."""
    times = []
    for _ in range(calls):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def call_costs(work: Path, calls: int) -> dict:
    import openmm.app
    from openmm import unit

    from knotmm.engine.reporters import DCDReporter, ObservablesReporter
    from knotmm.engine.simulation import Simulation
    from knotmm.shapes import torus_knot

    sim = Simulation(torus_knot(2, 3, 90), platform="CPU", engine="plugin")
    sim.run(5.0)
    out = {
        "energies (plugin, one call)": per_call(sim.energies, calls),
        "energies (4 x getState)": per_call(lambda: sim.energies(sim.positions), calls),
    }
    dcd = DCDReporter(work / "a.dcd", 0.5, sim.topology)
    frame = SimpleNamespace(positions=sim.positions)
    out["dcd frame (DCDReporter)"] = per_call(lambda: dcd.report(frame, None), calls)
    dcd.close()
    with open(work / "b.dcd", "wb") as fh:
        openmm_dcd = openmm.app.DCDFile(fh, sim.topology, 0.5)
        out["dcd frame (DCDFile.writeModel)"] = per_call(
            lambda: openmm_dcd.writeModel(sim.positions * unit.nanometer), calls)
    obs = ObservablesReporter(work / "o.csv", 0.5)
    out["observables row"] = per_call(lambda: obs.report(sim, None), calls)
    obs.close()
    few = max(calls // 10, 5)
    out["checkpoint (saveCheckpoint)"] = per_call(
        lambda: sim.saveCheckpoint(work / "c.npz", {"frames": 1}), few)
    out["  Context.createCheckpoint"] = per_call(sim.context.createCheckpoint, few)
    state = dict(np.load(work / "c.npz"))
    out["  np.savez into memory"] = per_call(lambda: np.savez(io.BytesIO(), **state), few)
    out["  the rest (file, fsync, rename)"] = (out["checkpoint (saveCheckpoint)"]
                                               - out["  Context.createCheckpoint"]
                                               - out["  np.savez into memory"])
    return out


def whole_runs(work: Path, duration: float, runs: int) -> list[dict]:
    from knotmm.cli.main import main
    from knotmm.engine.simulation import Simulation

    spent = [0.0, 0]
    report = Simulation._report

    def timed(self, reporters):
        t = time.perf_counter()
        try:
            return report(self, reporters)
        finally:
            spent[0] += time.perf_counter() - t
            spent[1] += 1

    Simulation._report = timed
    rows = []
    try:
        for _ in range(runs):
            spent[:] = [0.0, 0]
            load = os.getloadavg()[0]
            t = time.perf_counter()
            code = main(["run", "--duration", f"{duration:g}", "--out", str(work / "run"),
                         "--overwrite", "--no-progress"])
            rows.append({"wall": time.perf_counter() - t, "report": spent[0],
                         "frames": spent[1], "load": load, "code": code})
    finally:
        Simulation._report = report
    return rows


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=200)
    parser.add_argument("--run", type=float, default=400.0, help="tau_d; 0: no whole runs")
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        print(f"load average {os.getloadavg()[0]:.2f}; per call, median of {args.calls}:")
        for name, seconds in call_costs(work, args.calls).items():
            print(f"  {name:<34} {1e3 * seconds:8.3f} ms")
        if args.run > 0:
            rows = whole_runs(work, args.run, args.runs)
            for r in rows:
                print(f"knotmm run --duration {args.run:g}: wall {r['wall']:.2f} s, reporting "
                      f"{r['report']:.3f} s = {1e3 * r['report'] / max(r['frames'], 1):.3f} ms "
                      f"x {r['frames']} frames (load {r['load']:.2f}, exit {r['code']})")
            med = statistics.median(r["report"] / max(r["frames"], 1) for r in rows)
            print(f"median: wall {statistics.median(r['wall'] for r in rows):.2f} s, "
                  f"reporting {1e3 * med:.3f} ms per frame")


if __name__ == "__main__":
    main()
