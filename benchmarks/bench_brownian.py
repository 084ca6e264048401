"""Equilibrium of the Brownian integrators on the study's chain: bonds, centre of mass, cost.

For each ``NAME:DT`` (default: ito_heun at 0.002 and 0.01 tau_d, leimkuhler_matthews at
0.005, 0.01 and 0.02) a T(2,3) chain (default N = 90, the study's parameters, gravity 0,
``Pe`` 2) runs through knotmm's Python engine for ``--duration`` tau_d after ``--burn``
tau_d, and the script prints

* ``bond``: the bond-length variance over the Boltzmann value of the stretching energy,
  ``p(l) ~ l^2 exp(-B (l - l0)^2 / (2 kT))`` (bending depends on angles only; the ring
  closure and steric contacts change it by an estimated, not measured, < 0.1 % at N = 90), with the
  standard error from ``--blocks`` time blocks;
* ``com``: the mean square displacement of the centre of mass over ``--lag`` tau_d over
  ``6 kT D_K lag``, ``D_K = tr(sum_ij mu_ij) / (3 N^2)`` the Kirkwood short-time mobility
  averaged over the run's frames (the long-time value is a little lower for a flexible
  ring), with the standard error from the blocks; ``com_lm`` is the value the
  Leimkuhler-Matthews scheme should show instead, ``1 - dt / (2 lag)`` (each frame holds
  half a kick, see :class:`knotmm.dynamics.brownian.LeimkuhlerMatthews`);
* ``s/tau_d``: wall seconds per simulated tau_d, the median of ``--repeats`` short runs.

Run on demand (not part of the tests)::

    python benchmarks/bench_brownian.py                       # all five, 5-10 min
    python benchmarks/bench_brownian.py --runs leimkuhler_matthews:0.01 --duration 40
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import time

import numpy as np

from knotmm.config import RunConfig
from knotmm.dynamics.mobility import rpy_matrix
from knotmm.engine.simulation import Simulation
from knotmm.errors import SimulationFault

DEFAULT_RUNS = ("ito_heun:0.002", "ito_heun:0.01", "leimkuhler_matthews:0.005",
                "leimkuhler_matthews:0.01", "leimkuhler_matthews:0.02")


def boltzmann_bond_variance(stiffness, rest, kt):
    """Variance of ``l`` under ``l^2 exp(-B (l - l0)^2 / (2 kT))``, by quadrature, in d^2."""
    sd = math.sqrt(kt / stiffness)
    grid = np.linspace(max(0.0, rest - 12 * sd), rest + 12 * sd, 200_001)
    w = grid**2 * np.exp(-stiffness * (grid - rest) ** 2 / (2 * kt))
    mean = np.sum(w * grid) / np.sum(w)
    return float(np.sum(w * (grid - mean) ** 2) / np.sum(w))


def config(name, dt, beads, peclet, seed, platform):
    return RunConfig.from_dict({
        "knot": {"beads": beads},
        "model": {"gravity": 0.0},
        "run": {"peclet": peclet, "integrator": name, "timestep": dt, "seed": seed,
                "platform": platform, "engine": "python", "noise": "cholesky"},
    })


def measure(name, dt, args):
    cfg = config(name, dt, args.beads, args.peclet, args.seed, args.platform)
    sim = Simulation.from_config(cfg)
    kt = 1.0 / args.peclet
    every = max(1, round(args.frame / dt))
    try:
        sim.run(args.burn)
        n_frames = int(round(args.duration / (every * dt)))
        bonds = np.empty((n_frames, args.beads))
        com = np.empty((n_frames, 3))
        dk = []
        for k in range(n_frames):
            sim.step(every)
            bonds[k] = sim.bond_lengths()
            com[k] = sim.positions.mean(axis=0)
            if k % max(1, n_frames // 200) == 0:
                m = rpy_matrix(sim.positions)
                dk.append(sum(m[c::3, c::3].sum() for c in range(3)) / (3 * args.beads**2))
    except SimulationFault as exc:
        return {"name": name, "dt": dt, "fault": str(exc)[:90], "time": sim.time}
    ref = boltzmann_bond_variance(cfg["model.bond_stiffness"], cfg["model.bond_length"], kt)
    lag = max(1, round(args.lag / (every * dt)))
    d_k = float(np.mean(dk))
    bond_blocks, com_blocks = [], []
    for block in np.array_split(np.arange(n_frames), args.blocks):
        bond_blocks.append(bonds[block].var() / ref)
        c = com[block]
        disp = c[lag:] - c[:-lag]
        com_blocks.append(np.mean(np.sum(disp**2, axis=1)) / (6 * kt * d_k * lag * every * dt))
    se = lambda v: float(np.std(v, ddof=1) / math.sqrt(len(v)))  # noqa: E731
    return {"name": name, "dt": dt, "bond": float(np.mean(bond_blocks)), "bond_se": se(bond_blocks),
            "com": float(np.mean(com_blocks)), "com_se": se(com_blocks),
            "com_lm": 1 - dt / (2 * lag * every * dt), "d_k": d_k,
            "bond_sd": float(bonds.std()), "ref_sd": math.sqrt(ref)}


def cost(name, dt, args):
    cfg = config(name, dt, args.beads, args.peclet, args.seed, args.platform)
    times = []
    for _ in range(args.repeats):
        sim = Simulation.from_config(cfg)
        t0 = time.perf_counter()
        sim.run(args.cost_duration)
        times.append((time.perf_counter() - t0) / args.cost_duration)
    return statistics.median(times)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--runs", nargs="+", default=list(DEFAULT_RUNS), help="NAME:DT ...")
    p.add_argument("--beads", type=int, default=90)
    p.add_argument("--peclet", type=float, default=2.0)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--platform", default="CPU")
    p.add_argument("--burn", type=float, default=5.0, help="tau_d before measuring")
    p.add_argument("--duration", type=float, default=100.0, help="tau_d measured")
    p.add_argument("--frame", type=float, default=0.02, help="tau_d between frames")
    p.add_argument("--lag", type=float, default=0.5, help="COM lag, tau_d")
    p.add_argument("--blocks", type=int, default=10)
    p.add_argument("--repeats", type=int, default=3, help="cost runs (median)")
    p.add_argument("--cost-duration", type=float, default=2.0)
    args = p.parse_args(argv)
    print(f"T(2,3), N = {args.beads}, Pe = {args.peclet:g}, gravity 0, {args.platform}, "
          f"{args.duration:g} tau_d after {args.burn:g}; load {os.getloadavg()[0]:.2f}")
    print(f"{'integrator':<22}{'dt':>7}{'bond':>16}{'com':>16}{'com_lm':>8}{'s/tau_d':>9}")
    for spec in args.runs:
        name, dt = spec.split(":")
        r = measure(name, float(dt), args)
        if "fault" in r:
            print(f"{name:<22}{float(dt):>7g}  unstable at t = {r['time']:.3g}: {r['fault']}")
            continue
        c = cost(name, float(dt), args)
        print(f"{name:<22}{r['dt']:>7g}{r['bond']:>9.4f} +-{r['bond_se']:.4f}"
              f"{r['com']:>9.3f} +-{r['com_se']:.3f}{r['com_lm']:>8.3f}{c:>9.3f}", flush=True)


if __name__ == "__main__":
    main()
