"""Issue 13: the analysis on synthetic runs in every regime recovers the truth or says "not
detected" (rigid ring, tilted torus, flipping torus, elliptic swirl, relaxation, tilting after
the window). The runs are written as DCD files, so float32 rounding is part of the test."""

from __future__ import annotations

import json

import numpy as np
import pytest
from synthetic import vortex_knot_positions, write_run_directory
from synthetic_regimes import (
    elliptic_swirl,
    flip_angles,
    rigid_ring,
    tilted_torus,
)

from knotmm.analysis import analyze, analyze_run, format_table, load_run

DT = 0.5
TIMES = np.arange(401) * DT  # 0 .. 200 tau_d
K_23 = np.hypot(2, 3) / 3  # z/rho amplitude ratio of the vortex-knot formula for T(2,3)
CONFIG = {"knot": {"kind": "torus", "p": 2, "q": 3}, "model": {"bond_length": 0.6}}


def _analyse(tmp_path, name, positions, **kwargs):
    run = write_run_directory(tmp_path / name, positions, DT, CONFIG)
    return analyze(load_run(run), knot_samples=0, **kwargs)


@pytest.mark.parametrize(
    "tilt",
    [0.0, flip_angles(TIMES, [60.0], duration=40.0)],
    ids=["flat", "turning_over"],
)
def test_rigid_ring_sinking_and_turning_has_no_swirl(tmp_path, tilt):
    # a rigid circle that sinks at 7 d/tau_d and spins (period 50): no bead moves relative
    # to the others, so any "swirl" is float32 rounding of the DCD
    x = rigid_ring(TIMES, n_beads=60, radius=4.0, velocity=7.0, tau_spin=50.0, tilt_deg=tilt)
    result = _analyse(tmp_path, "ring", x)
    d = result.to_dict()
    assert d["swirl_detected"] is False
    assert d["tau_swirl"] is None and d["swirl_amplitude"] is None
    assert d["tau_swirl_body"] is None
    assert d["swirl_amplitude_rho"] is None and d["swirl_amplitude_z"] is None
    assert d["swirl_sense"] is None and d["fit"] is None
    assert d["tau_swirl_over_tau_sed"] is None
    assert any(n.startswith("no swirl detected") for n in d["notes"])
    # no periodic state to find: the window is the whole run, not a cut piece of it
    assert d["window"] == [0.0, 200.0]
    assert d["sedimentation_velocity"] == pytest.approx(7.0, rel=1e-6)
    assert d["body_frame"]["flips"]["count"] == (0 if np.ndim(tilt) == 0 else 1)


def test_tilted_torus_measured_in_the_body_frame(tmp_path):
    truth = dict(swirl_amplitude=0.5, tau_swirl=20.0, tau_rot=400.0, rho0=4.3)
    x = tilted_torus(TIMES, 50.0, velocity=7.0, **truth)
    d = _analyse(tmp_path, "tilted", x).to_dict()
    b = d["body_frame"]
    assert b["window_inclination_median_deg"] == pytest.approx(50.0, abs=0.01)
    assert b["inclination_median_deg"] == pytest.approx(50.0, abs=0.01)
    assert d["torus_fraction"] == 1.0 and d["toroidal_window"] is True
    assert d["swirl_detected"] is True
    assert d["tau_swirl_body"] == pytest.approx(20.0, rel=1e-3)
    assert d["swirl_amplitude_rho"] == pytest.approx(0.5, rel=0.01)
    assert d["swirl_amplitude_z"] == pytest.approx(0.5 * K_23, rel=0.01)
    # the body-frame fit recovers the formula's parameters
    assert d["swirl_amplitude"] == pytest.approx(0.5, rel=0.01)
    assert d["fit"]["tau_swirl"] == pytest.approx(20.0, rel=1e-3)
    assert abs(d["fit"]["tau_rot"]) == pytest.approx(400.0, rel=0.01)
    # lab-frame values of a tilted torus mix the tilt with the swirl: not reported
    assert d["rotation_sense"] is None and d["tau_swirl"] is None and d["tau_rot"] is None
    assert any("tilted in the window" in n for n in d["notes"])


def test_flipping_torus_flips_counted_and_window_between_them(tmp_path):
    x = tilted_torus(TIMES, flip_angles(TIMES, [40.0, 120.0], duration=4.0))
    d = _analyse(tmp_path, "flipping", x).to_dict()
    flips = d["body_frame"]["flips"]
    assert flips["count"] == 2
    # a flip completes when the tilt leaves the band 90 +- 30 (hysteresis): 120 of the 180
    # degrees into each turn
    assert flips["times"][0] == pytest.approx(40.0 + 4.0 * 120 / 180, abs=DT)
    assert flips["times"][1] == pytest.approx(120.0 + 4.0 * 120 / 180, abs=DT)
    assert flips["directions"] == [1, -1]
    assert d["body_frame"]["flips_per_100_tau"] == pytest.approx(100 * 2 / 200.5)
    # the automatic window lies between the flips, where the torus is level
    assert 40.0 < d["window"][0] and d["window"][1] < 122.0
    assert d["body_frame"]["window_inclination_max_deg"] <= 30.0
    assert d["torus_fraction"] == 1.0
    # a flat torus in every frame: the first stretch's length is not measured, only bounded
    assert d["body_frame"]["first_torus_lifetime"] is None
    assert d["body_frame"]["first_torus_lifetime_censored"] is True
    assert d["body_frame"]["first_torus_lifetime_lower_bound"] == pytest.approx(200.5)
    assert d["tau_swirl_body"] == pytest.approx(20.0, rel=1e-3)
    # upside down between the flips: seen from above it turns the other way
    assert d["rotation_sense"] == "clockwise"


def test_elliptic_swirl_amplitudes_and_bad_fit_note(tmp_path):
    # bending_stiffness = 5000 in the issue: half-amplitudes 0.52 d (rho) and 0.17 d (z)
    x = elliptic_swirl(TIMES, 0.52, 0.17, rho0=4.3, tau_swirl=20.0, tau_rot=400.0)
    d = _analyse(tmp_path, "elliptic", x).to_dict()
    assert d["swirl_amplitude_rho"] == pytest.approx(0.52, rel=0.01)
    assert d["swirl_amplitude_z"] == pytest.approx(0.17, rel=0.01)
    assert d["fit_quality"]["r2_z"] < 0.5
    note = next(n for n in d["notes"] if "fits badly" in n)
    assert "R^2(z)" in note and "0.52 d in rho" in note


def test_window_starts_after_the_relaxation(tmp_path):
    # the swirl amplitude relaxes as 0.5 (1 - 0.6 exp(-t/15)): within 5 % of 0.5 after
    # t = 15 ln(12) = 37 tau_d
    amp = 0.5 * (1.0 - 0.6 * np.exp(-TIMES / 15.0))
    d = _analyse(tmp_path, "relax", vortex_knot_positions(TIMES, swirl_amplitude=amp)).to_dict()
    assert d["window"][0] >= 30.0
    assert d["swirl_amplitude"] == pytest.approx(0.5, rel=0.02)


def test_tilt_after_the_window_is_reported(tmp_path):
    # level until t = 100, then tilting steadily to 25 degrees at t = 150
    tilt = 25.0 * np.clip((TIMES - 100.0) / 50.0, 0.0, 1.0)
    result = _analyse(tmp_path, "tilt_after", tilted_torus(TIMES, tilt))
    d = result.to_dict()
    assert d["window"][1] < 150.0
    b = d["body_frame"]
    assert b["tilts_after_window"] is True
    assert b["after_window_inclination_max_deg"] == pytest.approx(25.0, abs=0.01)
    assert b["inclination_max_deg"] == pytest.approx(25.0, abs=0.01)
    assert any("tilts after the window" in n for n in d["notes"])
    assert "tilts after the window, up to 25 deg" in format_table(result)


def test_new_keys_in_json_and_time_axis(tmp_path):
    x = vortex_knot_positions(TIMES, noise=0.02)
    run = write_run_directory(tmp_path / "run", x, DT, CONFIG)
    result = analyze_run(run, plots=False, knot_samples=0)
    on_disk = json.loads((run / "analysis.json").read_text())
    for key in (
        "swirl_detected",
        "swirl_detection",
        "tau_swirl_body",
        "tau_rot_body",
        "swirl_amplitude_rho",
        "swirl_amplitude_z",
        "torus_fraction",
        "torus_fraction_window",
        "toroidal_window",
        "body_frame",
        "uncertainties",
        "time_axis",
    ):
        assert key in on_disk, key
    assert on_disk == result.to_dict()
    assert "frame index" in on_disk["time_axis"]
    assert on_disk["swirl_detection"]["p_value"] < 0.01
    u = on_disk["uncertainties"]
    assert u["tau_swirl_body"]["value"] == pytest.approx(20.0, rel=0.01)
    assert u["sedimentation_velocity"]["value"] == pytest.approx(7.0, rel=1e-3)


def test_rigid_trefoil_has_no_swirl_amplitude(tmp_path):
    # a trefoil whose cross-section has C = 0.1 d in its shape but that only sinks and turns
    # rigidly (swirl frozen): float32 rounding used to turn this into C = 0.0023 d
    x = vortex_knot_positions(TIMES, swirl_amplitude=0.1, tau_swirl=1e12, tau_rot=50.0)
    d = _analyse(tmp_path, "rigid_trefoil", x).to_dict()
    assert d["swirl_detected"] is False
    assert d["swirl_amplitude"] is None and d["tau_swirl"] is None
    assert d["window"] == [0.0, 200.0]
    assert d["torus_fraction"] == 1.0
    assert d["tau_rot"] == pytest.approx(50.0, rel=1e-3)
    assert d["rotation_sense"] == "counterclockwise"


def test_plots_and_table_without_swirl(tmp_path):
    run = write_run_directory(tmp_path / "ring", rigid_ring(TIMES[:121]), DT, CONFIG)
    result = analyze_run(run, plots=True, knot_samples=0)
    assert len(result.plots) == 3 and all((run / f).is_file() for f in result.plots)
    table = format_table(result)
    assert "no swirl detected" in table and "C [d]" in table
