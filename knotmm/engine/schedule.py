"""The one scheduler of knotmm's reporters: report ``k`` at ``k * interval`` tau_d.

A knotmm reporter has ``next_report_time(simulation) -> float`` (tau_d) and
``report(simulation, state)``; :class:`knotmm.engine.simulation.Simulation` lands its steps
exactly on those times (``docs/architecture.md``). Report times are computed from the
report index, never accumulated, so they do not drift; a resumed run passes the index of its
next report as ``first_index``.

:func:`landing_slack` is the one landing rule: a step that ends within it of a report time
has landed on that time (the Python engine, the plugin engine, and the plugin's ``stepTo``
in C++, ``rpyplugin.landingSlack``, all use it).
"""

from __future__ import annotations

import math

__all__ = ["TimeScheduled", "landing_slack"]

#: Relative tolerance of the landing rule (:func:`landing_slack`).
LANDING_RELATIVE = 1e-9


def landing_slack(t: float) -> float:
    """How close to time ``t`` (tau_d) a state must be to count as being at ``t``.

    ``1e-9 max(1, |t|)``: relative 1e-9, absolute 1e-9 tau_d near 0; 0 for an infinite
    ``t`` (no report is due at infinity). The same rule as the plugin's ``stepTo``
    (``knotmm.plugin.rpyplugin.landingSlack``, equal for finite ``t``): a report time
    ``t_next`` has come when ``t_next <= time + landing_slack(time)``, and a step that
    ends within ``landing_slack(target)`` of its target has landed on it.

    Parameters
    ----------
    t : float
        A time, in tau_d.

    Returns
    -------
    float
        The tolerance, in tau_d.
    """
    return LANDING_RELATIVE * max(1.0, abs(t)) if math.isfinite(t) else 0.0


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
