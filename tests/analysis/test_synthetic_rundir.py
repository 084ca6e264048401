"""The synthetic runs the analysis tests read are what ``knotmm run`` writes (issue 31).

They are written by the run's own writers (one DCD writer, ``write_pdb``, ``write_run_toml``,
the observables reporter), and they are test data: not shipped in the package.
"""

from __future__ import annotations

import csv
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from synthetic import vortex_knot_positions, write_run_directory

import knotmm
from knotmm.config import RunConfig, load_run_file, read_toml
from knotmm.engine.reporters import DCDReporter
from knotmm.io.dcd import write_dcd
from knotmm.io.observables import OBSERVABLE_COLUMNS
from knotmm.io.pdb import write_pdb
from knotmm.io.run_data import load_run
from knotmm.model.topology import bead_topology

#: The header's second title line holds DCDFile's creation date ("Created <asctime>").
_DATE = slice(180, 260)
DT = 0.5


def _masked(data: bytes) -> bytes:
    out = bytearray(data)
    out[_DATE] = bytes(_DATE.stop - _DATE.start)
    return bytes(out)


def _synthetic(tmp_path):
    x = vortex_knot_positions(np.arange(9) * DT, n_beads=30, noise=0.01)
    config = {"knot": {"kind": "torus", "p": 2, "q": 3}, "model": {"bond_length": 0.6}}
    return x, write_run_directory(tmp_path / "run", x, DT, config)


def test_the_trajectory_is_the_run_reporters_file(tmp_path):
    x, run = _synthetic(tmp_path)
    reporter = DCDReporter(tmp_path / "reporter.dcd", DT, bead_topology(30))
    for frame in x:
        reporter.report(SimpleNamespace(positions=frame), None)
    reporter.close()
    want = (tmp_path / "reporter.dcd").read_bytes()
    assert _masked((run / "trajectory.dcd").read_bytes()) == _masked(want)
    write_dcd(tmp_path / "orbit.dcd", x, DT)  # the orbit's files: the same writer
    assert _masked((tmp_path / "orbit.dcd").read_bytes()) == _masked(want)


def test_topology_run_file_and_observables_are_the_runs(tmp_path):
    x, run = _synthetic(tmp_path)
    write_pdb(tmp_path / "top.pdb", x[0])
    assert (run / "topology.pdb").read_text() == (tmp_path / "top.pdb").read_text()
    cfg = load_run_file(run / "run.toml")  # a valid run file, every key resolved
    tables = read_toml(run / "run.toml")
    assert {k: v for k, v in tables.items() if k != "knotmm"} == cfg.to_dict()
    assert set(cfg.to_dict()) == set(RunConfig.from_dict({}).to_dict())
    assert cfg["knot.beads"] == 30 and cfg["run.duration"] == 8 * DT
    assert tables["knotmm"]["version"] == "synthetic"
    with open(run / "observables.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    assert tuple(rows[0]) == OBSERVABLE_COLUMNS and len(rows) == 1 + len(x)
    data = load_run(run)
    np.testing.assert_allclose(data.positions, x, atol=1e-4)


def test_the_fixtures_are_not_in_the_package():
    package = Path(knotmm.__file__).parent
    assert not list(package.rglob("synthetic*.py"))
