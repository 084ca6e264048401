"""End to end: knotmm.workflow.run and the `knotmm run` command write a valid run directory."""

from __future__ import annotations

import csv
import hashlib
import os
import subprocess
import sys
from pathlib import Path

import mdtraj as md
import numpy as np
import pytest
import reference_model as rm
from mdtraj.formats import DCDTrajectoryFile

from knotmm.cli.main import main
from knotmm.config import RunConfig, load_run_file, read_toml
from knotmm.errors import SimulationFault
from knotmm.shapes import build_template
from knotmm.workflow import run

SHORT = {"knot": {"beads": 40}, "run": {"duration": 5.0}, "output": {"frame_interval": 0.5}}


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    directory = tmp_path_factory.mktemp("runs") / "trefoil40"
    cfg = RunConfig.from_dict(SHORT)
    result = run(cfg, directory, progress=False)
    return cfg, directory, result


def _load(directory):
    return md.load(str(directory / "trajectory.dcd"), top=str(directory / "topology.pdb"))


def _observables(directory):
    with open(directory / "observables.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def _snapshot(directory):
    """Content hash and mtime of every file in a directory."""
    return {
        p.name: (hashlib.sha256(p.read_bytes()).hexdigest(), p.stat().st_mtime_ns)
        for p in sorted(Path(directory).iterdir())
    }


def test_run_directory_loads_in_mdtraj(short_run):
    cfg, directory, result = short_run
    traj = _load(directory)
    assert traj.n_atoms == 40 and traj.n_residues == 40
    assert {r.name for r in traj.topology.residues} == {"BEA"}
    bonds = {tuple(sorted((a.index, b.index))) for a, b in traj.topology.bonds}
    assert bonds == {tuple(sorted((i, (i + 1) % 40))) for i in range(40)}  # closure included
    assert traj.n_frames == round(5.0 / 0.5) + 1 == result.frames
    assert traj.unitcell_vectors is None
    assert "topology.pdb" in (directory / "view.vmd").read_text()
    # frame 0 is the template start (mdtraj reads nm = d)
    start = build_template(cfg).positions
    np.testing.assert_allclose(traj.xyz[0], start, atol=2e-6 * np.abs(start).max())
    pdb = md.load(str(directory / "topology.pdb"))
    np.testing.assert_allclose(pdb.xyz[0], start, atol=1e-3)  # PDB: 3 decimals in Angstrom
    assert pdb.unitcell_vectors is None


def test_dcd_is_in_angstrom_without_unit_cell(short_run):
    _, directory, _ = short_run
    with DCDTrajectoryFile(str(directory / "trajectory.dcd")) as fh:
        xyz, lengths, angles = fh.read()
    bonds = np.linalg.norm(xyz[:, 1:] - xyz[:, :-1], axis=2)
    assert np.median(bonds) == pytest.approx(6.0, rel=0.02)  # 0.6 d = 6 A
    assert lengths is None or np.all(lengths == 0)


def test_observables_rows_at_frame_times(short_run):
    _, directory, result = short_run
    obs = _observables(directory)
    k = np.arange(len(obs["time"]))
    assert len(k) == 11
    np.testing.assert_array_equal(obs["time"], 0.5 * k)
    assert obs["step"][0] == 0 and np.all(np.diff(obs["step"]) > 0)
    assert obs["step"][-1] == result.steps
    assert np.all(np.diff(obs["com_z"]) < 0)  # it falls
    traj = _load(directory)
    for i in (0, 5, 10):
        x = traj.xyz[i].astype(np.float64)
        want = rm.energies(x)
        for term in ("bond", "bend", "steric", "gravity"):
            assert obs[f"e_{term}"][i] == pytest.approx(want[term], rel=2e-3, abs=2e-4), term
        np.testing.assert_allclose(
            [obs["com_x"][i], obs["com_y"][i], obs["com_z"][i]], x.mean(axis=0), atol=1e-4
        )
        bonds = np.linalg.norm(x - np.roll(x, -1, axis=0), axis=1)
        assert obs["max_bond"][i] == pytest.approx(bonds.max(), abs=1e-5)


def test_run_toml_reloads_as_the_same_config(short_run):
    cfg, directory, _ = short_run
    loaded = load_run_file(directory / "run.toml")
    resolved = build_template(cfg).resolved
    # the integrator and step a run uses are written out ("auto" and an unset step resolved)
    stepping = {"run.integrator": "rk23", "run.timestep": 0.01, "run.tolerance": 1e-4}
    expected = cfg.replace({**resolved, **stepping, "output.directory": str(directory)})
    assert loaded == expected
    facts = read_toml(directory / "run.toml")["knotmm"]
    assert facts["status"] == "finished"
    assert facts["n_beads"] == 40
    assert facts["time_reached"] == pytest.approx(5.0)


def test_rerunning_run_toml_reproduces_the_trajectory(short_run, tmp_path):
    _, directory, _ = short_run
    cfg = load_run_file(directory / "run.toml")
    run(cfg, tmp_path / "again", progress=False)
    a, b = _load(directory), _load(tmp_path / "again")
    np.testing.assert_array_equal(a.xyz, b.xyz)


# -- the command line ---------------------------------------------------------------------------
def _cli(args, capsys):
    code = main(args)
    out, err = capsys.readouterr()
    return code, out, err


def test_cli_run_refuses_to_overwrite(tmp_path, capsys):
    out = tmp_path / "r"
    args = ["run", "--duration", "1", "--beads", "40", "--out", str(out), "--no-progress"]
    code, stdout, err = _cli(args, capsys)
    assert code == 0, err
    assert stdout.count("\n") == 1 and "simulated 1 tau_d" in stdout
    before = _snapshot(out)
    code, stdout, err = _cli(args, capsys)
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("knotmm: error:")
    assert "--overwrite" in err and "finished" in err
    assert _snapshot(out) == before
    code, _, err = _cli([*args, "--overwrite"], capsys)
    assert code == 0, err
    after = _snapshot(out)
    assert after["trajectory.dcd"][1] != before["trajectory.dcd"][1]


def test_console_script_refuses_to_overwrite(short_run):
    """The installed `knotmm` entry point: exit code 2, one line, no traceback."""
    _, directory, _ = short_run
    before = _snapshot(directory)
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "knotmm.cli",
            "run",
            "--beads",
            "40",
            "--duration",
            "5",
            "--out",
            str(directory),
            "--no-progress",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr
    assert proc.stdout == ""
    assert _snapshot(directory) == before


@pytest.mark.parametrize(
    "text,needles",
    [
        ("[model]\nbond_lenght = 0.7\n", ["bond_lenght", "did you mean 'bond_length'"]),
        ('[knot]\nbeads = "ninety"\n', ["knot.beads", "integer"]),
        ("[model]\nbond_stiffness = -5.0\n", ["model.bond_stiffness", "> 0"]),
        ('[run]\nintegrator = "rk45"\n', ["run.integrator", "rk23"]),
        ("[modle]\nbond_length = 0.7\n", ["[modle]", "did you mean 'model'"]),
        ("[run]\nduration = 1.0\n[output]\nframe_interval = 2.0\n", ["output.frame_interval"]),
    ],
)
def test_bad_run_files_exit_2_with_one_line_and_write_nothing(tmp_path, capsys, text, needles):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    out = tmp_path / "never"
    code, stdout, err = _cli(["run", str(path), "--out", str(out), "--no-progress"], capsys)
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("knotmm: error:"), err
    for needle in needles:
        assert needle in err, err
    assert stdout == ""
    assert not out.exists()


def test_bad_set_override_is_one_line(tmp_path, capsys):
    out = tmp_path / "never"
    code, _, err = _cli(["run", "--set", "model.gravty=2", "--out", str(out)], capsys)
    assert code == 2 and err.count("\n") == 1 and "did you mean 'gravity'" in err
    assert not out.exists()


# -- faults -------------------------------------------------------------------------------------
FAULTY = {
    "knot": {"beads": 40},
    "run": {"duration": 5.0, "integrator": "euler", "timestep": 0.1},
    "output": {"frame_interval": 0.25},
}


def test_fault_keeps_the_files_written_so_far(tmp_path):
    directory = tmp_path / "fault"
    with pytest.raises(SimulationFault) as info:
        run(RunConfig.from_dict(FAULTY), directory, progress=False)
    message = str(info.value)
    assert "run.max_bond_length" in message and "run.timestep" in message
    traj = _load(directory)
    assert traj.n_frames >= 2  # frame 0 and the frames before the fault
    obs = _observables(directory)
    assert len(obs["time"]) == traj.n_frames
    np.testing.assert_array_equal(obs["time"], 0.25 * np.arange(traj.n_frames))
    facts = read_toml(directory / "run.toml")["knotmm"]
    assert facts["status"] == "fault"
    assert facts["message"] == message
    assert facts["time_reached"] < 5.0


def test_cli_fault_exit_code_3(tmp_path, capsys):
    path = tmp_path / "faulty.toml"
    path.write_text(
        '[knot]\nbeads = 40\n[run]\nduration = 5.0\nintegrator = "euler"\ntimestep = 0.1\n'
    )
    code, _, err = _cli(["run", str(path), "--out", str(tmp_path / "f"), "--no-progress"], capsys)
    assert code == 3
    assert err.count("\n") == 1 and "bond" in err
    assert (tmp_path / "f" / "trajectory.dcd").exists()


def test_knotmm_console_script_is_installed():
    exe = Path(sys.executable).with_name("knotmm")
    assert exe.exists() or any(
        (Path(p) / "knotmm").exists() for p in os.environ.get("PATH", "").split(os.pathsep)
    )


def test_resume_takes_no_run_options_but_duration(short_run, capsys):
    _, directory, _ = short_run
    code, _, err = _cli(["run", "--resume", str(directory), "--beads", "40"], capsys)
    assert code == 2 and err.count("\n") == 1
    assert "--beads" in err and "but --duration" in err
