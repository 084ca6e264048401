"""``knotmm run`` with run.engine: the plugin run killed and resumed, the fallback, faults."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from workflow.test_resume import _load, _start_run

import knotmm.plugin
from knotmm.cli.main import main

needs_plugin = pytest.mark.skipif(not knotmm.plugin.available(),
                                  reason=str(knotmm.plugin.load_error()))


def _run_file(path: Path, directory: Path, run_keys: str = "") -> Path:
    """A 40-bead, 6 tau_d run with a checkpoint every tau_d (what _start_run counts)."""
    path.write_text(
        "[knot]\nbeads = 40\n[run]\nduration = 6.0\ntopology_check_interval = 0.0\n"
        f'engine = "plugin"\n{run_keys}'
        f"[output]\ndirectory = {str(directory)!r}\nframe_interval = 0.5\n"
        "checkpoint_interval = 1.0\n"
    )
    return path


def _facts(directory: Path) -> str:
    return (directory / "run.toml").read_text()


@needs_plugin
@pytest.mark.parametrize("run_keys", ["", "peclet = 2.0\nseed = 5\n"],
                         ids=["rk23", "brownian"])
def test_plugin_run_killed_and_resumed_equals_uninterrupted(tmp_path, run_keys):
    """SIGKILL after the first checkpoints, --resume: the frames and rows of an uninterrupted
    plugin run, bit for bit (the Brownian noise stream rides in the Context checkpoint)."""
    reference = tmp_path / "reference"
    assert main(["run", str(_run_file(tmp_path / "ref.toml", reference, run_keys)),
                 "--no-progress"]) == 0
    assert 'engine = "plugin"' in _facts(reference).split("[knotmm]")[1]
    directory = tmp_path / "run"
    proc = _start_run(_run_file(tmp_path / "run.toml", directory, run_keys), directory, 2,
                      subprocess.DEVNULL)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    if proc.returncode == 0:
        pytest.skip("the run finished before it could be killed")
    assert main(["run", "--resume", str(directory), "--no-progress"]) == 0
    (traj, rows), (ref_traj, ref_rows) = _load(directory), _load(reference)
    assert traj.n_frames == ref_traj.n_frames == 13
    assert np.array_equal(traj.xyz, ref_traj.xyz)
    assert rows == ref_rows


@needs_plugin
def test_resume_with_another_engine_is_refused(tmp_path, capsys):
    directory = tmp_path / "run"
    run_file = _run_file(tmp_path / "run.toml", directory)
    proc = _start_run(run_file, directory, 1, subprocess.DEVNULL)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    if proc.returncode == 0:
        pytest.skip("the run finished before it could be killed")
    toml = directory / "run.toml"
    toml.write_text(toml.read_text().replace('engine = "plugin"', 'engine = "python"', 1))
    capsys.readouterr()
    assert main(["run", "--resume", str(directory), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "run.engine ('plugin' -> 'python')" in err[0]


def test_missing_plugin_says_so_in_one_line_and_runs_python(tmp_path):
    directory = tmp_path / "run"
    run_file = _run_file(tmp_path / "run.toml", directory).read_text()
    (tmp_path / "run.toml").write_text(run_file.replace("duration = 6.0", "duration = 1.0"))
    done = subprocess.run(
        [sys.executable, "-m", "knotmm.cli.main", "run", str(tmp_path / "run.toml"),
         "--no-progress"],
        capture_output=True, text=True, env=dict(os.environ, KNOTMM_NO_PLUGIN="1"), check=False,
    )
    assert done.returncode == 0, done.stderr
    lines = [ln for ln in done.stderr.splitlines() if ln.startswith("knotmm:")]
    assert len(lines) == 1, done.stderr
    assert "KNOTMM_NO_PLUGIN" in lines[0] and "using the Python engine" in lines[0]
    facts = _facts(directory).split("[knotmm]")[1]
    assert 'engine = "python"' in facts


@needs_plugin
@pytest.mark.parametrize(("run_keys", "expect"), [
    ("max_bond_length = 0.6005\n", "past run.max_bond_length = 0.6005"),
    ("tolerance = 1e-12\nmin_timestep = 1e-3\n", "below run.min_timestep"),
])
def test_plugin_fault_is_one_line_exit_3_frames_kept(tmp_path, capsys, run_keys, expect):
    """The same fault line as the Python engine's run; frame 0 is kept, status = "fault"."""
    errors = {}
    for engine in ("plugin", "python"):
        directory = tmp_path / engine
        run_file = _run_file(tmp_path / f"{engine}.toml", directory, run_keys)
        run_file.write_text(run_file.read_text().replace('"plugin"', f'"{engine}"'))
        capsys.readouterr()
        assert main(["run", str(run_file), "--no-progress"]) == 3
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and expect in err[0]
        errors[engine] = err[0].replace(str(directory), "DIR")
        text = _facts(directory)
        assert 'status = "fault"' in text
        assert _load(directory)[0].n_frames >= 1
    assert errors["plugin"] == errors["python"]
