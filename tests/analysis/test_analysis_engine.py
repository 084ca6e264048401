"""End to end: a real (short) T(2,3) run from the engine, analysed. Slow: run with -m slow."""

from __future__ import annotations

import json

import pytest

pytestmark = pytest.mark.slow


def test_engine_run_analysed(tmp_path, capsys):
    pytest.importorskip("knotmm.cli.run")
    from knotmm.cli.main import main

    run = tmp_path / "trefoil"
    assert main(["run", "--duration", "100", "--out", str(run), "--no-progress"]) == 0
    assert main(["analyze", str(run), "--knot-samples", "5"]) == 0
    d = json.loads((run / "analysis.json").read_text())
    # the periodic state is reached after a transient and holds to the end of this run
    assert 10.0 < d["window"][0] < 60.0 and d["window"][1] == 100.0
    assert d["p_detected"] == 2 and d["q_detected"] == 3
    assert d["sedimentation_velocity"] > 0
    assert d["major_radius"] == pytest.approx(d["major_radius_geometric"], rel=0.03)
    assert 0 < d["swirl_amplitude"] < 0.2 * d["major_radius"]
    # the three time scales are well separated
    assert d["tau_sed"] < d["tau_swirl"] < d["tau_rot"]
    assert d["fit"]["tau_swirl"] == pytest.approx(d["tau_swirl"], rel=0.01)
    assert d["fit_quality"]["r2"] > 0.9
    assert d["handedness"] == "right" and d["writhe"] > 2.5
    assert d["rotation_sense"] in ("clockwise", "counterclockwise")
    if d["knot_type_start"] is not None:
        assert d["knot_type_start"] == d["knot_type_end"] == "+3_1"
        assert d["knot_type_changed_at"] is None
