"""Issue 35: a number only where it is measured, in the table, the JSON and the replica table.

tau_rot (and tau_rot/tau_sed) from a window holding too little of a rotation is n/a with the
reason in the notes; a replica table's mean says over how many replicas it is.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from synthetic import vortex_knot_positions, write_run_directory

from knotmm.analysis import analyze, analyze_run
from knotmm.analysis.replicas import replica_statistics
from knotmm.analysis.window import MIN_ROTATION_FRACTION, rotation_unmeasured
from knotmm.cli.analyze import SWEEP_COLUMNS, _mean_se
from knotmm.cli.main import main
from knotmm.io.run_data import RunData

DT = 0.5
TIMES = np.arange(401) * DT  # 0 .. 200 tau_d
CONFIG = {"knot": {"kind": "torus", "p": 2, "q": 3}, "model": {"bond_length": 0.6}}
TREFOIL = dict(n_beads=60, p=2, q=3, rho0=2.9, swirl_amplitude=0.3, tau_swirl=10.0,
               velocity=7.0, noise=0.02)


def _row(table: str, name: str) -> str:
    match = re.search(rf"^{re.escape(name)}\s+(.*)$", table, re.MULTILINE)
    assert match, (name, table)
    return match.group(1)


def test_rotation_far_slower_than_the_window_is_not_reported(tmp_path):
    """tau_rot = 7000 tau_d seen in a 200 tau_d window (3 % of a turn): n/a everywhere."""
    x = vortex_knot_positions(TIMES, tau_rot=7000.0, **TREFOIL)
    run = write_run_directory(tmp_path / "slow", x, DT, CONFIG)
    result = analyze_run(run, plots=False, knot_samples=0)
    on_disk = json.loads((run / "analysis.json").read_text())
    assert on_disk == result.to_dict()
    for key in ("tau_rot", "tau_rot_uncertainty", "tau_rot_over_tau_sed",
                "tau_rot_over_tau_sed_uncertainty", "tau_rot_body", "rotation_frequency"):
        assert on_disk[key] is None, key
    assert on_disk["uncertainties"]["tau_rot_body"]["value"] is None
    table = result.summary()
    assert _row(table, "tau_rot [tau_d]") == "n/a"
    assert _row(table, "tau_rot/tau_sed") == "n/a"
    assert any("of a rotation" in n and "tau_rot and tau_rot/tau_sed not measured" in n
               for n in on_disk["notes"])
    # the note gives the reason, not the withheld period
    assert not any("tau_rot =" in n for n in on_disk["notes"])
    # what is measured still is: the swirl, the speed
    assert on_disk["tau_swirl"] == pytest.approx(10.0, rel=0.01)
    assert on_disk["sedimentation_velocity"] == pytest.approx(7.0, rel=1e-3)


@pytest.mark.parametrize("tau_rot", [50.0, -40.0])
def test_several_rotations_in_the_window_are_measured(tau_rot):
    """tau_rot = 50 (or 40 clockwise) in a 200 tau_d window: a number within 2 % of it."""
    x = vortex_knot_positions(TIMES, tau_rot=tau_rot, **TREFOIL)
    result = analyze(RunData.from_arrays(x, DT, CONFIG), knot_samples=0, fit=False)
    d = result.to_dict()
    assert d["tau_rot"] == pytest.approx(abs(tau_rot), rel=0.02)
    assert d["tau_rot_over_tau_sed"] == pytest.approx(abs(tau_rot) / d["tau_sed"], rel=0.03)
    assert d["tau_rot_body"] == pytest.approx(abs(tau_rot), rel=0.02)
    assert not any("not measured" in n and "rot" in n for n in d["notes"])
    assert _row(result.summary(), "tau_rot [tau_d]").startswith(f"{d['tau_rot']:.4g}")


def test_rotation_rule():
    assert rotation_unmeasured(100.0, 1.0, 200.0) is None
    assert rotation_unmeasured(100.0, 1.0, 100.0 * MIN_ROTATION_FRACTION) is None
    assert "of a rotation" in rotation_unmeasured(7189.0, 1.0, 21.5)
    # issue 35's "tau_rot 7189 +- 1.1e+05": the uncertainty exceeds the value
    assert "uncertainty" in rotation_unmeasured(7189.0, 1.1e5, 7189.0)
    assert rotation_unmeasured(float("inf"), float("nan"), 200.0) is not None


# -- the replica table ---------------------------------------------------------------------
def test_a_mean_says_over_how_many_replicas():
    """tau_swirl_body from 1 replica of 3 (issue 35: printed as 7.471 beside n = 3)."""
    stats = replica_statistics([
        {"tau_swirl_body": 7.471, "sedimentation_velocity": 6.0, "swirl_amplitude": None},
        {"tau_swirl_body": None, "sedimentation_velocity": 6.2, "swirl_amplitude": 0.2},
        {"tau_swirl_body": None, "sedimentation_velocity": 6.1, "swirl_amplitude": 0.3},
    ])
    assert stats["tau_swirl_body"]["n"] == 1
    assert _mean_se(stats["tau_swirl_body"], 3) == "7.471 (n=1 of 3)"
    assert _mean_se(stats["swirl_amplitude"], 3) == "0.25 +- 0.05 (n=2 of 3)"
    assert _mean_se(stats["sedimentation_velocity"], 3) == "6.1 +- 0.058"
    assert _mean_se(None, 3) == "n/a (n=0 of 3)"
    assert _mean_se(stats["tau_swirl_body"], 1) == "7.471"  # a point of one run


def test_printed_replica_table_shows_each_quantitys_n(tmp_path, monkeypatch, capsys):
    """``knotmm analyze SET`` on a fake set where one replica of three measured the swirl."""
    import knotmm.analysis.replicas as replicas

    (tmp_path / "sweep.toml").write_text('[sweep]\nseeds = 3\n')
    analyses = [
        {"sedimentation_velocity": 6.0 + 0.1 * k, "tau_swirl_body": 7.471 if k == 0 else None,
         "swirl_amplitude": None, "torus_fraction": 1.0,
         "body_frame": {"flips_per_100_tau": 0.0}}
        for k in range(3)
    ]
    runs = [f"replica={k}" for k in range(3)]
    summary = {"points": {"all": {"runs": runs, "excluded": {}, "failed": {},
                                  "statistics": replica_statistics(analyses)}}}
    monkeypatch.setattr(replicas, "analyze_sweep", lambda *a, **k: summary)
    assert main(["analyze", str(tmp_path), "--no-plots", "--knot-samples", "0"]) == 0
    lines = capsys.readouterr().out.splitlines()
    header = lines[0].split()
    assert header == ["point", "n", *SWEEP_COLUMNS]
    row = lines[1]
    assert row.startswith("all") and re.search(r"all\s+3\s", row)
    assert "7.471 (n=1 of 3)" in row
    assert "n/a (n=0 of 3)" in row  # swirl_amplitude: no replica measured it
    assert "6.1 +- 0.058" in row  # all three: no (n=...)
    assert "7.471  " not in row.replace("7.471 (n=1 of 3)", "")
