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
    """Run and print the knot-type changes and the one-line summary."""
    from knotmm.engine.interrupt import stop_between_steps
    from knotmm.replicas import identical_replicas_note
    from knotmm.replicas import resume_replicas as resume
    from knotmm.replicas import run_replicas as run

    if args.resume:
        given = [o for o, v in (("RUN.toml", args.run_file), ("--out", args.out),
                                ("--beads", args.beads), ("--set", args.set),
                                ("--overwrite", args.overwrite)) if v]
        if given:
            raise ConfigError(
                f"--resume takes no other run options but --duration (got "
                f"{', '.join(given)}): a resumed run keeps the parameters in its run.toml"
            )
        # Ctrl-C / SIGTERM: finish the step, checkpoint that state, then stop (exit 130)
        with stop_between_steps():  # a signal once the run is recorded: no stop left to make
            result = resume(args.resume, progress=args.progress, duration=args.duration)
            _report(result)
        return 3 if getattr(result, "errors", None) else 0  # a replica broke down
    cfg = config_from_args(args)
    identical = identical_replicas_note(cfg, int(cfg["run.replicas"]))
    if identical:
        print(f"knotmm: note: {identical}", file=sys.stderr)
    with stop_between_steps():
        result = run(cfg, overwrite=args.overwrite, progress=args.progress)
        _report(result)
    return 3 if getattr(result, "errors", None) else 0  # a replica broke down
