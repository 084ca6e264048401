"""``knotmm orbit``: the periodic orbit of a run, its Floquet multipliers, a continuation."""

from __future__ import annotations

import argparse
import math

__all__ = ["add_parser", "execute"]


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register the ``orbit`` sub-command."""
    p = subparsers.add_parser(
        "orbit",
        help="find the periodic orbit of a run's swirling state and its stability",
        description=(
            "Converge the relative periodic orbit of a deterministic run (the shape repeats "
            "after one period up to a fall and a rotation about z) by Newton-Krylov "
            "shooting from a state of its steady window, compute its leading Floquet "
            "multipliers by Arnoldi, and describe the leading mode. Writes orbit.json, "
            "orbit.dcd + topology.pdb (one period), mode_1.dcd and orbit_multipliers.png "
            "(default into RUN_DIR/orbit). With --continue, follow the orbit along a "
            "parameter and report where a multiplier crosses the unit circle "
            "(continuation.csv, continuation.json, continuation.png, rewritten after each "
            "converged point; --resume goes on with a stopped one). The output directory is "
            "locked while orbit writes there, and an earlier orbit's files in it are replaced. "
            "Ctrl-C or SIGTERM stops at once (exit 130): a continuation keeps every converged "
            "point. Model units: d, tau_d."
        ),
    )
    p.add_argument("run", metavar="RUN_DIR", help="a deterministic run directory")
    p.add_argument("--t", type=float, metavar="T",
                   help="time of the starting state in tau_d (default: middle of the window)")
    p.add_argument("--modes", type=int, default=10, metavar="K",
                   help="leading non-neutral Floquet multipliers to compute (default 10; at "
                   "most 3N - 8 for N beads)")
    p.add_argument("--out", metavar="DIR", help="output directory (default RUN_DIR/orbit)")
    p.add_argument("--continue", dest="spec", metavar="KEY=A:B",
                   help="follow the orbit along a parameter, e.g. "
                   "model.bending_stiffness=5:500 or knot.beads=60:90")
    p.add_argument("--points", type=int, default=8, metavar="N",
                   help="points of the continuation between A and B (default 8)")
    p.add_argument("--resume", action="store_true",
                   help="with --continue: go on with the continuation stopped in --out "
                   "(Ctrl-C, SIGTERM, a kill), from its last converged point; give the "
                   "options it was started with")
    p.add_argument("--timestep", type=float, metavar="H",
                   help="fixed step of the flow map in tau_d, in (0, 0.05] (default: 0.01, "
                   "smaller for stiffer chains so that Heun stays stable)")
    p.add_argument("--tolerance", type=float, default=1e-8, metavar="R",
                   help="Newton's residual in d rms per bead (default 1e-8)")
    p.add_argument("--engine", choices=("auto", "plugin", "python"), default="auto",
                   help="who integrates (default: the compiled plugin when available)")
    p.set_defaults(execute=execute)
    return p


def _mu(pair) -> str:
    re, im = pair
    return f"{re:+.4f}{im:+.4f}i (|mu| = {math.hypot(re, im):.4f})"


def _print_orbit(summary: dict) -> None:
    rows = [
        ("status", summary["status"] + ("" if summary["status"] == "converged"
                                        else f" ({summary['message']})")),
        ("period T [tau_d]", f"{summary['period']:.6g}  (run's tau_swirl "
                             f"{summary['run_tau_swirl']:.6g})"),
        ("rotation per period [rad]", f"{summary['rotation_per_period']:+.6g}"),
        ("sedimentation speed [d/tau_d]", f"{summary['sedimentation_velocity']:.6g}"),
        ("residual [d rms per bead]", f"{summary['residual']:.3g} after "
                                      f"{summary['newton_iterations']} Newton steps"),
    ]
    if summary.get("floquet_multipliers"):
        rows.append(("leading multiplier", _mu(summary["floquet_multipliers"][0])))
        rows.append(("leading exponent [1/tau_d]", f"{summary['leading_exponent']:+.4g}"))
        rows.append(("unstable multipliers", str(summary["unstable_multipliers"])))
        rows.append(("leading mode", summary["leading_mode"]))
        for item in summary["neutral_multipliers"]:
            rows.append((f"neutral: {item['symmetry']}", _mu(item["multiplier"])))
    width = max(len(r[0]) for r in rows)
    for name, value in rows:
        print(f"{name:<{width}}  {value}")


def execute(args) -> int:
    """Find the orbit (and a continuation); 0 when converged, 1 when Newton did not.

    A signal (Ctrl-C, SIGTERM) stops at the next integration step: exit 130 with one line
    saying what was kept.
    """
    import io
    import sys

    from knotmm.errors import ConfigError

    if args.resume and not args.spec:
        raise ConfigError("--resume goes on with a continuation: give it with --continue "
                          "KEY=A:B and the --out, --points and --modes it was started with")
    try:  # the imports take a second: a signal then is this command's line too
        from knotmm.engine.interrupt import stop_between_steps
        from knotmm.orbit.driver import OrbitInterrupted
    except KeyboardInterrupt:
        print("knotmm: interrupted before the orbit's computation began; nothing was "
              "written", file=sys.stderr)
        return 130
    try:
        # the first signal stops at the next step of the flow map, never inside a write
        with stop_between_steps(stream=io.StringIO()):
            return _execute(args)
    except OrbitInterrupted as exc:
        print(f"knotmm: {exc.message}", file=sys.stderr)
    except KeyboardInterrupt:
        print("knotmm: interrupted before the orbit's computation began; nothing was "
              "written", file=sys.stderr)
    return 130


def _execute(args) -> int:
    from knotmm.orbit.driver import continuation_of_run, orbit_of_run

    common = dict(t=args.t, modes=args.modes, out=args.out, timestep=args.timestep,
                  tolerance=args.tolerance, engine=args.engine)
    if args.spec:
        def show(point):
            o = point.orbit
            lead = "" if point.floquet is None or not len(point.floquet.multipliers) else (
                f", |mu1| = {abs(point.floquet.multipliers[0]):.4f}")
            print(f"  {point.value:.6g}: T = {o.period:.6g} tau_d, residual "
                  f"{o.residual:.2g} d{lead}", flush=True)

        branch, bifurcations, out = continuation_of_run(args.run, args.spec,
                                                        points=args.points, on_point=show,
                                                        resume=args.resume, **common)
        for b in bifurcations:
            where = "" if "discrete" in b.kind else f" near {b.value:.6g}"
            print(f"bifurcation{where}: {b.kind}; {'; '.join(b.notes)}")
        if not bifurcations:
            print("no multiplier crossed the unit circle along the branch")
        print(f"{len(branch)} points; wrote continuation.csv, continuation.json, "
              f"continuation.png in {out}")
        return 0 if branch else 1
    report = orbit_of_run(args.run, **common)
    _print_orbit(report.summary)
    print(f"wrote orbit.json, orbit.dcd, topology.pdb"
          f"{', mode_1.dcd, orbit_multipliers.png' if report.floquet is not None else ''} "
          f"in {report.out}")
    if not report.orbit.converged:
        print(f"knotmm: the orbit did not converge: residual {report.orbit.residual:.3g} d "
              f"({report.orbit.message}); orbit.json holds the last iterate")
        return 1
    return 0
