"""The ``knotmm`` command: a thin dispatcher over :mod:`knotmm.cli`.

Each sub-command lives in its own module under ``knotmm/cli/`` and provides
``add_parser(subparsers)`` and ``execute(args) -> int``. User errors
(:class:`knotmm.errors.KnotmmError`) are printed as one line, ``knotmm: error: ...``, and
exit with the error's code (2 for bad input) and no traceback.

``-v/--verbose`` and ``-q/--quiet`` belong to every sub-command, before or after its name
(one parent parser, :func:`common_options`, given to ``knotmm`` and each sub-parser): ``-v``
logs knotmm's debug messages, ``-q`` shows only warnings and errors (no summary on standard
output, no progress).
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import importlib
import logging
import os
import sys
import time

from knotmm import __version__
from knotmm.errors import KnotmmError

log = logging.getLogger("knotmm.cli")

#: Sub-command name -> module under knotmm.cli.
COMMANDS = ("run", "template", "analyze", "orbit", "sweep", "movie")
#: Other spellings of a sub-command (alias -> command): the docs' British ``analyse``.
ALIASES = {"analyse": "analyze"}


def common_options() -> argparse.ArgumentParser:
    """The options of ``knotmm`` and of every sub-command: ``-v/--verbose``, ``-q/--quiet``.

    A parent parser (``parents=[...]``). The options are left out of the namespace when not
    given (``argparse.SUPPRESS``), so that a sub-parser does not reset what was given
    before the sub-command's name.
    """
    common = argparse.ArgumentParser(add_help=False)
    group = common.add_argument_group("output")
    group.add_argument("-v", "--verbose", action="store_true", default=argparse.SUPPRESS,
                       help="also show knotmm's debug messages")
    group.add_argument("-q", "--quiet", action="store_true", default=argparse.SUPPRESS,
                       help="show only warnings and errors (no summary, no progress)")
    return common


def version_report() -> str:
    """What ``knotmm --version`` prints: the installation, as OpenMM's ``testInstallation``.

    knotmm's version and Python's; OpenMM's version; whether the compiled RPY plugin loaded
    (:func:`knotmm.plugin.available`) or why not (:func:`knotmm.plugin.load_error`); the
    OpenMM platforms that loaded, those the plugin has its kernel on
    (:func:`knotmm.engine.engines.plugin_platforms`) and why a platform's plugin library did
    not load; the OpenMM platform libraries that failed to load.
    """
    import platform
    import re

    import openmm

    from knotmm import plugin

    lines = [f"knotmm {__version__} (Python {platform.python_version()}, {sys.platform})",
             f"OpenMM {openmm.version.full_version}"]
    if plugin.available():
        lines.append(f"plugin: loaded (RPYIntegrator: {', '.join(plugin.METHODS)})")
    else:
        why = (plugin.load_error() or "unknown reason").removeprefix("knotmm.plugin: ")
        lines.append(f"plugin: not loaded ({why}); runs use the Python engine")
    from knotmm.engine.engines import platform_names, plugin_platforms

    names = platform_names()
    lines.append(f"platforms: {', '.join(names) or 'none'}")
    if plugin.available():
        lines.append(f"plugin runs on: {', '.join(plugin_platforms()) or 'none'}")
        for name, why in plugin.platform_load_errors().items():
            lines.append(f"plugin not on {name}: {why}")
    failed: dict[str, list[str]] = {}  # why -> the OpenMM plugin libraries that failed so
    for failure in openmm.Platform.getPluginLoadFailures():
        text = " ".join(str(failure).split())
        m = re.search(r"lib(?:OpenMM)?(\w+)\.(?:so|dylib|dll)\S*: (.*)$", text)
        name, why = (m.group(1), m.group(2)) if m else ("a plugin", text)
        failed.setdefault(why, []).append(name)
    for why, libraries in failed.items():
        lines.append(f"OpenMM plugins not loaded: {', '.join(libraries)} ({why})")
    return "\n".join(lines)


class _VersionAction(argparse.Action):
    """``--version``: print :func:`version_report` (imports OpenMM only when asked) and exit."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS,
                 help=None):
        super().__init__(option_strings=option_strings, dest=dest, default=default, nargs=0,
                         help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        try:
            print(version_report(), flush=True)
        except BrokenPipeError:  # `knotmm --version | head -1`
            _drop_stdout()
        parser.exit()


def _drop_stdout() -> None:
    """Standard output's reader has gone (a pager or ``head`` closed early): send the rest to
    /dev/null, so that Python's flush at exit raises nothing."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())


class _Parser(argparse.ArgumentParser):
    """``knotmm``'s parser: an unknown sub-command's error line says the nearest names."""

    def error(self, message):
        import difflib
        import re

        m = re.match(r"argument COMMAND: invalid choice: '(.*?)' \(", message)
        if m:
            near = difflib.get_close_matches(m.group(1), [*COMMANDS, *ALIASES], n=3, cutoff=0.6)
            near = list(dict.fromkeys(ALIASES.get(n, n) for n in near))  # an alias: its command
            hint = f"did you mean {' or '.join(repr(n) for n in near)}? " if near else ""
            message = (f"unknown command {m.group(1)!r}: {hint}the commands are "
                       f"{', '.join(COMMANDS)} (knotmm COMMAND -h for one)")
        super().error(message)


class _Registrar:
    """The sub-parsers as a sub-command module sees them: its aliases (:data:`ALIASES`) added."""

    def __init__(self, sub):
        self._sub = sub

    def add_parser(self, name, **kwargs):
        aliases = [a for a, command in ALIASES.items() if command == name]
        if aliases:
            kwargs.setdefault("aliases", aliases)
        return self._sub.add_parser(name, **kwargs)


def build_parser() -> argparse.ArgumentParser:
    """Build the argument parser with every available sub-command."""
    common = common_options()
    parser = _Parser(
        prog="knotmm",
        description="Simulate and analyse knotted filaments sedimenting at low Reynolds number.",
        parents=[common],
    )
    parser.add_argument("--version", action=_VersionAction,
                        help="show knotmm's and OpenMM's versions, whether the compiled "
                        "plugin loaded (or why not) and OpenMM's platforms, and exit")
    sub = parser.add_subparsers(
        dest="command",
        metavar="COMMAND",
        parser_class=functools.partial(argparse.ArgumentParser, parents=[common]),
    )
    sub.required = True
    for name in COMMANDS:
        try:
            module = importlib.import_module(f"knotmm.cli.{name}")
        except ModuleNotFoundError as exc:  # a command not built yet
            if exc.name != f"knotmm.cli.{name}":
                raise
            continue
        module.add_parser(_Registrar(sub))
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
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return code


def _verbosity(parser: argparse.ArgumentParser, args) -> tuple[bool, bool]:
    """``(verbose, quiet)`` from the parsed arguments; both at once is a usage error."""
    verbose = bool(getattr(args, "verbose", False))
    quiet = bool(getattr(args, "quiet", False))
    if verbose and quiet:
        parser.error("-v/--verbose and -q/--quiet exclude each other; give one")
    args.verbose, args.quiet = verbose, quiet
    return verbose, quiet


@contextlib.contextmanager
def _output(verbose: bool, quiet: bool):
    """knotmm's log level (and, quiet, standard output discarded) while a command runs.

    The root logger gets a handler on standard error at WARNING (``logging.basicConfig``,
    which keeps handlers already there, e.g. pytest's); the ``knotmm`` logger is set to
    DEBUG (verbose) or WARNING (quiet) and put back afterwards, so that a call of
    :func:`main` leaves the logging of its caller as it was.
    """
    logging.basicConfig(level=logging.WARNING, format="knotmm: %(message)s")
    package = logging.getLogger("knotmm")
    level = package.level
    if verbose:
        package.setLevel(logging.DEBUG)
    elif quiet:
        package.setLevel(logging.WARNING)
    try:
        if quiet:
            with open(os.devnull, "w") as devnull, contextlib.redirect_stdout(devnull):
                yield
        else:
            yield
    finally:
        package.setLevel(level)


def _dispatch(argv: list[str] | None) -> int:
    try:  # the sub-commands' imports take a second: a stop asked for then is no traceback
        parser = build_parser()
        args = parser.parse_args(argv)
        args.command = ALIASES.get(args.command, args.command)
    except KeyboardInterrupt:
        print("knotmm: interrupted while starting; nothing was written", file=sys.stderr)
        return 130
    verbose, quiet = _verbosity(parser, args)
    if quiet and getattr(args, "progress", None) is None:
        args.progress = False  # no bar and no progress lines (an explicit --progress wins)
    with _output(verbose, quiet):
        return _execute(args)


_KEPT = "files written so far are kept"
#: What an interrupted command leaves and how it goes on (the one line of exit code 130).
_AFTER_INTERRUPT = {
    "run": f"{_KEPT} (a run continues with knotmm run --resume DIR)",
    "sweep": f"{_KEPT}; the same knotmm sweep command continues the sweep",
    "analyze": "each file of the analysis is written whole or not at all: run knotmm "
               "analyze again",
    "movie": "no movie is left half-written: run knotmm movie again",
}


def _execute(args) -> int:
    """Run the parsed command; user errors and interruptions become exit codes."""
    import platform

    wall0 = time.monotonic()
    log.debug("version %s, Python %s, %s", __version__, platform.python_version(), sys.platform)
    options = {k: v for k, v in vars(args).items() if k not in ("execute", "command")}
    log.debug("%s: %s", args.command, ", ".join(f"{k}={v!r}" for k, v in options.items()))
    code = 1
    try:
        code = int(args.execute(args) or 0)
        return code
    except KnotmmError as exc:
        print(f"knotmm: error: {exc}", file=sys.stderr)
        code = exc.exit_code
        return code
    except KeyboardInterrupt:
        print(f"knotmm: interrupted; {_AFTER_INTERRUPT.get(args.command, _KEPT)}",
              file=sys.stderr)
        code = 130
        return code
    except BrokenPipeError:  # output piped into a pager or `head` that closed early
        _drop_stdout()
        code = 0
        return code
    finally:
        log.debug("%s: exit code %d after %.2f s", args.command, code,
                  time.monotonic() - wall0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(console_main())
