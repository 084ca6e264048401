"""``knotmm run`` on the plugin engine answers signals and faults inside a stretch (issue 30,
BUG-13).

The audit's reproductions: a chain that blows up inside the first frame interval (Pe = 1e-6)
kept the plugin in one C++ ``stepTo`` for 8 minutes, deaf to SIGTERM and to two SIGINTs,
before it reported the bond fault the Python engine reports in a second; a run whose step
(``run.max_timestep = 1e-300``; now refused as needing over 2^63 steps, so 1e-14 here)
cannot reach the next frame ignored SIGTERM for 11 minutes.
Each case runs ``python -m knotmm.cli run`` in a child process with a deadline; a child still
alive then is killed by its pid, and the test fails.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

import knotmm.plugin

pytestmark = pytest.mark.skipif(not knotmm.plugin.available(),
                                reason=str(knotmm.plugin.load_error()))

BASE = ["--no-progress", "--duration", "2", "--set", "knot.beads=30",
        "--set", "run.engine=plugin", "--set", "run.topology_check_interval=0"]


def _status(directory: Path) -> str | None:
    try:
        with open(directory / "run.toml", "rb") as fh:
            return tomllib.load(fh).get("knotmm", {}).get("status")
    except (OSError, ValueError):
        return None


def _default_sigint() -> None:
    """In the child before exec: SIGINT to its default, as in a terminal's foreground job."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _start(directory: Path, *options: str) -> subprocess.Popen:
    argv = [sys.executable, "-m", "knotmm.cli", "run", "--out", str(directory), *BASE, *options]
    return subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_default_sigint)


def _finish(proc: subprocess.Popen, deadline: float) -> tuple[int | None, str]:
    """Wait up to ``deadline`` seconds; kill (by pid) and return None if it is still alive."""
    try:
        _, err = proc.communicate(timeout=deadline)
        return proc.returncode, err
    except subprocess.TimeoutExpired:
        os.kill(proc.pid, signal.SIGKILL)
        _, err = proc.communicate(timeout=30)
        return None, err


def _wait_running(directory: Path, proc: subprocess.Popen, timeout: float = 60.0) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end and proc.poll() is None:
        if _status(directory) == "running":
            return
        time.sleep(0.05)


def test_a_chain_that_blows_up_inside_a_stretch_faults_in_seconds(tmp_path):
    """Pe = 1e-6: bond 16 d after the first step; the Python engine faults in about 1 s."""
    directory = tmp_path / "run"
    start = time.monotonic()
    proc = _start(directory, "--set", "run.peclet=1e-6")
    code, err = _finish(proc, deadline=60)
    elapsed = time.monotonic() - start
    assert code == 3, f"exit {code} after {elapsed:.1f} s\n{err}"
    assert "Traceback" not in err
    assert "bond" in err and "past run.max_bond_length" in err, err
    assert _status(directory) == "fault"
    assert elapsed < 20, f"the fault took {elapsed:.1f} s"


@pytest.mark.parametrize("sig", ["SIGTERM", "SIGINT"])
def test_a_step_far_below_the_stretch_answers_a_signal_within_two_seconds(tmp_path, sig):
    """run.max_timestep = 1e-14: the next frame (2e12 steps away) is out of reach; the signal
    ends the run."""
    directory = tmp_path / "run"
    proc = _start(directory, "--set", "run.min_timestep=1e-320",
                  "--set", "run.max_timestep=1e-14")
    try:
        _wait_running(directory, proc)
        time.sleep(1.0)  # well inside the first stretch
        assert proc.poll() is None, proc.communicate()[1]
        sent = time.monotonic()
        os.kill(proc.pid, getattr(signal, sig))
        code, err = _finish(proc, deadline=20)
        elapsed = time.monotonic() - sent
    finally:
        if proc.poll() is None:
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait(timeout=30)
    assert code == 130, f"exit {code} {elapsed:.1f} s after {sig}\n{err}"
    assert elapsed < 2.5, f"{sig} answered after {elapsed:.2f} s"
    assert "Traceback" not in err
    assert _status(directory) == "interrupted"
