"""K copies of one chain in one Context against the same runs one after another on the CPU.

Issue 33's device target: K replicas (T(2,3), N beads, 40 tau_d, sedimenting at Pe = inf)
stepped as copies of one Context on ``--platform`` (``RPYIntegrator.setNumCopies``, every copy
from its own perturbed start, on the grid), against the same replicas one after another with
the CPU plugin, each its own Context (pinned to one core with OpenMM's pool thread, as knotmm
runs it). The single runs are a measured sample of ``--sample`` replicas; "K single runs" is
their mean times K. Both sides are timed from a Context that exists and has taken a first
step (kernels compiled), to the end of the duration; imports, templates and files are not in
either. Repetitions are interleaved; the ratio is the median of the per-repetition ratios::

    python benchmarks/bench_copies.py --platform OpenCL --copies 32 --duration 10
    python benchmarks/bench_copies.py --platform CUDA --copies 1024 --sample 8   # the H200 target

The copies' platform runs in double precision by default (``--precision``); the CPU plugin
sums its forces in float and steps in double. ``--quick``: 4 copies of 30 beads for 0.5 tau_d.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # harness.py sits here
import harness  # noqa: E402

FIRST = 0.01  # tau_d: the first step of every case, untimed (compiles the device kernels)


def _starts(beads: int, count: int, seed: int):
    """``count`` starts: the T(2,3) template, each bead moved by 0.05 d normal noise."""
    import numpy as np

    x0 = harness.template(beads)
    rng = np.random.default_rng(seed)
    return [x0 + 0.05 * rng.standard_normal(x0.shape) for _ in range(count)]


def _integrator(args):
    from knotmm.plugin import RPYIntegrator

    return RPYIntegrator(0.01, "rk23", args.tolerance)


def _copies_case(args, starts):
    """Seconds for the K copies from FIRST to the duration, one Context on the platform."""
    import numpy as np
    import openmm

    from knotmm.model.layout import ChainLayout
    from knotmm.model.system import chain_system

    def run():
        k = len(starts)
        integ = _integrator(args)
        integ.setNumCopies(k)
        integ.setCopiesApart(True)
        x = np.vstack(starts)
        system = chain_system(x, layout=ChainLayout((args.beads,) * k, (True,) * k))
        properties = {"Precision": args.precision} if args.platform in ("OpenCL", "CUDA") else {}
        ctx = openmm.Context(system, integ, openmm.Platform.getPlatformByName(args.platform),
                             properties)
        ctx.setPositions(x)
        for c, start in enumerate(starts):
            integ.setCopyPositions(c, start.ravel().tolist())
            integ.setCopyTime(c, 0.0)
        integ.stepCopiesTo([FIRST] * k, 1e9)
        t = time.perf_counter()
        done = integ.stepCopiesTo([args.duration] * k, 1e9)
        wall = time.perf_counter() - t
        failed = sum(integ.getCopyFaultKind(c) != "" for c in range(k))
        del ctx
        return {"wall": wall, "reached": bool(done), "failed": failed}

    return run


def _singles_case(args, starts):
    """Seconds for the sample's single runs on the CPU plugin, one after another."""
    import openmm

    from knotmm.model.system import chain_system

    def run():
        wall = 0.0
        for x in starts:
            with harness.Pinned():
                integ = _integrator(args)
                ctx = openmm.Context(chain_system(x), integ,
                                     openmm.Platform.getPlatformByName("CPU"))
                ctx.setPositions(x)
                integ.stepTo(FIRST)
                t = time.perf_counter()
                integ.stepTo(args.duration)
                wall += time.perf_counter() - t
                del ctx
        return {"wall": wall, "per run": wall / len(starts)}

    return run


def main(argv=None) -> int:
    p = harness.parser(__doc__.splitlines()[0])
    p.add_argument("--platform", default="OpenCL", help="the copies' platform (default OpenCL)")
    p.add_argument("--precision", default="double", help="a device platform's precision")
    p.add_argument("--copies", type=int, default=32)
    p.add_argument("--sample", type=int, default=4, help="single runs measured on the CPU")
    p.add_argument("--beads", type=int, default=90)
    p.add_argument("--duration", type=float, default=40.0, help="tau_d")
    p.add_argument("--tolerance", type=float, default=1e-4, help="rk23's error tolerance (d)")
    args = p.parse_args(argv)
    if args.quick:
        args.copies, args.sample, args.beads, args.duration, args.repeats = 4, 2, 30, 0.5, 1
    import knotmm.plugin as kp

    if not kp.available:
        print(f"the plugin is not available: {kp.load_error}")
        return 2
    info = harness.machine()
    starts = _starts(args.beads, args.copies, seed=1)
    copies = f"{args.copies} copies on {args.platform}"
    sample = f"{args.sample} single runs on CPU"
    print(f"# {info['date']}; {args.beads} beads, {args.duration} tau_d, rk23 at "
          f"{args.tolerance} d; {args.repeats} interleaved repetitions")
    samples = harness.interleave({copies: _copies_case(args, starts),
                                  sample: _singles_case(args, starts[:args.sample])},
                                 args.repeats, log=print)
    cases = harness.summarize(samples, key="wall")
    # the copies against K single runs: the sample's time scaled by K / sample, per repetition
    ratio = harness.ratio(samples, copies, sample, key="wall") * args.sample / args.copies
    per_run = cases[sample]["median"] / args.sample
    print(f"median: {copies} {cases[copies]['median']:.3f} s; a single run on CPU "
          f"{per_run:.4f} s, times {args.copies}: {per_run * args.copies:.3f} s; ratio {ratio:.4f}")
    harness.save("bench_copies", args, cases, samples,
                 extra={"ratio to K single runs": ratio},
                 machine_before=info)
    return 0


if __name__ == "__main__":
    sys.exit(main())
