"""Cost of one Brownian step: knotmm's engines against the numba + LAPACK yardstick (issue 12).

Target: "Brownian, Pe = 2, N = 90: a step no slower than a plain numba + LAPACK program doing
the same scheme at the same dt". T(2,3), N = 90, the study's parameters, gravity 0 (as
``bench_brownian.py``), Pe = 2, Cholesky noise; for each scheme (``ito_heun`` at 0.002,
``leimkuhler_matthews`` at 0.01 tau_d) three programs take ``--steps`` steps from the same
start, interleaved, ``--repeats`` times (medians):

* ``numba``: ``benchmarks/numba_brownian.py`` (compiled before timing);
* ``python``: ``Simulation(engine="python")``, CPU platform, one thread;
* ``plugin``: ``Simulation(engine="plugin")``, CPU platform, one thread, LAPACK's Cholesky
  (:func:`knotmm.plugin.use_lapack_cholesky`).

Each line also gives simulated tau_d per wall second and its ratio to the Python engine's
``ito_heun`` at 0.002 tau_d (the default before the plugin had ``leimkuhler_matthews``).

Then where a step's time goes, from each piece timed alone (microseconds per call, medians
of 5 batches): numba and Python engine: ``forces``, ``mobility``, ``matrix`` (dense RPY),
``cholesky`` (LAPACK ``dpotrf`` in both), ``L xi`` (normals and the triangular product),
``rest`` = step - the pieces times their count per step. The Python engine's ``forces`` cycles
through 64 consecutive positions of a Brownian run, as in a run: the CPU platform then
rebuilds its neighbour list on most calls; ``forces fixed`` repeats one position (no
rebuild). Plugin (each a step of a fresh Context from the run's positions, per call):
``step`` (the scheme at the run's Pe), ``still`` (the same at kT = 1e-12 F0 d: every noise
sample is drawn, the beads move only by the drift), ``det`` (the same at kT = 0: no noise;
``heun`` for ``ito_heun``, ``euler`` for ``leimkuhler_matthews``), ``no-force`` (an Euler step
on a System without forces: mobility and the CPU platform's fixed cost per force call);
``noise`` = still - det (matrix, Cholesky, normals, ``L xi``, and what they do to the force
calls after them), ``motion`` = step - still (neighbour-list rebuilds as the noise moves the
beads), ``forces`` = (det / evaluations - no-force). ``cholesky`` / ``cholesky builtin``:
the plugin's factorisation alone (``rpyplugin.choleskyFactor``, LAPACK / the built-in loop,
with a copy of the matrix in and out).

``--noise lanczos`` gives both engines Lanczos noise (``run.noise``; the numba program keeps
its Cholesky noise) and skips the pieces, which assume Cholesky.

BLAS/LAPACK run on one thread (``threadpoolctl``) unless ``--blas-threads`` says otherwise::

    python benchmarks/bench_brownian_step.py                     # about 1 min
    python benchmarks/bench_brownian_step.py --schemes ito_heun --steps 300
    python benchmarks/bench_brownian_step.py --schemes ito_heun --beads 400 --noise lanczos \
        --steps 20 --burn 0.01
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import statistics
import sys
import time
from functools import partial
from pathlib import Path

import numpy as np
import scipy.linalg
from threadpoolctl import threadpool_limits

from knotmm.config import RunConfig
from knotmm.dynamics.mobility import rpy_matrix, rpy_velocities
from knotmm.engine.simulation import Simulation

STEPS = {"ito_heun": 0.002, "leimkuhler_matthews": 0.01}
#: (scheme, program) -> simulated tau_d per wall second, filled as the schemes run.
RATES: dict = {}
#: Force + mobility evaluations per step, and noise samples per step.
COUNTS = {"ito_heun": (2, 1), "leimkuhler_matthews": (1, 1)}
#: The pieces are timed in CPU time (less disturbed by other jobs on a shared machine).
CLOCK = time.process_time


def _load(name):
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(
            name, Path(__file__).resolve().parent / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module  # numba's cache looks the module up by name
        spec.loader.exec_module(module)
    return sys.modules[name]


def config(scheme, args, engine):
    return RunConfig.from_dict({
        "knot": {"beads": args.beads},
        "model": {"gravity": 0.0},
        "run": {"peclet": args.peclet, "integrator": scheme, "timestep": STEPS[scheme],
                "seed": args.seed, "platform": "CPU", "engine": engine, "noise": args.noise},
    })


def python_pieces(sim, budget, trajectory) -> dict:
    per_call = partial(_load("numba_brownian").per_call, clock=CLOCK)
    x = sim.positions.copy()
    k = [0]

    def moving():  # consecutive positions of a run: the CPU platform rebuilds its list
        k[0] = (k[0] + 1) % len(trajectory)
        sim.forces(trajectory[k[0]])

    f = sim.forces(x)
    out = np.empty_like(x)
    m = rpy_matrix(x)
    lower = scipy.linalg.cholesky(m, lower=True, check_finite=False)
    rng = np.random.default_rng(0)
    return {
        "forces": per_call(moving, budget),
        "forces fixed": per_call(lambda: sim.forces(x), budget),
        "mobility": per_call(lambda: rpy_velocities(x, f, out=out), budget),
        "matrix": per_call(lambda: rpy_matrix(x), budget),
        "cholesky": per_call(
            lambda: scipy.linalg.cholesky(m, lower=True, check_finite=False), budget),
        "L xi": per_call(lambda: lower @ rng.standard_normal(m.shape[0]), budget),
    }


def plugin_pieces(sim, scheme, args, budget) -> dict:
    import openmm

    from knotmm.model.system import chain_system
    from knotmm.plugin import RPYIntegrator, rpyplugin

    per_call = partial(_load("numba_brownian").per_call, clock=CLOCK)
    x = sim.positions.copy()
    cpu = openmm.Platform.getPlatformByName("CPU")
    keep = []

    def stepper(system, method, kt):
        """One step of a fresh Context (from the run's positions) per call."""
        integ = RPYIntegrator(STEPS[scheme], method, kT=kt, seed=1, threads=1)
        ctx = openmm.Context(system, integ, cpu, {"Threads": "1"})
        ctx.setPositions(x)
        keep.append(ctx)
        return lambda: integ.step(1)

    empty = openmm.System()
    for _ in range(len(x)):
        empty.addParticle(1.0)
    system = chain_system(x, sim.model)
    a = rpy_matrix(x)
    return {
        "step": per_call(stepper(system, scheme, 1.0 / args.peclet), budget),
        "still": per_call(stepper(system, scheme, 1e-12), budget),
        "det": per_call(stepper(system, scheme, 0.0), budget),
        "no-force": per_call(stepper(empty, "euler", 0.0), budget),
        "cholesky": per_call(lambda: rpyplugin.choleskyFactor(a, False), budget),
        "cholesky builtin": per_call(lambda: rpyplugin.choleskyFactor(a, True), budget),
    }

def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--schemes", nargs="+", default=list(STEPS), choices=list(STEPS))
    p.add_argument("--beads", type=int, default=90)
    p.add_argument("--peclet", type=float, default=2.0)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--steps", type=int, default=1000, help="steps per timed run")
    p.add_argument("--burn", type=float, default=0.2, help="tau_d before timing")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--budget", type=float, default=0.5, help="s per piece timing")
    p.add_argument("--blas-threads", type=int, default=1)
    p.add_argument("--noise", default="cholesky", choices=["cholesky", "lanczos"],
                   help="the engines' noise (the numba program's is Cholesky)")
    args = p.parse_args(argv)
    with threadpool_limits(args.blas_threads):
        for scheme in args.schemes:
            run_scheme(scheme, args)


def run_scheme(scheme, args):
    nb = _load("numba_brownian")
    dt = STEPS[scheme]
    kt = 1.0 / args.peclet
    engines = ["python", "plugin"]
    sims = {e: Simulation.from_config(config(scheme, args, e), engine=e) for e in engines}
    x0 = sims["python"].positions.copy()
    params = nb.parameters(gravity=0.0)
    state = {"numba": nb.run(scheme, x0, params, kt, dt, int(round(args.burn / dt)), args.seed)}
    for sim in sims.values():
        sim.run(args.burn)
    steps = args.steps
    times = {k: ([], []) for k in ["numba", *engines]}  # wall, cpu
    loads = [os.getloadavg()[0]]

    def timed(key, fn, count):
        t0, c0 = time.perf_counter(), time.process_time()
        n = fn()
        times[key][0].append(1e6 * (time.perf_counter() - t0) / (count if n is None else n))
        times[key][1].append(1e6 * (time.process_time() - c0) / (count if n is None else n))

    for r in range(args.repeats):
        def numba_run(r=r):
            state["numba"] = nb.run(scheme, state["numba"], params, kt, dt, steps,
                                    args.seed + r + 1)
        timed("numba", numba_run, steps)
        for e, sim in sims.items():
            def engine_run(sim=sim):
                n0 = sim.currentStep
                sim.run(steps * dt)
                return sim.currentStep - n0
            timed(e, engine_run, steps)
        loads.append(os.getloadavg()[0])
    med = {k: statistics.median(v[0]) for k, v in times.items()}
    cpu = {k: statistics.median(v[1]) for k, v in times.items()}
    print(f"\n{scheme}, dt = {dt:g} tau_d, T(2,3) N = {args.beads}, Pe = {args.peclet:g}, "
          f"gravity 0, {args.noise} noise, {steps} steps per run, medians of {args.repeats} "
          f"interleaved; load {min(loads):.2f}-{max(loads):.2f}")
    print(f"  {'':<7} {'wall':>8} {'cpu':>8} us/step  {'wall/numba':>10} {'cpu/numba':>10} "
          f"{'tau_d/s':>8} {'x today':>7}  runs (wall/cpu)")
    for k in med:
        spread = ", ".join(f"{w:.0f}/{c:.0f}" for w, c in zip(*times[k], strict=True))
        rate = dt / (1e-6 * med[k])  # simulated tau_d per wall second
        RATES[(scheme, k)] = rate
        today = RATES.get(("ito_heun", "python"))
        print(f"  {k:<7} {med[k]:8.0f} {cpu[k]:8.0f}          {med[k] / med['numba']:10.2f} "
              f"{cpu[k] / cpu['numba']:10.2f} {rate:8.2f} "
              f"{'' if today is None else f'{rate / today:7.2f}'}  ({spread})")
    if args.noise != "cholesky":
        return  # the pieces below assume Cholesky noise
    n_eval, n_noise = COUNTS[scheme]
    budget = args.budget
    trajectory = [state["numba"]]
    for k in range(63):
        trajectory.append(nb.run(scheme, trajectory[-1], params, kt, dt, 1, k))
    pieces = {"numba": nb.profile(state["numba"], params, budget, clock=CLOCK),
              "python": python_pieces(sims["python"], budget, trajectory)}
    for k in ("numba", "python"):
        pc = pieces[k]
        used = n_eval * (pc["forces"] + pc["mobility"]) + n_noise * (
            pc["matrix"] + pc["cholesky"] + pc["L xi"])
        pc["rest"] = cpu[k] - used
        print(f"  {k:<7} cpu us/call: " + ", ".join(f"{n} {t:.0f}" for n, t in pc.items())
              + f"  (x{n_eval} forces, mobility; x{n_noise} matrix, cholesky, L xi)")
    pc = plugin_pieces(sims["plugin"], scheme, args, budget)
    pc["noise"] = pc["still"] - pc["det"]
    pc["motion"] = pc["step"] - pc["still"]
    pc["forces"] = pc["det"] / n_eval - pc["no-force"]
    print("  plugin  cpu us/call: " + ", ".join(f"{n} {t:.0f}" for n, t in pc.items()))


if __name__ == "__main__":
    main()
