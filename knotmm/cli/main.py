"""The ``knotmm`` command: a thin dispatcher over :mod:`knotmm.cli`.

Each sub-command lives in its own module under ``knotmm/cli/`` and provides
``add_parser(subparsers)`` and ``execute(args) -> int``. User errors
(:class:`knotmm.errors.KnotmmError`) are printed as one line, ``knotmm: error: ...``, and
exit with the error's code (2 for bad input) and no traceback.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys

from knotmm import __version__
from knotmm.errors import KnotmmError

#: Sub-command name -> module under knotmm.cli.
COMMANDS = ("run", "template", "analyze", "orbit", "sweep", "movie")


def build_parser() -> argparse.ArgumentParser:
    """Build the argument parser with every available sub-command."""
    parser = argparse.ArgumentParser(
        prog="knotmm",
        description="Simulate and analyse knotted filaments sedimenting at low Reynolds number.",
    )
    parser.add_argument("--version", action="version", version=f"knotmm {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress details")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMANDS:
        try:
            module = importlib.import_module(f"knotmm.cli.{name}")
        except ModuleNotFoundError as exc:  # a command not built yet
            if exc.name != f"knotmm.cli.{name}":
                raise
            continue
        module.add_parser(sub)
    return parser


def _terminate(signum, frame):
    """SIGTERM (a batch system ending a job) stops a run like Ctrl-C: status recorded."""
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    """Run one knotmm command (``argv`` as on the command line); return its exit code."""
    import signal
    import threading

    previous = None
    if threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGTERM, _terminate)
    try:
        return _dispatch(argv)
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def console_main() -> int:
    """The ``knotmm`` console script: :func:`main`, then a quiet interpreter shutdown.

    Once the command has returned, its files are closed; Ctrl-C or SIGTERM arriving while
    Python shuts down (joining helper processes) then ends the process without a traceback.
    """
    import signal

    try:
        code = main()
    except KeyboardInterrupt:  # a signal between two of main's handlers
        print("knotmm: interrupted", file=sys.stderr)
        code = 130
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if code == 130:
        # Stopped by a signal: every file is closed and run.toml written. Python's own
        # teardown of the loaded libraries takes 1-3 s more on a loaded machine; a user (or a
        # batch system) asking to stop expects the process gone within a second.
        import os

        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return code


def _dispatch(argv: list[str] | None) -> int:
    try:  # the sub-commands' imports take a second: a stop asked for then is no traceback
        parser = build_parser()
        args = parser.parse_args(argv)
    except KeyboardInterrupt:
        print("knotmm: interrupted while starting; nothing was written", file=sys.stderr)
        return 130
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="knotmm: %(message)s",
    )
    try:
        return int(args.execute(args) or 0)
    except KnotmmError as exc:
        print(f"knotmm: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print("knotmm: interrupted; files written so far are kept (a run continues with "
              "knotmm run --resume DIR)", file=sys.stderr)
        return 130
    except BrokenPipeError:  # output piped into a pager or `head` that closed early
        import os

        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(console_main())
