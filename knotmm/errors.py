"""knotmm's exceptions.

Every error a user can cause by input is a :class:`KnotmmError`; the command line prints its
message as one line and exits with code 2, without a traceback. Messages name the argument or
key, the value given, what was expected, and how to fix it.
"""

from __future__ import annotations


class KnotmmError(Exception):
    """Base class of knotmm's user-facing errors (printed as one line by the CLI)."""

    exit_code = 2


class ConfigError(KnotmmError, ValueError):
    """A run file, sweep file or command-line option is invalid."""


class TemplateError(KnotmmError, ValueError):
    """A knot template cannot be built or would not be a valid start."""


class TrajectoryFileError(KnotmmError, ValueError):
    """A trajectory, topology or run directory is missing, truncated or inconsistent."""


class RunDirectoryError(KnotmmError, FileExistsError):
    """A run directory exists and would be overwritten."""


class SimulationFault(KnotmmError, RuntimeError):
    """The dynamics broke down (non-finite positions, an overstretched bond, a collapsed step).

    Everything written before the fault is kept. Exit code 3.
    """

    exit_code = 3


class KnotTypeChanged(SimulationFault):
    """The knot type changed during a run with ``run.on_topology_change = "stop"``."""
