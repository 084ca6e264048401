"""``knotmm analyze SWEEP_DIR``: mean +- standard error per point over its replicas."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from synthetic import vortex_knot_positions, write_run_directory

from knotmm.analysis.replicas import point_of, replica_statistics
from knotmm.cli.main import main

DT = 0.5
TIMES = np.arange(161) * DT
CONFIG = {"knot": {"kind": "torus", "p": 2, "q": 3}, "model": {"bond_length": 0.6}}
# two points (falling speeds), three replicas each (different noise)
SPEEDS = {"model.speed=6": 6.0, "model.speed=8": 8.0}


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    root = tmp_path_factory.mktemp("sweep")
    (root / "sweep.toml").write_text('[sweep]\n"model.speed" = [6, 8]\nseeds = 3\n')
    for name, speed in SPEEDS.items():
        for k in range(3):
            x = vortex_knot_positions(TIMES, n_beads=60, velocity=speed, noise=0.05, seed=k)
            write_run_directory(root / f"{name},replica={k}", x, DT, CONFIG)
    return root


def test_point_of():
    assert point_of("knot.beads=90,replica=3") == "knot.beads=90"
    assert point_of("replica=12,knot.p=2") == "knot.p=2"
    assert point_of("knot.beads=40") == "knot.beads=40"
    assert point_of("replica=0") == "all"


def test_replica_statistics_against_numpy():
    stats = replica_statistics([{"a": 1.0, "b": None}, {"a": 2.5, "b": 4.0}, {"a": 4.0}])
    a = np.array([1.0, 2.5, 4.0])
    assert stats["a"]["mean"] == pytest.approx(a.mean())
    assert stats["a"]["std_error"] == pytest.approx(a.std(ddof=1) / math.sqrt(3))
    assert stats["b"]["n"] == 1 and stats["b"]["missing"] == 2
    assert stats["b"]["std_error"] is None


def test_analyze_sweep_directory(sweep, capsys):
    assert main(["analyze", str(sweep), "--no-plots", "--knot-samples", "0"]) == 0
    out = capsys.readouterr().out
    summary = json.loads((sweep / "replicas.json").read_text())
    assert list(summary["points"]) == list(SPEEDS)
    for name, speed in SPEEDS.items():
        point = summary["points"][name]
        assert point["runs"] == [f"{name},replica={k}" for k in range(3)]
        # the statistics are those of the replicas' own analysis.json files
        each = [
            json.loads((sweep / run / "analysis.json").read_text())["sedimentation_velocity"]
            for run in point["runs"]
        ]
        v = point["statistics"]["sedimentation_velocity"]
        assert v["values"] == pytest.approx(each)
        assert v["mean"] == pytest.approx(np.mean(each))
        assert v["std_error"] == pytest.approx(np.std(each, ddof=1) / math.sqrt(3))
        assert v["mean"] == pytest.approx(speed, rel=1e-3)
        assert point["statistics"]["tau_swirl_body"]["mean"] == pytest.approx(20.0, rel=0.01)
        assert point["statistics"]["swirl_detected"]["mean"] == 1.0
        assert name in out
    assert "replicas.json" in out
