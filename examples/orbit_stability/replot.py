"""Redraw this example's continuation figures from the saved results, without recomputing.

``knotmm orbit --continue`` draws ``continuation.png`` beside its ``continuation.csv`` and
``continuation.json`` after every point; this script draws the same figure again, with the
installed knotmm's drawing (:func:`knotmm.orbit.output.write_branch`'s), from the files in
``results/``:

* ``continuation.png`` from ``continuation.json`` (its points and its bifurcations);
* ``beads_continuation.png`` from ``beads_continuation.csv`` (only the CSV was kept: the
  changes of stability are found again from its multipliers, as ``knotmm orbit`` finds them
  for a discrete parameter, :func:`knotmm.orbit.continuation.find_bifurcations`);
* ``exponent_vs_N.png`` from ``exponent_vs_N.csv`` (``exponent_vs_N.plot_exponents``).

Usage::

    python examples/orbit_stability/replot.py [--results DIR]

Takes about 2 s. Units: as in the files (tau_d, F0 d, rad).
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np

RESULTS = Path(__file__).resolve().parent / "results"


def _number(text: str):
    """A CSV cell as a float (int for the counts), None when empty."""
    if text == "":
        return None
    value = float(text)
    return int(value) if value.is_integer() and "." not in text else value


def read_rows(path: Path) -> tuple[str, list[dict]]:
    """The continued key and the rows of a ``continuation.csv``."""
    with path.open(newline="") as fh:
        reader = csv.DictReader(fh)
        rows = [{k: _number(v) for k, v in row.items()} for row in reader]
    return reader.fieldnames[0], rows


def discrete_bifurcations(key: str, rows: list[dict]) -> list:
    """The changes of stability between neighbouring rows, as ``knotmm orbit`` reports them
    for a discrete parameter (from the rows' multipliers, moduli and angles)."""
    from knotmm.orbit.continuation import ContinuationPoint, find_bifurcations
    from knotmm.orbit.floquet import FloquetResult

    branch = []
    for row in rows:
        mu = []
        k = 1
        while f"mu{k}_abs" in row:
            if row[f"mu{k}_abs"] is not None:
                mu.append(row[f"mu{k}_abs"] * np.exp(1j * row[f"mu{k}_arg"]))
            k += 1
        floquet = FloquetResult(np.array(mu), np.empty((0,)), np.empty(0), [],
                                row["period"], 0)
        branch.append(ContinuationPoint(row[key], None, floquet))
    return find_bifurcations(branch, discrete=True)


def draw(path: Path, key: str, rows: list[dict], bifurcations) -> Path:
    """Write the continuation figure of ``rows`` to ``path`` as ``knotmm orbit`` draws it."""
    from knotmm.orbit.output import _plot_branch

    _plot_branch(path, key, rows, bifurcations)
    return path


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--results", type=Path, default=RESULTS,
                        help="folder of continuation.json and beads_continuation.csv")
    args = parser.parse_args(argv)
    saved = json.loads((args.results / "continuation.json").read_text())
    marks = [SimpleNamespace(value=b["parameter"]) for b in saved["bifurcations"]]
    print("wrote", draw(args.results / "continuation.png", saved["parameter"],
                        saved["points"], marks))
    key, rows = read_rows(args.results / "beads_continuation.csv")
    print("wrote", draw(args.results / "beads_continuation.png", key, rows,
                        discrete_bifurcations(key, rows)))
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from exponent_vs_N import plot_exponents

    with (args.results / "exponent_vs_N.csv").open(newline="") as fh:
        exponents = list(csv.DictReader(fh))
    print("wrote", plot_exponents(exponents, args.results / "exponent_vs_N.png"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
