"""The checks ``knotmm run`` makes before a run starts, made on every point of a sweep.

``knotmm sweep --dry-run`` runs nothing, writes nothing, and reports every point that
``knotmm run`` would refuse (too few beads for the knot, a bad integrator for the Peclet
number, a platform that is not there, ...), with the same one-line message. The checks are
the run path's own: the run plan (:func:`knotmm.plan.prepare`), which
:func:`knotmm.workflow.run` makes before it writes anything (the integrator, the template
with its chains: ``[[chains]]``, links and open filaments, bonds, steric distances, knot
type; then the Simulation on that layout: model, platform, starting positions). See
``docs/architecture.md``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from knotmm.config import RunConfig
from knotmm.errors import KnotmmError
from knotmm.sweep.plan import SweepPoint
from knotmm.sweep.point import error_text

__all__ = ["PointCheck", "check_config", "check_points"]


@dataclass(frozen=True)
class PointCheck:
    """The outcome of the pre-run checks of one point.

    Attributes
    ----------
    point : SweepPoint
    error : str or None
        The one-line message ``knotmm run`` would print for this point's run file (without
        the ``knotmm: error:`` prefix); None when the point can run.
    """

    point: SweepPoint
    error: str | None

    @property
    def ok(self) -> bool:
        """Whether the point passes every check."""
        return self.error is None


def check_config(cfg: RunConfig) -> None:
    """Make the checks ``knotmm run`` makes before it writes anything; raise as it would.

    Parameters
    ----------
    cfg : RunConfig
        A validated run configuration (validation itself is :class:`RunConfig`'s).

    Raises
    ------
    ConfigError, TemplateError, TrajectoryFileError
        The error :func:`knotmm.workflow.run` raises for this configuration before it starts.
    """
    from knotmm.plan import prepare

    prepare(cfg, identify="now")  # run()'s own plan: [[chains]], links, open filaments


def check_points(points: Sequence[SweepPoint]) -> list[PointCheck]:
    """Check every point (:func:`check_config`), never stopping at the first failure.

    Returns
    -------
    list of PointCheck
        One per point, in order.
    """
    checks = []
    for point in points:
        error = None
        try:
            check_config(point.config)
        except KnotmmError as exc:
            error = " ".join(str(exc).split())
        except Exception as exc:  # anything else `knotmm run` would fail on
            error = error_text(exc)
        checks.append(PointCheck(point, error))
    return checks
