"""The analysis recovers known parameters from synthetic vortex-knot trajectories."""

from __future__ import annotations

import json

import numpy as np
import pytest
from synthetic import vortex_knot_positions, write_run_directory

from knotmm.analysis import analyze, analyze_run, load_run
from knotmm.io.run_data import RunData

# Realistic numbers for T(2,3), N = 90 (docs/model.md; Gruziel et al. 2018).
TREFOIL = dict(
    n_beads=90, p=2, q=3, rho0=4.3, swirl_amplitude=0.5, tau_swirl=20.0, tau_rot=400.0, velocity=7.0
)
# A left-handed T(2,5) turning clockwise, with other numbers.
CINQUEFOIL = dict(
    n_beads=120,
    p=2,
    q=5,
    rho0=5.7,
    swirl_amplitude=0.4,
    tau_swirl=14.0,
    tau_rot=250.0,
    velocity=8.5,
    mirror=True,
)

REQUIRED_KEYS = {
    "sedimentation_velocity",
    "major_radius",
    "major_radius_geometric",
    "swirl_amplitude",
    "tau_sed",
    "tau_swirl",
    "tau_rot",
    "tau_swirl_over_tau_sed",
    "tau_rot_over_tau_sed",
    "rotation_sense",
    "writhe",
    "handedness",
    "knot_type_start",
    "knot_type_end",
    "knot_type_changed_at",
    "window",
    "p",
    "q",
    "fit_quality",
}


def _make_run(path, params, duration=300.0, dt=0.5, noise=0.03, seed=1, run_file=True):
    times = np.arange(int(round(duration / dt)) + 1) * dt
    x = vortex_knot_positions(times, noise=noise, seed=seed, **params)
    config = {
        "knot": {"kind": "torus", "p": params["p"], "q": params["q"]},
        "model": {"bond_length": 0.6},
    }
    write_run_directory(path, x, dt, config, write_run_file=run_file)
    return path


@pytest.fixture(scope="module")
def trefoil_result(tmp_path_factory):
    run = _make_run(tmp_path_factory.mktemp("trefoil"), TREFOIL)
    return analyze_run(run, plots=False, knot_samples=4)


@pytest.fixture(scope="module")
def cinquefoil_result(tmp_path_factory):
    run = _make_run(tmp_path_factory.mktemp("cinquefoil"), CINQUEFOIL, seed=2)
    return analyze(load_run(run), knot_samples=0)


def _rel(a, b):
    return abs(a - b) / abs(b)


@pytest.mark.parametrize("which", ["trefoil", "cinquefoil"])
def test_recovers_parameters_within_one_percent(which, trefoil_result, cinquefoil_result):
    result, truth = {
        "trefoil": (trefoil_result, TREFOIL),
        "cinquefoil": (cinquefoil_result, CINQUEFOIL),
    }[which]
    d = result.to_dict()
    assert _rel(d["sedimentation_velocity"], truth["velocity"]) < 0.01
    assert _rel(d["major_radius"], truth["rho0"]) < 0.01
    assert _rel(d["swirl_amplitude"], truth["swirl_amplitude"]) < 0.01
    assert _rel(d["tau_swirl"], truth["tau_swirl"]) < 0.01
    assert _rel(d["tau_rot"], abs(truth["tau_rot"])) < 0.01
    fit = d["fit"]
    assert _rel(fit["rho0"], truth["rho0"]) < 0.01
    assert _rel(fit["tau_swirl"], truth["tau_swirl"]) < 0.01
    assert _rel(abs(fit["tau_rot"]), abs(truth["tau_rot"])) < 0.01
    assert _rel(fit["sedimentation_velocity"], truth["velocity"]) < 0.01
    tau_sed = 2 * truth["rho0"] / truth["velocity"]
    assert _rel(d["tau_sed"], tau_sed) < 0.01
    assert _rel(d["tau_swirl_over_tau_sed"], truth["tau_swirl"] / tau_sed) < 0.02
    assert _rel(d["tau_rot_over_tau_sed"], abs(truth["tau_rot"]) / tau_sed) < 0.02
    # the reported uncertainties are small but not zero, and cover the error loosely
    assert 0 < d["tau_swirl_uncertainty"] < 0.01 * truth["tau_swirl"]
    # a good fit: noise 0.03 d against an amplitude of 0.4-0.5 d
    assert d["fit_quality"]["r2"] > 0.98
    assert d["fit_quality"]["converged"]
    assert d["p"] == truth["p"] and d["q"] == truth["q"]
    assert d["p_detected"] == truth["p"] and d["q_detected"] == truth["q"]


def test_geometric_radius(trefoil_result):
    assert trefoil_result.major_radius_geometric == pytest.approx(90 * 0.6 / (4 * np.pi))


def test_rotation_sense_and_handedness(trefoil_result, cinquefoil_result):
    assert trefoil_result.handedness == "right"
    assert trefoil_result.writhe > 2.5
    assert trefoil_result.rotation_sense == "counterclockwise"
    assert cinquefoil_result.handedness == "left"
    assert cinquefoil_result.writhe < -4.0
    assert cinquefoil_result.rotation_sense == "clockwise"
    assert cinquefoil_result.fit.tau_rot < 0
    # the formula as written swirls outward at the top; a mirror in x keeps rho and z
    assert trefoil_result.swirl_sense == "outward at the top"
    assert cinquefoil_result.swirl_sense == "outward at the top"
    assert (trefoil_result.fit.sign_z, trefoil_result.fit.sign_alpha) == (1, 1)
    assert (cinquefoil_result.fit.sign_z, cinquefoil_result.fit.sign_alpha) == (1, -1)


def test_rotation_sense_does_not_follow_from_handedness():
    """A right-handed knot made to turn clockwise is reported clockwise."""
    times = np.arange(241) * 0.5
    x = vortex_knot_positions(times, **{**TREFOIL, "tau_rot": -300.0}, noise=0.02)
    result = analyze(
        RunData.from_arrays(x, 0.5, {"knot": {"p": 2, "q": 3}}), knot_samples=0, fit=False
    )
    assert result.handedness == "right"
    assert result.rotation_sense == "clockwise"
    assert _rel(result.tau_rot, 300.0) < 0.01


def test_json_contract(trefoil_result):
    path = trefoil_result.data.directory / "analysis.json"
    on_disk = json.loads(path.read_text())
    assert on_disk == trefoil_result.to_dict()
    assert REQUIRED_KEYS <= on_disk.keys()
    assert on_disk["window"] == [0.0, 300.0]
    assert on_disk["rotation_sense"] in ("clockwise", "counterclockwise")
    assert on_disk["knot_type_start"] in (None, "+3_1")
    assert on_disk["knot_type_changed_at"] is None


def test_without_run_file_p_detected_and_q_null(tmp_path):
    run = _make_run(tmp_path, TREFOIL, duration=120.0, run_file=False)
    data = load_run(run / "trajectory.dcd", frame_interval=0.5)
    result = analyze(data, knot_samples=0)
    d = result.to_dict()
    assert d["p"] == 2 and d["p_source"] == "data"
    assert d["q"] is None and d["q_detected"] == 3
    assert _rel(d["tau_swirl"], 20.0) < 0.01
    assert any("q not known" in n for n in d["notes"])
    # --q given: reported
    assert analyze(data, q=3, knot_samples=0, fit=False).to_dict()["q"] == 3


def test_inputs_not_modified():
    times = np.arange(121) * 0.5
    x = vortex_knot_positions(times, **TREFOIL)
    x.flags.writeable = False
    data = RunData.from_arrays(x, 0.5, {"knot": {"p": 2, "q": 3}})
    data.positions.flags.writeable = False
    before = data.positions.copy()
    analyze(data, knot_samples=0)
    np.testing.assert_array_equal(data.positions, before)
