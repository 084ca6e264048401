"""``knotmm run``: run a simulation from a run file (or the default T(2,3), N = 90)."""

from __future__ import annotations

import argparse
import sys

from knotmm.config import RunConfig, load_run_file, parse_override
from knotmm.errors import ConfigError


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register ``knotmm run``."""
    p = subparsers.add_parser(
        "run",
        help="run a simulation and write a run directory",
        description=(
            "Run overdamped dynamics with Rotne-Prager-Yamakawa hydrodynamics and write a run "
            "directory (trajectory.dcd, topology.pdb, run.toml, observables.csv, view.vmd). "
            "Without a run file: the right-handed T(2,3) with 90 beads, the study's "
            "parameters, 200 tau_d."
        ),
    )
    p.add_argument("run_file", nargs="?", metavar="RUN.toml", help="run file (TOML)")
    p.add_argument("--out", metavar="DIR", help="run directory (default: output.directory)")
    p.add_argument("--duration", type=float, metavar="T",
                   help="simulated time, in tau_d (with --resume: extend the run to T)")
    p.add_argument("--beads", type=int, metavar="N",
                   help="number of beads (knot.beads; not for a [[chains]] run file)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing run directory")
    p.add_argument("--resume", metavar="DIR",
                   help="continue a stopped or killed run from its last checkpoint (a "
                        "finished one with --duration T)")
    p.add_argument("--from", dest="start_from", metavar="RUN",
                   help="a new run (time from 0) started from a frame of RUN: a run directory "
                        "(its trajectory, its chains, and, without RUN.toml, its settings; "
                        "change them with --set), or a PDB or DCD file; needs --out")
    p.add_argument("--frame", type=int, metavar="K",
                   help="with --from: the frame to start from (default -1, the last; 0 the "
                        "first)")
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="TABLE.KEY=VALUE",
        help="override any run-file key, e.g. --set run.integrator=heun (repeatable)",
    )
    bar = p.add_mutually_exclusive_group()
    bar.add_argument("--progress", dest="progress", action="store_true", default=None,
                     help="always show the progress bar")
    bar.add_argument("--no-progress", dest="progress", action="store_false",
                     help="never show the progress bar")
    p.set_defaults(execute=execute)
    return p


def config_from_args(args) -> RunConfig:
    """The run configuration: run file (or defaults) with the command-line overrides."""
    if getattr(args, "start_from", None) is not None:
        cfg = start_from_config(args)
    else:
        if getattr(args, "frame", None) is not None:
            raise ConfigError(f"--frame {args.frame} applies only with --from RUN; add --from "
                              "or leave --frame out")
        cfg = load_run_file(args.run_file) if args.run_file else RunConfig.from_dict({})
    changes = dict(parse_override(text) for text in args.set)
    if args.duration is not None:
        changes["run.duration"] = args.duration
    if args.beads is not None:
        if cfg.chains is not None:  # which chain's count? each [[chains]] entry has its own
            raise ConfigError(
                f"--beads {args.beads}: {args.run_file} gives [[chains]] "
                f"({len(cfg.chains)} chains), each with its own bead count; set beads = N in "
                "each [[chains]] entry of the run file and leave --beads out"
            )
        changes["knot.beads"] = args.beads
    if args.out is not None:
        changes["output.directory"] = args.out
    if changes:
        if (args.beads is not None and "knot.major_radius" not in changes
                and cfg["knot.major_radius"] is not None):
            # a run file's resolved radius belongs to its bead count: let it follow --beads
            data = cfg.to_dict()
            data["knot"].pop("major_radius", None)
            cfg = RunConfig.from_dict(data)
        cfg = cfg.replace(changes)
    return cfg


def start_from_config(args) -> RunConfig:
    """The run configuration of ``knotmm run --from RUN``: a new run from a frame of RUN.

    The settings are those of ``RUN.toml`` when given, else of RUN's ``run.toml`` when RUN
    is a run directory (its model, stepping and output; its ``output.directory`` dropped),
    else the defaults; the start is ``[knot] kind = "file"`` with ``path = RUN`` and
    ``frame`` (``--frame``, default -1): the chains RUN's files hold
    (:mod:`knotmm.shapes.file_start`). ``--set`` and the other options apply after.

    Raises
    ------
    ConfigError
        Without ``--out`` (or a run file's ``output.directory``), with ``--beads`` (the file
        fixes the beads), or when the new run would be written into RUN itself.
    """
    from pathlib import Path  # noqa: PLC0415

    from knotmm.io.rundir import RUN_FILE, TOPOLOGY_FILE, TRAJECTORY_FILE  # noqa: PLC0415

    source = Path(args.start_from)
    if args.beads is not None:
        raise ConfigError(f"--beads {args.beads}: --from {args.start_from} starts from a frame "
                          "of that run, which fixes the beads; leave --beads out")
    if not source.exists():
        raise ConfigError(f"--from {args.start_from!r}: no such run directory or file")
    if source.is_dir():
        run_dir = source
    elif source.name in (TRAJECTORY_FILE, TOPOLOGY_FILE) and (source.parent / RUN_FILE).is_file():
        run_dir = source.parent  # a run's own file: that run's settings
    else:
        run_dir = None
    if source.is_dir() and not (source / TRAJECTORY_FILE).is_file():
        raise ConfigError(
            f"--from {args.start_from!r} is a directory without {TRAJECTORY_FILE}: give a run "
            "directory (for a replica set, one replica_K), a PDB or a DCD file"
        )
    out_given = args.out is not None or any(
        text.partition("=")[0].strip() == "output.directory" for text in args.set)
    if args.run_file:
        data = load_run_file(args.run_file).to_dict()
    elif run_dir is not None and (run_dir / RUN_FILE).is_file():
        data = load_run_file(run_dir / RUN_FILE).to_dict()
        data.get("output", {}).pop("directory", None)  # never the source's own directory
        if not out_given:
            raise ConfigError(
                f"--from {args.start_from}: give --out DIR for the new run (its settings are "
                f"{args.start_from}'s, whose output.directory is that run itself)"
            )
    else:
        data = {}
    if not out_given and "directory" not in data.get("output", {}):
        raise ConfigError(f"--from {args.start_from}: give --out DIR for the new run")
    data.pop("chains", None)
    data["knot"] = {"kind": "file", "path": str(source.resolve()),
                    "frame": -1 if args.frame is None else args.frame}
    cfg = RunConfig.from_dict(data)
    target = Path(args.out if args.out is not None else cfg["output.directory"])
    if run_dir is not None and target.exists() and target.resolve() == run_dir.resolve():
        raise ConfigError(f"--out {str(target)!r} is where --from {args.start_from} lies; give "
                          "another directory for the new run")
    return cfg


def knot_lines(facts: dict) -> list[str]:
    """What ``knotmm run`` prints about the knot checks: the changes line and the note for the
    summary line.

    Parameters
    ----------
    facts : dict
        The ``[knotmm]`` table of run.toml (``knot_type_changes``: dicts with ``time`` in
        tau_d, ``from``, ``to``; ``knot_type_checks_dropped``; ``notes``).

    Returns
    -------
    list of str
        ``[changes, not_made]``, each ``""`` when there is nothing to say: ``changes`` lists
        every change of knot type in order, ``"knot type changed: +5_2 -> -8_20 at t = 30,
        -8_20 -> +9_24 at t = 100 tau_d"``; ``not_made`` says how many checks were not made
        (the knot worker had not started topoly when the run ended) and that ``knotmm
        analyze`` makes them.
    """
    from knotmm.engine.knot_checks import checks_not_made

    # the phrase of knotmm.analysis.knot_types.describe_changes, without importing the analysis
    # (half a second after the run, when a Ctrl-C would be taken for an interrupted run)
    changes = [f"{c['from']} -> {c['to']} at t = {float(c['time']):g}"
               for c in facts.get("knot_type_changes", []) or []]
    first = f"knot type changed: {', '.join(changes)} tau_d" if changes else ""
    dropped, template = checks_not_made(facts)
    parts = []
    if dropped:
        parts.append(f"{dropped} knot-type check{'s' if dropped != 1 else ''}")
    if template:
        parts.append("the template's knot-type check")
    not_made = ""
    if parts:
        them = "them" if dropped + template > 1 else "it"
        not_made = (f"{' and '.join(parts)} not made (topoly had not started when the run "
                    f"ended): knotmm analyze makes {them}")
    return [first, not_made]


def _report(result) -> None:
    """Print the knot-type changes, then the one-line summary (with any checks not made).

    The run is finished and its directory complete: a Ctrl-C now (SIGINT, SIGTERM) stops
    only this report, with one line on stderr, and ``knotmm run`` still exits 0.
    """
    import sys

    from knotmm.io.rundir import read_facts

    try:
        try:
            facts = read_facts(result.directory)
        except Exception:  # the summary must not fail for run.toml  # noqa: BLE001
            facts = {}
        changes, not_made = knot_lines(facts)
        sys.stderr.flush()  # the run's own warnings first, then these lines in order
        if changes:
            print(changes)
        print(result.summary() + (f"; {not_made}" if not_made else ""), flush=True)
    except KeyboardInterrupt:
        print(f"knotmm: interrupted after the run finished: {result.directory} is complete",
              file=sys.stderr)


def execute(args) -> int:
    """Run and print the knot-type changes and the one-line summary.

    The knot worker starts as soon as the input is read (before the imports of the run's
    modules), so that topoly's import (about 1.5 s in its own process) overlaps all of the
    run's start and a short run's last checks wait for it less (:func:`start_worker`).
    """
    from knotmm.knots.identify import start_worker

    if args.resume:
        given = [o for o, v in (("RUN.toml", args.run_file), ("--out", args.out),
                                ("--beads", args.beads), ("--set", args.set),
                                ("--overwrite", args.overwrite),
                                ("--from", args.start_from),
                                ("--frame", args.frame is not None)) if v]
        if given:
            raise ConfigError(
                f"--resume takes no other run options but --duration (got "
                f"{', '.join(given)}): a resumed run keeps the parameters in its run.toml"
            )
    else:
        cfg = config_from_args(args)
    start_worker()
    from knotmm.engine.interrupt import stop_between_steps
    from knotmm.replicas import identical_replicas_note, resume_replicas, run_replicas

    if args.resume:
        # Ctrl-C / SIGTERM: finish the step, checkpoint that state, then stop (exit 130)
        with stop_between_steps():  # a signal once the run is recorded: no stop left to make
            result = resume_replicas(args.resume, progress=args.progress,
                                     duration=args.duration)
            _report(result)
        return 3 if getattr(result, "errors", None) else 0  # a replica broke down
    identical = identical_replicas_note(cfg, int(cfg["run.replicas"]))
    if identical:
        print(f"knotmm: note: {identical}", file=sys.stderr)
    with stop_between_steps():
        result = run_replicas(cfg, overwrite=args.overwrite, progress=args.progress)
        _report(result)
    return 3 if getattr(result, "errors", None) else 0  # a replica broke down
