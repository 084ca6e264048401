"""The one scheduler of knotmm's reporters: report ``k`` at ``k * interval`` tau_d.

A knotmm reporter has ``next_report_time(simulation) -> float`` (tau_d) and
``report(simulation, state)``; :class:`knotmm.engine.simulation.Simulation` lands its steps
exactly on those times (``docs/architecture.md``). Report times are computed from the
report index, never accumulated, so they do not drift; a resumed run passes the index of its
next report as ``first_index``.
"""

from __future__ import annotations

__all__ = ["TimeScheduled"]


class TimeScheduled:
    """Base class of time-scheduled reporters: reports at ``(first_index + k) * interval``.

    Parameters
    ----------
    interval : float
        Time between reports, in tau_d (> 0).
    first_index : int
        Index of the next report (report ``k`` is at ``k * interval``).

    Attributes
    ----------
    index : int
        Index of the next report; :meth:`advance` after each one.
    """

    def __init__(self, interval: float, first_index: int = 0):
        if not interval > 0:
            raise ValueError(f"interval={interval!r}: must be > 0 (tau_d)")
        self.interval = float(interval)
        self.index = int(first_index)

    def next_report_time(self, simulation) -> float:
        """Time of the next report, in tau_d."""
        return self.index * self.interval

    def advance(self) -> None:
        """Move on to the next report time."""
        self.index += 1
