"""``knotmm analyze``: measure a run's observables, write analysis.json and plots."""

from __future__ import annotations

import argparse
import logging

__all__ = ["add_parser", "execute"]

logger = logging.getLogger(__name__)


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register the ``analyze`` sub-command."""
    parser = subparsers.add_parser(
        "analyze",
        help="measure V, rho0, tau_sed, tau_swirl, tau_rot, the vortex-knot fit, "
        "writhe and knot type of a run",
        description=(
            "Analyse a saved run: finds the steady window (or use --from/--to), measures the "
            "sedimentation speed, major radius, the three time scales and their ratios, "
            "fits the vortex-knot formula to every bead, and reports writhe, handedness, "
            "rotation sense and knot type. Writes analysis.json and PNG plots into the run "
            "directory (model units: d, tau_d)."
        ),
    )
    parser.add_argument("run", metavar="RUN", help="run directory, or a DCD trajectory file")
    parser.add_argument(
        "--from",
        dest="t_from",
        type=float,
        metavar="T",
        help="window start in tau_d (default: after the initial transient)",
    )
    parser.add_argument(
        "--to",
        dest="t_to",
        type=float,
        metavar="T",
        help="window end in tau_d (default: where the periodic state ends)",
    )
    parser.add_argument(
        "--p",
        type=int,
        metavar="P",
        help="loops of the torus knot T(p,q) (default: run.toml or detected)",
    )
    parser.add_argument(
        "--q", type=int, metavar="Q", help="windings of the torus knot T(p,q) (default: run.toml)"
    )
    parser.add_argument(
        "--frame-interval",
        type=float,
        metavar="T",
        help="time between frames in tau_d (needed without run.toml)",
    )
    parser.add_argument(
        "--topology", metavar="PDB", help="topology PDB for a DCD (default: the PDB beside it)"
    )
    parser.add_argument(
        "--out", metavar="DIR", help="write results here (default: the run directory)"
    )
    parser.add_argument(
        "--no-plots", dest="plots", action="store_false", help="write analysis.json only"
    )
    parser.add_argument(
        "--knot-samples",
        type=int,
        default=40,
        metavar="K",
        help="frames checked with topoly for a change of knot type "
        "(0: skip knot identification; default 40)",
    )
    parser.set_defaults(execute=execute)
    return parser


def execute(args) -> int:
    """Run the analysis and print a short table; 0 on success."""
    import matplotlib

    matplotlib.use("Agg")
    from knotmm.analysis import analyze_run, format_table
    from knotmm.analysis.core import ANALYSIS_FILE

    result = analyze_run(
        args.run,
        t_from=args.t_from,
        t_to=args.t_to,
        p=args.p,
        q=args.q,
        plots=args.plots,
        frame_interval=args.frame_interval,
        topology=args.topology,
        out_dir=args.out,
        knot_samples=max(0, args.knot_samples),
    )
    print(format_table(result))
    out = args.out or (result.data.directory if result.data else ".")
    files = [ANALYSIS_FILE, *result.plots]
    print(f"wrote {', '.join(files)} in {out}")
    return 0
