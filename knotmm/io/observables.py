"""``observables.csv``: its columns, and cutting it back to a checkpoint's row count.

The table has a header line and one row per report time; the engine's
:class:`knotmm.engine.reporters.ObservablesReporter` writes it (``docs/architecture.md``).
"""

from __future__ import annotations

import os
from pathlib import Path

from knotmm.errors import TrajectoryFileError

__all__ = ["OBSERVABLE_COLUMNS", "truncate_csv"]

#: Columns of ``observables.csv`` (times in tau_d, lengths in d, energies in F0 d).
OBSERVABLE_COLUMNS = (
    "time",
    "step",
    "com_x",
    "com_y",
    "com_z",
    "e_bond",
    "e_bend",
    "e_steric",
    "e_gravity",
    "e_total",
    "max_bond",
    "timestep",
    "evaluations",
)


def truncate_csv(path, n_rows: int) -> None:
    """Keep the header and the first ``n_rows`` data rows of a CSV file.

    Raises
    ------
    TrajectoryFileError
        The file is missing or holds fewer whole rows.
    """
    path = Path(path)
    if not path.exists():
        raise TrajectoryFileError(f"observables {str(path)!r} are missing; cannot resume")
    with open(path, "rb") as fh:
        lines = fh.read().split(b"\n")
    complete = lines[: n_rows + 1]
    if len(complete) < n_rows + 1 or any(not line for line in complete):
        raise TrajectoryFileError(
            f"observables {str(path)!r} hold fewer rows than the checkpoint counts ({n_rows})"
        )
    with open(path, "wb") as fh:
        fh.write(b"\n".join(complete) + b"\n")
        fh.flush()
        os.fsync(fh.fileno())
