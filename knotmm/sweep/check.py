"""The checks ``knotmm run`` makes before a run starts, made on every point of a sweep.

``knotmm sweep --dry-run`` runs nothing, writes nothing, and reports every point that
``knotmm run`` would refuse (too few beads for the knot, a bad integrator for the Peclet
number, a platform that is not there, ...), with the same one-line message. The checks are
the run path's own functions, in its order: the integrator
(:func:`knotmm.dynamics.registry.integrator_from_config`), the template
(:func:`knotmm.shapes.build_template`: bonds, steric distances, knot type) and the
Simulation (:meth:`knotmm.engine.simulation.Simulation.from_config`: model, platform,
starting positions). See ``docs/architecture.md``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from knotmm.config import RunConfig, resolve_stepping
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
    from knotmm.dynamics.registry import integrator_from_config
    from knotmm.engine.simulation import Simulation
    from knotmm.shapes import build_template

    name, timestep = resolve_stepping(cfg)
    cfg = cfg.replace({"run.integrator": name, "run.timestep": timestep})
    integrator_from_config(cfg)  # as run(): the integrator is checked before the template
    template = build_template(cfg)
    if template.resolved:
        cfg = cfg.replace(template.resolved)
    Simulation.from_config(cfg, template.positions)


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
