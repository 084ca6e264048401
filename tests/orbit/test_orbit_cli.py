"""``knotmm orbit`` end to end: files, keys, exit codes, one-line errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from knotmm.cli.main import main


def _one_line_error(capsys, code, argv):
    assert main(argv) == code
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("knotmm: error:"), err
    assert "Traceback" not in err[0]
    return err[0]


@pytest.fixture(scope="module")
def orbit_out(run40, tmp_path_factory):
    out = tmp_path_factory.mktemp("orbit_cli") / "o"
    code = main(["orbit", str(run40), "--modes", "3", "--out", str(out)])
    return code, out


def test_orbit_writes_its_files_and_keys(orbit_out, orbit40):
    code, out = orbit_out
    assert code == 0
    data = json.loads((out / "orbit.json").read_text())
    assert data["status"] == "converged"
    assert data["residual"] <= 1e-8
    _, orbit, _ = orbit40
    assert data["period"] == pytest.approx(orbit.period, rel=1e-6)
    assert data["rotation_per_period"] == pytest.approx(orbit.rotation, abs=1e-6)
    mods = [np.hypot(*m) for m in data["floquet_multipliers"]]
    assert len(mods) == 3 and mods == sorted(mods, reverse=True)
    assert data["floquet_moduli"] == pytest.approx(mods)
    assert data["leading_exponent"] == pytest.approx(np.log(mods[0]) / data["period"])
    assert {n["symmetry"] for n in data["neutral_multipliers"]} >= {"time shift",
                                                                     "rotation about z"}
    assert isinstance(data["leading_mode"], str) and data["leading_mode"]
    assert data["sedimentation_velocity"] > 0
    assert data["tau_rot"] == pytest.approx(2 * np.pi * data["period"]
                                            / abs(data["rotation_per_period"]))
    for name in ("orbit.dcd", "topology.pdb", "mode_1.dcd", "orbit_multipliers.png"):
        assert (out / name).stat().st_size > 0


def test_orbit_dcd_holds_one_period(orbit_out):
    """Frame 0 is the orbit state; the last frame is it turned by the rotation and fallen."""
    import mdtraj

    _, out = orbit_out
    data = json.loads((out / "orbit.json").read_text())
    traj = mdtraj.load_dcd(str(out / "orbit.dcd"), top=str(out / "topology.pdb"))
    assert traj.n_frames == 61
    x0 = traj.xyz[0].astype(float)  # nm = d
    x1 = traj.xyz[-1].astype(float)
    from knotmm.orbit.flow import centre, rms, rotate_z

    back = rotate_z(centre(x1), -data["rotation_per_period"])
    assert rms(back - centre(x0)) < 1e-4  # float32 in Angstrom
    fall = x1.mean(axis=0)[2] - x0.mean(axis=0)[2]
    assert -fall / data["period"] == pytest.approx(data["sedimentation_velocity"], rel=1e-4)
    mode = mdtraj.load_dcd(str(out / "mode_1.dcd"), top=str(out / "topology.pdb"))
    dev = [rms(mode.xyz[k] - traj.xyz[k]) for k in range(0, 61, 20)]
    assert dev == pytest.approx([0.5] * len(dev), rel=1e-3)


def test_missing_run_is_one_line(capsys, tmp_path):
    _one_line_error(capsys, 2, ["orbit", str(tmp_path / "nope")])


def test_bad_arguments_are_one_line(capsys, run40):
    assert "--modes" in _one_line_error(capsys, 2, ["orbit", str(run40), "--modes", "-1"])
    assert "--continue" in _one_line_error(capsys, 2, ["orbit", str(run40), "--continue",
                                                       "run.duration=1:2"])
    assert "--t" in _one_line_error(capsys, 2, ["orbit", str(run40), "--t", "900"])


def test_run_without_periodic_window_is_one_line(capsys, tmp_path):
    from synthetic import write_run_directory
    from synthetic_regimes import rigid_ring

    t = np.arange(0, 100, 0.5)
    write_run_directory(tmp_path / "ring", rigid_ring(t, n_beads=40, radius=3.0), 0.5)
    line = _one_line_error(capsys, 2, ["orbit", str(tmp_path / "ring")])
    assert "no periodic window" in line


def test_brownian_run_is_refused(capsys, tmp_path, run_maker):
    run_maker(tmp_path / "brown", **{"run.peclet": 10.0, "run.duration": 1.0})
    line = _one_line_error(capsys, 2, ["orbit", str(tmp_path / "brown")])
    assert "run.peclet" in line


def test_newton_that_cannot_converge_says_so(run40, tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["orbit", str(run40), "--modes", "0", "--tolerance", "1e-30",
                 "--out", str(out)]) == 1
    data = json.loads((out / "orbit.json").read_text())
    assert data["status"] == "did not converge"
    assert data["floquet_multipliers"] is None
    assert "did not converge" in capsys.readouterr().out
