"""One owner per sweep directory (issue 23, item 6).

Two ``knotmm sweep`` on one directory: started together, the second said the directory "is
not empty and holds no knotmm sweep" (it was being created by the first); started 3 s later,
it ran again, with overwrite, points the first had already finished. A sweep now holds the
directory's lock (:class:`knotmm.io.rundir.RunLock`, the run directory's lock, with the
owner's process id) while it runs, and a second sweep is refused in one line naming it.

The owner here is a child process that takes the lock the way a sweep does and waits; the
sweeps under test get a point function that only records that it was called.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from test_sweep_run import tiny_sweep

from knotmm.cli.main import main
from knotmm.errors import RunDirectoryError
from knotmm.io.rundir import LOCK_FILE
from knotmm.sweep import run_sweep

HOLD = """
import sys, time
from knotmm.io.rundir import RunLock
lock = RunLock(sys.argv[1], "sweep")
print("locked", flush=True)
time.sleep(120)
"""



@pytest.fixture
def owner():
    """Start a process that holds a directory's lock; yield (start(directory), its pid)."""
    procs: list[subprocess.Popen] = []

    def start(directory: Path) -> int:
        proc = subprocess.Popen([sys.executable, "-c", HOLD, str(directory)],
                                stdout=subprocess.PIPE, text=True)
        procs.append(proc)
        assert proc.stdout.readline().strip() == "locked"
        return proc.pid

    yield start
    for proc in procs:
        if proc.poll() is None:
            os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)


def _recording(calls: list):
    def point(task):
        calls.append(task["name"])
        return {"name": task["name"], "status": "finished", "error": None, "values": {}}

    return point


def test_a_sweep_being_created_is_in_use_not_foreign(tmp_path, owner):
    """The first sweep has made the directory and is writing sweep.toml (a temporary)."""
    directory = tmp_path / "sweep"
    pid = owner(directory)
    (directory / ".sweep.toml.x1y2.tmp").write_text("[knot]\n")
    calls: list = []
    with pytest.raises(RunDirectoryError) as info:
        run_sweep(tiny_sweep(directory, **{"knot.beads": [30, 32]}), workers=0,
                  progress=False, _point_function=_recording(calls))
    message = str(info.value)
    assert f"process {pid}" in message and "in use" in message, message
    assert "holds no knotmm sweep" not in message
    assert calls == []


def test_a_second_sweep_reruns_nothing_while_the_first_runs(tmp_path, owner):
    """The first sweep has written sweep.toml and summary.csv and runs its points."""
    directory = tmp_path / "sweep"
    sweep = tiny_sweep(directory, **{"knot.beads": [30, 32, 34]})
    calls: list = []
    run_sweep(sweep, workers=0, progress=False, _point_function=_recording(calls))
    assert len(calls) == 3  # its points report "finished" without a run directory
    summary = (directory / "summary.csv").read_bytes()
    pid = owner(directory)
    calls.clear()
    with pytest.raises(RunDirectoryError, match=f"in use by process {pid}"):
        run_sweep(sweep, workers=0, progress=False, _point_function=_recording(calls))
    assert calls == []
    assert (directory / "summary.csv").read_bytes() == summary


def test_the_command_refuses_in_one_line_naming_the_owner(tmp_path, owner, capsys):
    directory = tmp_path / "sweep dir"
    path = tmp_path / "s.toml"
    path.write_text(
        f'[knot]\nbeads = 30\n[run]\nduration = 1.0\ntopology_check_interval = 0.0\n'
        f'[output]\ndirectory = "{directory}"\n'
        f'[sweep]\n"knot.beads" = [30, 32]\nknot_samples = 0\nplots = false\n'
    )
    pid = owner(directory)
    assert main(["sweep", str(path), "--workers", "0", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("knotmm: error: "), err
    assert f"process {pid}" in err[0], err
    assert sorted(p.name for p in directory.iterdir()) == [LOCK_FILE]  # nothing written


def test_the_lock_is_released_and_a_dead_owners_lock_taken_over(tmp_path, owner):
    directory = tmp_path / "sweep"
    sweep = tiny_sweep(directory, **{"knot.beads": [30]})
    calls: list = []
    run_sweep(sweep, workers=0, progress=False, _point_function=_recording(calls))
    assert not (directory / LOCK_FILE).exists()  # released, and its file removed
    # a sweep killed with SIGKILL leaves its lock file behind, with a dead pid: taken over
    (directory / LOCK_FILE).write_text("999999999\n")
    run_sweep(sweep, workers=0, progress=False, _point_function=_recording(calls))
    assert len(calls) == 2


@pytest.mark.slow
def test_two_sweep_commands_started_together(tmp_path):
    """Two real `knotmm sweep` processes on one directory: every point runs exactly once."""
    out = tmp_path / "out"
    path = tmp_path / "s.toml"
    path.write_text(
        f'[knot]\nbeads = 30\n[run]\nduration = 4.0\ntopology_check_interval = 0.0\n'
        f'[output]\ndirectory = "{out}"\nframe_interval = 0.25\n'
        f'[sweep]\n"knot.beads" = [30, 32, 34, 36, 38, 40]\nknot_samples = 0\nplots = false\n'
    )
    cmd = [sys.executable, "-m", "knotmm.cli", "sweep", str(path), "--workers", "1",
           "--no-progress"]
    first = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(0.05)
    second = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    outs = [p.communicate(timeout=300) for p in (first, second)]
    codes = sorted(p.returncode for p in (first, second))
    assert codes in ([0, 0], [0, 2]), outs
    runs = 0
    for proc, (stdout, stderr) in zip((first, second), outs, strict=True):
        if proc.returncode == 2:
            lines = stderr.strip().splitlines()
            assert len(lines) == 1 and "in use by process" in lines[0], stderr
            assert "holds no knotmm sweep" not in stderr
        else:
            runs += int(stdout.split("this time ")[1].split(" run")[0])
    assert runs == 6, outs
