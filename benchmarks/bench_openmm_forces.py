"""Where OpenMM's time goes in one force evaluation, and the floor it puts under a full step.

For a T(2,3) of N beads on the platform a run uses (CPU, one thread), times
``Context.setPositions`` + ``Context.getState(getForces=True)`` (new positions each call, as
in a run) for

* a System with no forces at all (the platform's fixed cost per call),
* a System with each of knotmm's four forces alone,
* knotmm's System (all four),
* the bending term as ``HarmonicAngleForce`` and as knotmm's ``CustomAngleForce``
  (interleaved, in otherwise identical Systems; same forces to round-off),

and the RPY mobility loop alone. The fixed cost and the mobility loop together bound the
ratio "full evaluation / mobility alone" from below, whatever the forces cost.

Run on demand (not part of the tests)::

    python benchmarks/bench_openmm_forces.py
    python benchmarks/bench_openmm_forces.py --beads 90 120 --repeats 9
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import numpy as np
import openmm

from knotmm.dynamics.mobility import rpy_velocities
from knotmm.model.forces import bend_force, bond_force, gravity_force, steric_force
from knotmm.model.system import ChainModel
from knotmm.shapes import torus_knot


def _per_call(fn, inner):
    t0 = time.perf_counter()
    for _ in range(inner):
        fn()
    return (time.perf_counter() - t0) / inner


def _context(x, forces, threads):
    system = openmm.System()
    for _ in range(x.shape[0]):
        system.addParticle(1.0)
    for force in forces:
        system.addForce(force)
    platform = openmm.Platform.getPlatformByName("CPU")
    context = openmm.Context(
        system, openmm.VerletIntegrator(0.01), platform, {"Threads": str(threads)}
    )
    context.setPositions(x)
    return context


def _harmonic_bend(n, model):
    force = openmm.HarmonicAngleForce()
    for i in range(n):
        force.addAngle((i - 1) % n, i, (i + 1) % n, np.pi, model.bending_stiffness)
    return force


def costs(n, repeats, inner, threads=1):
    """Median microseconds per force computation of each variant, for n beads."""
    model = ChainModel()
    x = torus_knot(2, 3, n)
    cases = {
        "no forces": [],
        "bond alone": [bond_force(n, model)],
        "bend alone": [bend_force(n, model)],
        "steric alone": [steric_force(n, model)],
        "gravity alone": [gravity_force(n, model)],
        "knotmm (all four)": [
            bond_force(n, model),
            bend_force(n, model),
            steric_force(n, model),
            gravity_force(n, model),
        ],
        "all four, HarmonicAngleForce": [
            bond_force(n, model),
            _harmonic_bend(n, model),
            steric_force(n, model),
            gravity_force(n, model),
        ],
    }
    contexts = {name: _context(x, forces, threads) for name, forces in cases.items()}
    a = contexts["knotmm (all four)"].getState(getForces=True).getForces(asNumpy=True)._value
    b = contexts["all four, HarmonicAngleForce"].getState(getForces=True)
    deviation = float(np.abs(a - b.getForces(asNumpy=True)._value).max())
    # New positions every call, as in a run (the CPU platform redoes its neighbour list and
    # float copies after setPositions; the same positions again would skip that work).
    jitter = [x + 1e-6 * k for k in range(2)]
    toggle = [0]

    def call(context):
        toggle[0] ^= 1
        context.setPositions(jitter[toggle[0]])
        context.getState(getForces=True)

    calls = {name: (lambda c=c: call(c)) for name, c in contexts.items()}
    f = a.copy()
    calls["RPY mobility loop"] = lambda: rpy_velocities(x, f)
    samples = {name: [] for name in calls}
    for fn in calls.values():
        fn()  # warm up
    for _ in range(repeats):  # interleaved, so that load changes hit every variant alike
        for name, fn in calls.items():
            samples[name].append(_per_call(fn, inner) * 1e6)
    ratio = statistics.median(
        np.array(samples["knotmm (all four)"]) / np.array(samples["all four, HarmonicAngleForce"])
    )
    return {k: statistics.median(v) for k, v in samples.items()}, ratio, deviation


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--beads", nargs="+", type=int, default=[40, 90, 120, 240])
    parser.add_argument("--repeats", type=int, default=7, help="interleaved timings per median")
    parser.add_argument("--inner", type=int, default=300, help="calls per timing")
    parser.add_argument("--threads", type=int, default=1, help="CPU platform threads")
    args = parser.parse_args(argv)
    print(
        f"OpenMM {openmm.__version__} CPU platform, {args.threads} thread(s); "
        f"{os.cpu_count()} CPUs visible, load average {os.getloadavg()[0]:.2f}; "
        f"medians of {args.repeats}, microseconds per call"
    )
    for n in args.beads:
        med, ratio, deviation = costs(n, args.repeats, args.inner, args.threads)
        print(f"\nN = {n}")
        for name, us in med.items():
            print(f"  {name:<30} {us:8.1f}")
        floor = (med["no forces"] + med["RPY mobility loop"]) / med["RPY mobility loop"]
        print(
            f"  CustomAngleForce / HarmonicAngleForce, whole System: {ratio:.3f} "
            f"(largest force difference {deviation:.1e} F0)"
        )
        print(f"  lower bound of velocity / mobility (empty System + loop): {floor:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
