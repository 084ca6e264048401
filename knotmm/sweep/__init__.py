"""Parameter sweeps and ensembles: many runs, each analysed, collected in one table.

=============================  ================================================================
:mod:`~knotmm.sweep.spec`      the sweep file: schema, validation, :class:`Sweep`
:mod:`~knotmm.sweep.plan`      points, replica seeds, what to skip, analyse, resume or run
:mod:`~knotmm.sweep.check`     the checks ``knotmm run`` makes, on every point (``--dry-run``)
:mod:`~knotmm.sweep.point`     one point: run it, analyse it, its summary values
:mod:`~knotmm.sweep.together`  a point's ``seeds = K`` replicas as one replicated run
:mod:`~knotmm.sweep.local`     executor: local worker processes, with crash recovery
:mod:`~knotmm.sweep.dask`      executor: an existing Dask distributed cluster
:mod:`~knotmm.sweep.runner`    :func:`run_sweep`: plan, execute, write the summary and plots
:mod:`~knotmm.sweep.summary`   ``summary.csv``: columns, rows, reading it back
:mod:`~knotmm.sweep.plots`     plots of the summary against a swept key
=============================  ================================================================

See ``docs/architecture.md``.
"""

from knotmm.sweep.check import PointCheck, check_points
from knotmm.sweep.plan import SweepPoint, expand, point_name, replica_seeds
from knotmm.sweep.point import run_point
from knotmm.sweep.runner import SweepResult, run_sweep
from knotmm.sweep.spec import (
    SWEEP_OPTIONS,
    Sweep,
    SweepOptions,
    describe_points,
    load_sweep_file,
)
from knotmm.sweep.summary import ANALYSIS_COLUMNS, STATUSES, read_summary, summary_values

__all__ = [
    "ANALYSIS_COLUMNS",
    "SWEEP_OPTIONS",
    "STATUSES",
    "PointCheck",
    "Sweep",
    "SweepOptions",
    "SweepPoint",
    "SweepResult",
    "check_points",
    "describe_points",
    "expand",
    "load_sweep_file",
    "point_name",
    "read_summary",
    "replica_seeds",
    "run_point",
    "run_sweep",
    "summary_values",
]
