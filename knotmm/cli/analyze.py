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
            "rotation sense and knot type. An open chain gets its speed, shape and end-to-end "
            "vector (no knot type, no torus quantities); a run of several chains each chain's "
            "observables and the system's (centre of mass, pairs, linking numbers; a link as "
            "one object); every chain its elasto-gravitation number B = N^3 F0 l0 / A. What "
            "does not apply is n/a with the reason. Writes analysis.json and PNG plots into "
            "the run directory (model units: d, tau_d)."
        ),
    )
    parser.add_argument(
        "run",
        metavar="RUN",
        help="run directory, a DCD trajectory file, or a sweep directory (every run analysed; "
        "mean +- standard error per point over its replicas in replicas.json)",
    )
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
        help="time between frames in tau_d (default: run.toml's, else the DCD header's)",
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
    parser.add_argument(
        "--include-partial",
        action="store_true",
        help="sweep directory or replica set: also average the runs that stopped early "
        "(fault, interrupted) or are still running (default: left out and named)",
    )
    parser.set_defaults(execute=execute)
    return parser


def _options(args) -> dict:
    """The analysis options shared by a run and a sweep directory."""
    return {
        "t_from": args.t_from,
        "t_to": args.t_to,
        "p": args.p,
        "q": args.q,
        "plots": args.plots,
        "knot_samples": max(0, args.knot_samples),
    }


def execute(args) -> int:
    """Run the analysis and print a short table; 0 on success."""
    import matplotlib

    matplotlib.use("Agg")
    from knotmm.analysis import analyze_run, format_table
    from knotmm.analysis.core import ANALYSIS_FILE
    from knotmm.analysis.replicas import is_sweep_directory
    from knotmm.io.rundir import SHAPE_FILE, OutputError, WriteFault

    if is_sweep_directory(args.run):
        return _execute_sweep(args)
    if args.include_partial:
        logger.warning("--include-partial is for a sweep directory or a replica set; ignored")
    _check_output(args)
    try:
        result = analyze_run(
            args.run,
            frame_interval=args.frame_interval,
            topology=args.topology,
            out_dir=args.out,
            **_options(args),
        )
    except OutputError as exc:  # after the computation: a failure while writing, exit 3
        if isinstance(exc, WriteFault):
            raise
        raise WriteFault(f"{exc}; the files written before it are kept") from None
    print(format_table(result))
    out = args.out or (result.data.directory if result.data else ".")
    shape = [SHAPE_FILE] if result.shape is not None else []
    files = [ANALYSIS_FILE, *shape, *result.plots]
    print(f"wrote {', '.join(files)} in {out}")
    return 0


def _check_output(args) -> None:
    """Check before the analysis that its output place can be written (one line, exit 2).

    The place is ``--out`` (created if missing), else the run directory (the folder of a
    DCD); a run path that does not exist is left to the loader's message.
    """
    from pathlib import Path

    from knotmm.io.rundir import check_output_directory

    if args.out is not None:
        check_output_directory(args.out)
        return
    run = Path(args.run)
    if run.is_dir():
        check_output_directory(run, "RUN")
    elif run.is_file():
        check_output_directory(run.parent, "RUN")


def _check_sweep_output(root) -> None:
    """Check before any analysis that the sweep directory and its runs can take files (exit 2,
    one line naming the place), as :func:`_check_output` for a run."""
    from knotmm.io.rundir import RUN_FILE, check_output_directory

    check_output_directory(root, "RUN")
    for run in sorted(p for p in root.iterdir() if (p / RUN_FILE).is_file()):
        check_output_directory(run, "RUN")


#: Columns of the per-point table printed for a sweep directory.
SWEEP_COLUMNS = (
    "sedimentation_velocity",
    "tau_swirl_body",
    "swirl_amplitude",
    "torus_fraction",
    "body_frame.flips_per_100_tau",
)


def _mean_se(stat: dict | None, total: int | None = None) -> str:
    """A table cell: ``mean +- std_error`` over the point's replicas that measured it.

    When fewer than ``total`` replicas (the point's ``n``) measured the quantity, the cell
    says over how many (``7.471 (n=1 of 3)``: one replica's value, no error); ``n/a`` when
    none did.
    """
    n = stat["n"] if stat else 0
    of = f" (n={n} of {total})" if total is not None and n < total else ""
    if not stat or stat["mean"] is None:
        return "n/a" + of
    text = f"{stat['mean']:.4g}"
    if stat["std_error"] is not None:
        text += f" +- {stat['std_error']:.2g}"
    return text + of


def _execute_sweep(args) -> int:
    """Analyse every run of a sweep directory; print mean +- standard error per point."""
    from pathlib import Path

    from knotmm.analysis.replicas import REPLICAS_FILE, analyze_sweep

    if args.out is not None or args.frame_interval is not None or args.topology is not None:
        logger.warning("--out, --frame-interval and --topology are ignored for a sweep")
    _check_sweep_output(Path(args.run))
    summary = analyze_sweep(args.run, include_partial=args.include_partial, **_options(args))
    rows = [("point", "n", *SWEEP_COLUMNS)]
    for name, point in summary["points"].items():
        stats = point["statistics"]
        total = len(point["runs"])
        rows.append(
            (name, str(total), *(_mean_se(stats.get(c), total) for c in SWEEP_COLUMNS))
        )
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    for row in rows:
        print("  ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=True)).rstrip())
    for name, point in summary["points"].items():
        for run, why in point["excluded"].items():
            print(f"note: {name}: {run} left out: {why}")
        for run, why in point.get("partial", {}).items():
            print(f"note: {name}: {run} averaged although unfinished: {why}")
        for run, error in point["failed"].items():
            print(f"note: {name}: {run} failed: {error}")
    print(f"wrote {REPLICAS_FILE} (mean +- standard error over replicas) in {Path(args.run)}")
    return 0
