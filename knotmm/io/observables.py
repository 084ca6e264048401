"""``observables.csv``: its columns, and cutting it back to a checkpoint's row count.

The table has a header line and one row per report time; the engine's
:class:`knotmm.engine.reporters.ObservablesReporter` writes it (``docs/architecture.md``).
"""

from __future__ import annotations

import os
from pathlib import Path

from knotmm.errors import TrajectoryFileError
from knotmm.model.forces import FORCE_GROUPS

__all__ = ["ENERGY_TERMS", "OBSERVABLE_COLUMNS", "truncate_csv"]

#: The energy terms of a row, then their sum ``"total"``: the model's force groups
#: (:data:`knotmm.model.forces.FORCE_GROUPS`: bond, bend, steric, gravity).
ENERGY_TERMS: tuple[str, ...] = (*FORCE_GROUPS, "total")

#: Columns of ``observables.csv`` (times in tau_d, lengths in d, energies in F0 d): time,
#: step, com_x, com_y, com_z, e_bond, e_bend, e_steric, e_gravity, e_total, max_bond,
#: timestep, evaluations. Files already written read by these names: a new force group adds
#: a column before ``e_total``.
OBSERVABLE_COLUMNS: tuple[str, ...] = (
    "time",
    "step",
    "com_x",
    "com_y",
    "com_z",
    *(f"e_{term}" for term in ENERGY_TERMS),
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
        data = fh.read()
    lines = data.split(b"\n")
    complete = lines[: n_rows + 1]
    if len(complete) < n_rows + 1 or any(not line for line in complete):
        raise TrajectoryFileError(
            f"observables {str(path)!r} hold fewer rows than the checkpoint counts ({n_rows})"
        )
    end = sum(len(line) + 1 for line in complete)
    with open(path, "r+b") as fh:  # cut, never rewritten: a full disk loses no row
        fh.truncate(min(end, len(data)))
        if end > len(data):  # the last row kept had lost its line end
            fh.seek(0, os.SEEK_END)
            fh.write(b"\n")
        os.fsync(fh.fileno())
