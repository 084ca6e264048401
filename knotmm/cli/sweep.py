"""``knotmm sweep``: run every point of a sweep file, analyse each, write the summary."""

from __future__ import annotations

import argparse

__all__ = ["add_parser", "execute"]


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register ``knotmm sweep``."""
    p = subparsers.add_parser(
        "sweep",
        help="run a parameter sweep or ensemble (locally or on a Dask cluster)",
        description=(
            "Run a sweep file: a run file plus a [sweep] table mapping dotted keys to lists "
            '(e.g. "knot.beads" = [40, 60, 80]), expanded as a grid (mode = "grid") or '
            'side by side (mode = "zip"); seeds = K runs K replicas of every point. Each '
            "point gets its own run directory in the sweep directory and is analysed; "
            "DIR/summary.csv has one row per point and DIR/ratios.png plots the time-scale "
            "ratios. Running it again skips finished points and redoes the others. One sweep "
            "at a time owns a sweep directory: a second one is refused (exit status 2, "
            "naming the first one's process id). --set and --duration apply to every point "
            "(recorded in each run.toml and in DIR/sweep.toml); a key the sweep varies "
            "cannot be set, and a sweep directory is continued only with the same --set "
            "and --duration it was started with. Exit status 1 when some point failed, 3 "
            "when summary.csv cannot be written after points ran."
        ),
    )
    p.add_argument("sweep_file", metavar="SWEEP.toml", help="sweep file (TOML)")
    p.add_argument("--out", metavar="DIR", help="sweep directory (default: output.directory)")
    p.add_argument("--duration", type=float, metavar="T",
                   help="simulated time of every point, in tau_d (as --set run.duration=T)")
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="TABLE.KEY=VALUE",
        help="override a run-file key at every point, e.g. --set run.peclet=10 "
        "(repeatable; not a key that [sweep] varies)",
    )
    p.add_argument(
        "--workers",
        type=int,
        metavar="K",
        help="local worker processes (default: CPU cores / run.threads; 0: in this process)",
    )
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="run on an existing Dask cluster: tcp://host:port or a scheduler JSON file "
        "(needs knotmm[cluster]; workers must see the sweep directory)",
    )
    p.add_argument(
        "--reanalyze",
        action="store_true",
        help="analyse finished points again instead of skipping them",
    )
    p.add_argument(
        "--dry-run",
        action="store_true",
        help="validate the sweep file, make the checks of `knotmm run` on every point (exit "
        "2 when one cannot run) and list the points; run nothing",
    )
    bar = p.add_mutually_exclusive_group()
    bar.add_argument(
        "--progress",
        dest="progress",
        action="store_true",
        default=None,
        help="always show the progress bar",
    )
    bar.add_argument(
        "--no-progress", dest="progress", action="store_false", help="never show the progress bar"
    )
    p.set_defaults(execute=execute)
    return p


def execute(args) -> int:
    """Validate the whole sweep, then run it; 0 when every point finished, else 1."""
    import sys

    from knotmm.config import parse_override
    from knotmm.errors import ConfigError
    from knotmm.sweep import check_points, describe_points, load_sweep_file, run_sweep

    if args.workers is not None and args.workers < 0:
        raise ConfigError(f"--workers {args.workers}: expected an integer >= 0")
    overrides = {}
    for text in args.set:
        try:
            key, value = parse_override(text)
        except ConfigError as exc:
            message = str(exc)
            raise ConfigError(message if message.startswith("--set") else
                              f"--set {text}: {message}") from None
        overrides[key] = value
    if args.duration is not None:
        overrides["run.duration"] = args.duration
    sweep = load_sweep_file(args.sweep_file, directory=args.out, overrides=overrides)
    for note in sweep.notes:
        print(f"knotmm: note: {note}", file=sys.stderr)
    if args.dry_run:  # the checks `knotmm run` makes, on every point; nothing is written
        errors = {c.point.name: c.error for c in check_points(sweep.points) if not c.ok}
        print(describe_points(sweep, errors))
        for name, error in errors.items():
            print(f"knotmm: error: point {name}: {error}", file=sys.stderr)
        return 2 if errors else 0
    result = run_sweep(
        sweep,
        workers=args.workers,
        scheduler=args.scheduler,
        progress=args.progress,
        reanalyze=args.reanalyze,
    )
    print(result.report())
    # a point that could not write its files (a full disk): 3, as knotmm run; any other: 1
    unwritten = ("OutputError", "OutputFault", "WriteFault")
    unwritable = [r for r in result.failed if str(r.get("error") or "").startswith(unwritten)]
    if unwritable:
        first = str(unwritable[0]["error"]).split(": ", 1)[-1]
        print(f"knotmm: error: {len(unwritable)} of {len(result.failed)} failed points could "
              f"not write their files ({first}); free the space and run the same command to "
              f"continue the sweep", file=sys.stderr)
        return 3
    return 1 if result.failed else 0
