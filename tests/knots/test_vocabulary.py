"""One chirality vocabulary from template to analysis: a left-handed knot is "-5_1" everywhere."""

from __future__ import annotations

import json

import numpy as np
import pytest
from synthetic import vortex_knot_positions, write_run_directory

from knotmm.cli.main import main
from knotmm.knots.identify import topoly_available

needs_topoly = pytest.mark.skipif(not topoly_available(), reason="topoly not installed")


@needs_topoly
def test_analyze_prints_a_left_handed_cinquefoil_with_its_sign(tmp_path, capsys):
    """The mirrored T(2,5) (a left-handed 5_1, writhe < 0) is "-5_1" in the table and
    analysis.json, and its handedness is "left"."""
    times = np.arange(201) * 0.5
    x = vortex_knot_positions(
        times, n_beads=120, p=2, q=5, rho0=5.7, swirl_amplitude=0.4, tau_swirl=14.0,
        tau_rot=250.0, velocity=8.5, mirror=True, noise=0.02,
    )
    config = {"knot": {"kind": "torus", "p": 2, "q": 5, "mirror": True}}
    run = write_run_directory(tmp_path / "run", x, 0.5, config)
    assert main(["analyze", str(run), "--knot-samples", "2", "--no-plots"]) == 0
    out = capsys.readouterr().out
    knot_row = next(line for line in out.splitlines() if line.startswith("knot type"))
    assert knot_row.split()[2] == "-5_1", out
    assert "handedness left" in out and "right" not in out
    result = json.loads((run / "analysis.json").read_text())
    assert result["knot_type_start"] == result["knot_type_end"] == "-5_1"
    assert result["handedness"] == "left" and result["writhe"] < 0
