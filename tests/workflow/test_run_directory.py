"""Issue 11: one owner per run directory, resume only with the same physics, clean I/O
failures, a resumed run that counts like an uninterrupted one, progress in logs."""

from __future__ import annotations

import errno
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import mdtraj
import numpy as np
import pytest

from knotmm.cli.main import main
from knotmm.config import RunConfig, read_toml
from knotmm.engine.reporters import DCDReporter
from knotmm.io.rundir import ANALYSIS_FILE, LOCK_FILE
from knotmm.workflow import run

SETTINGS = {
    "knot": {"beads": 40},
    "run": {"duration": 6.0, "topology_check_interval": 0.0},
    "output": {"frame_interval": 0.5, "checkpoint_interval": 1.0},
}


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    directory = tmp_path_factory.mktemp("ref") / "run"
    run(RunConfig.from_dict(SETTINGS), directory=directory, progress=False)
    return directory


def _frames(directory: Path) -> np.ndarray:
    return mdtraj.load(str(directory / "trajectory.dcd"), top=str(directory / "topology.pdb")).xyz


def _rows(directory: Path) -> list[list[str]]:
    return [r.split(",") for r in (directory / "observables.csv").read_text().splitlines()]


def _facts(directory: Path) -> dict:
    return read_toml(directory / "run.toml")["knotmm"]


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def _same_as(directory: Path, reference: Path) -> None:
    """Same frames (to the file's float32 precision) and the same observables rows: time,
    step, centre of mass and the velocity-evaluation count."""
    np.testing.assert_allclose(_frames(directory), _frames(reference), rtol=0, atol=1e-5)
    rows, ref_rows = _rows(directory), _rows(reference)
    assert len(rows) == len(ref_rows)
    for a, b in zip(rows[1:], ref_rows[1:], strict=True):
        assert a[:2] == b[:2] and a[-1] == b[-1]  # time, step, evaluations
        np.testing.assert_allclose([float(v) for v in a[2:5]], [float(v) for v in b[2:5]],
                                   atol=1e-6)


def _interrupted_copy(reference: Path, directory: Path, t_stop: float) -> Path:
    """Run the reference's settings to ``t_stop`` and mark the run interrupted there."""
    cfg = RunConfig.from_dict(SETTINGS).replace({"run.duration": t_stop})
    run(cfg, directory=directory, progress=False)
    path = directory / "run.toml"
    text = path.read_text().replace(f"duration = {t_stop}", "duration = 6.0")
    path.write_text(text.replace('status = "finished"', 'status = "interrupted"'))
    return directory


# -- item 2: a run directory has one owner ----------------------------------------------------
def test_a_live_run_directory_is_refused_naming_its_owner(tmp_path, capsys):
    directory = tmp_path / "live"
    run_file = tmp_path / "long.toml"
    run_file.write_text(
        "[knot]\nbeads = 40\n[run]\nduration = 5000.0\ntopology_check_interval = 0.0\n"
        f"[output]\ndirectory = {str(directory)!r}\n"
    )
    owner = subprocess.Popen(
        [sys.executable, "-m", "knotmm.cli.main", "run", str(run_file), "--no-progress"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 120
        while not ((directory / LOCK_FILE).exists() and (directory / "checkpoint.npz").exists()):
            assert owner.poll() is None and time.monotonic() < deadline
            time.sleep(0.02)
        before = (directory / "topology.pdb").read_bytes()
        for argv in (["run", str(run_file), "--no-progress"],
                     ["run", str(run_file), "--overwrite", "--no-progress"],
                     ["run", "--resume", str(directory), "--no-progress"]):
            assert main(argv) == 2, argv
            line = _one_line(capsys)
            assert f"in use by process {owner.pid}" in line, line
        assert owner.poll() is None  # untouched, still running
        assert (directory / "topology.pdb").read_bytes() == before
    finally:
        owner.send_signal(signal.SIGTERM)
        owner.wait(timeout=60)
    assert _facts(directory)["status"] == "interrupted"
    assert not (directory / LOCK_FILE).exists()


def test_a_lock_left_by_a_killed_process_is_taken_over(tmp_path, reference):
    directory = _interrupted_copy(reference, tmp_path / "run", 3.0)
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    (directory / LOCK_FILE).write_text(f"{dead.pid}\n")  # as SIGKILL leaves it
    assert main(["run", "--resume", str(directory), "--no-progress"]) == 0
    _same_as(directory, reference)
    assert not (directory / LOCK_FILE).exists()


# -- item 3: resume with the same physics; extend a finished run --------------------------------
def test_resume_after_editing_the_physics_is_refused_naming_the_keys(tmp_path, reference,
                                                                     capsys):
    directory = _interrupted_copy(reference, tmp_path / "run", 3.0)
    path = directory / "run.toml"
    text = path.read_text()
    assert "bending_stiffness = 5.0" in text and "gravity = 1.0" in text
    path.write_text(text.replace("bending_stiffness = 5.0", "bending_stiffness = 7.0")
                    .replace("gravity = 1.0", "gravity = 2.0"))
    before = (directory / "trajectory.dcd").read_bytes()
    assert main(["run", "--resume", str(directory), "--no-progress"]) == 2
    line = _one_line(capsys)
    assert "model.bending_stiffness (5.0 -> 7.0)" in line and "model.gravity" in line, line
    assert "run.duration" not in line  # the one key a resume may change
    assert (directory / "trajectory.dcd").read_bytes() == before
    path.write_text(text)  # undone: resumes, and equals the uninterrupted run
    assert main(["run", "--resume", str(directory), "--no-progress"]) == 0
    _same_as(directory, reference)


def test_resume_with_duration_extends_a_finished_run(tmp_path, reference, capsys):
    directory = tmp_path / "short"
    cfg = RunConfig.from_dict(SETTINGS).replace({"run.duration": 3.5})
    run(cfg, directory=directory, progress=False)
    (directory / ANALYSIS_FILE).write_text("{}")
    assert main(["run", "--resume", str(directory), "--no-progress"]) == 2
    line = _one_line(capsys)
    assert line.startswith("knotmm: error: --resume") and "already finished" in line, line
    assert "--duration" in line  # says how to extend it
    assert main(["run", "--resume", str(directory), "--duration", "3.0"]) == 2
    capsys.readouterr()
    assert main(["run", "--resume", str(directory), "--duration", "6", "--no-progress"]) == 0
    _same_as(directory, reference)
    facts = _facts(directory)
    assert facts["status"] == "finished" and facts["time_reached"] == pytest.approx(6.0)
    assert read_toml(directory / "run.toml")["run"]["duration"] == 6.0
    assert facts["evaluations"] == _facts(reference)["evaluations"]  # item 12
    assert not (directory / ANALYSIS_FILE).exists()  # item 12: the stale analysis is gone


# -- item 4: I/O errors -------------------------------------------------------------------------
def _fail_at_frame(monkeypatch, frame: int, error: int):
    report = DCDReporter.report

    def failing(self, simulation, state):
        if self.index == frame:
            def write_frame(positions):
                self._file.write(b"\0" * 100)  # part of a frame got out before the disk filled
                self._file.flush()
                raise OSError(error, os.strerror(error))

            self._write_frame = write_frame
        report(self, simulation, state)

    monkeypatch.setattr(DCDReporter, "report", failing)


def test_a_full_disk_during_the_run_is_a_fault_that_resumes(tmp_path, reference, monkeypatch,
                                                            capsys):
    directory = tmp_path / "run"
    run_file = tmp_path / "run.toml"
    run_file.write_text(
        "[knot]\nbeads = 40\n[run]\nduration = 6.0\ntopology_check_interval = 0.0\n"
        f"[output]\ndirectory = {str(directory)!r}\nframe_interval = 0.5\n"
        "checkpoint_interval = 1.0\n"
    )
    _fail_at_frame(monkeypatch, 7, errno.ENOSPC)
    assert main(["run", str(run_file), "--no-progress"]) == 3
    line = _one_line(capsys)
    assert "trajectory.dcd" in line and "no space left" in line and "--resume" in line, line
    facts = _facts(directory)
    assert facts["status"] == "fault" and "no space left" in facts["message"]
    assert len(_frames(directory)) == 7  # every whole frame kept, the partial one dropped
    assert not (directory / LOCK_FILE).exists()
    monkeypatch.undo()  # space freed
    assert main(["run", "--resume", str(directory), "--no-progress"]) == 0
    _same_as(directory, reference)


def test_unwritable_before_the_start_is_one_line_exit_2(tmp_path, monkeypatch, capsys):
    import knotmm.io.pdb

    def denied(path, positions, *args, **kwargs):
        raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(path))

    monkeypatch.setattr(knotmm.io.pdb, "write_pdb", denied)
    directory = tmp_path / "run"
    assert main(["run", "--beads", "40", "--duration", "1", "--out", str(directory)]) == 2
    line = _one_line(capsys)
    assert "topology.pdb" in line and "permission denied" in line, line
    assert not (directory / "run.toml").exists()  # never "running"
    assert not (directory / LOCK_FILE).exists()


def _mount_tmpfs(path: Path, size: str) -> bool:
    if os.geteuid() != 0 or shutil.which("mount") is None:
        return False
    path.mkdir()
    result = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)],
                            capture_output=True)
    return result.returncode == 0


@pytest.fixture
def tiny_disk(tmp_path):
    disk = tmp_path / "disk"
    if not _mount_tmpfs(disk, "1m"):
        pytest.skip("needs root and a mountable tmpfs")
    yield disk
    subprocess.run(["umount", str(disk)], check=True)


def test_a_real_full_disk_and_a_read_only_one(tiny_disk, reference):
    """On a 1 MB tmpfs: a run fills it (exit 3, status fault, frames kept), resumes once
    space is free; on the same disk mounted read-only a run is refused before it starts."""
    directory = tiny_disk / "run"
    run_file = tiny_disk.parent / "run.toml"
    run_file.write_text(
        "[knot]\nbeads = 40\n[run]\nduration = 6.0\ntopology_check_interval = 0.0\n"
        f"[output]\ndirectory = {str(directory)!r}\nframe_interval = 0.5\n"
        "checkpoint_interval = 1.0\n"
    )
    free = os.statvfs(tiny_disk).f_bavail * os.statvfs(tiny_disk).f_frsize
    filler = tiny_disk / "filler"
    # eleven pages left: a few frames fit, and the last checkpoint (the plugin engine's
    # holds the Context's, ~4 kB more at N = 40)
    filler.write_bytes(b"\0" * (free - 11 * 4096))
    cmd = [sys.executable, "-m", "knotmm.cli.main", "run", str(run_file), "--no-progress"]
    first = subprocess.run(cmd, capture_output=True, text=True)
    assert first.returncode == 3, first.stderr
    errors = [line for line in first.stderr.splitlines() if line.startswith("knotmm")]
    assert len(errors) == 1 and "no space left" in errors[0], first.stderr
    assert _facts(directory)["status"] == "fault"
    kept = len(_frames(directory))
    assert 0 < kept < 13
    filler.unlink()
    again = subprocess.run([*cmd[:4], "--resume", str(directory), "--no-progress"],
                           capture_output=True, text=True)
    assert again.returncode == 0, again.stderr
    _same_as(directory, reference)

    subprocess.run(["mount", "-o", "remount,ro", str(tiny_disk)], check=True)
    refused = subprocess.run([*cmd[:4], "--beads", "40", "--duration", "1", "--out",
                              str(tiny_disk / "other")], capture_output=True, text=True)
    assert refused.returncode == 2
    errors = [line for line in refused.stderr.splitlines() if line.startswith("knotmm")]
    assert len(errors) == 1 and "read-only file system" in errors[0], refused.stderr


# -- item 12: progress when standard error is not a terminal -----------------------------------
def test_progress_lines_when_stderr_is_not_a_terminal(tmp_path, capsys):
    assert main(["run", "--beads", "40", "--duration", "2", "--set", "output.frame_interval=0.1",
                 "--set", "run.topology_check_interval=0", "--out", str(tmp_path / "r")]) == 0
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 10 and lines[-1].startswith("knotmm: t = 2 / 2 tau_d (100 %)"), lines


# -- item 11: stopping -------------------------------------------------------------------------
def _started(run_file: Path, directory: Path) -> subprocess.Popen:
    proc = subprocess.Popen(
        [sys.executable, "-m", "knotmm.cli.main", "run", str(run_file), "--no-progress"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
    )
    deadline = time.monotonic() + 120
    while not (directory / "checkpoint.npz").exists():
        assert proc.poll() is None and time.monotonic() < deadline
        time.sleep(0.02)
    return proc


def _long_run_file(tmp_path: Path, directory: Path) -> Path:
    run_file = tmp_path / "long.toml"
    run_file.write_text(
        "[knot]\nbeads = 40\n[run]\nduration = 5000.0\ntopology_check_interval = 0.5\n"
        f"[output]\ndirectory = {str(directory)!r}\n"
    )
    return run_file


def test_sigterm_stops_the_run_within_a_second(tmp_path):
    """The run stops, checkpoints, records the signal and lets go of the directory within a
    second of SIGTERM (knot checks on). What the interpreter does after the command has
    returned (tearing its modules down) is knotmm.cli.main's to keep short."""
    directory = tmp_path / "run"
    proc = _started(_long_run_file(tmp_path, directory), directory)
    sent = time.monotonic()
    proc.send_signal(signal.SIGTERM)
    while (directory / LOCK_FILE).exists():
        assert time.monotonic() - sent < 1.0, "the run did not stop within a second"
        time.sleep(0.005)
    proc.communicate(timeout=60)
    gone = time.monotonic() - sent
    assert proc.returncode == 130
    # the whole process, interpreter teardown included (knotmm.cli.main skips the teardown
    # after a stop); 1 s is the promise, the margin is for a loaded CI machine
    assert gone < 2.0, f"the process lingered {gone:.2f} s after SIGTERM"
    facts = _facts(directory)
    assert facts["status"] == "interrupted" and facts["message"] == "interrupted by SIGTERM"


def test_kill_9_leaves_no_leaked_semaphore_warning(tmp_path):
    directory = tmp_path / "run"
    proc = _started(_long_run_file(tmp_path, directory), directory)
    proc.kill()
    proc.wait()
    err = proc.stderr.read()  # EOF once every process holding the pipe (helpers) is gone
    assert "leaked" not in err and "resource_tracker" not in err, err
    assert main(["run", "--resume", str(directory), "--duration", "1", "--no-progress"]) == 0


def test_signals_wait_for_the_last_run_toml_write():
    """A second Ctrl-C stops at once, but not in the middle of recording the outcome."""
    from knotmm.workflow import _signals_held

    seen = []
    previous = signal.signal(signal.SIGTERM, lambda signum, frame: seen.append(signum))
    try:
        with _signals_held():
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(0.05)
            assert seen == []
        for _ in range(200):
            if seen:
                break
            time.sleep(0.005)
        assert seen == [signal.SIGTERM]
    finally:
        signal.signal(signal.SIGTERM, previous)


def test_stop_on_change_without_topoly_is_refused(tmp_path, monkeypatch, capsys):
    """Issue 11, item 9: a stop request that cannot be honoured is an error, not dropped."""
    import knotmm.knots.identify

    monkeypatch.setattr(knotmm.knots.identify, "topoly_available", lambda: False)
    directory = tmp_path / "run"
    args = ["run", "--beads", "40", "--duration", "1", "--no-progress", "--out", str(directory),
            "--set", 'run.on_topology_change="stop"']
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "on_topology_change" in err[0] and "topoly" in err[0], err
    assert not directory.exists()
    # "warn" still runs unchecked
    assert main(args[:-1] + ['run.on_topology_change="warn"']) == 0
