"""``knotmm analyze`` on a run that is still running (issue 23, item 4).

It used to exit 0 with an ``analysis.json`` saying "the run stopped early" although the run
held its directory's lock, and that file stayed after the run ended. Now the analysis says
"run still running at t = ..." (in analysis.json and on screen), and the run, when it ends
(here by Ctrl-C; finishing records its status the same way), removes an analysis older than
its last frame.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time

from test_run_fuzz import RUN_OPTIONS, _call, _default_sigint, _kill, _status, _wait_running

from knotmm.cli.main import main
from knotmm.io.dcd import dcd_layout


def _wait_frames(directory, proc, n, timeout=120.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        assert proc.poll() is None, proc.communicate()
        try:
            if dcd_layout(directory / "trajectory.dcd").complete_frames >= n:
                return
        except Exception:  # noqa: BLE001 - not written yet
            pass
        time.sleep(0.05)
    raise AssertionError(f"fewer than {n} frames after {timeout} s")


def test_analysis_of_a_live_run_says_so_and_is_retired_when_the_run_ends(tmp_path, capsys):
    directory = tmp_path / "live"
    argv = [sys.executable, "-m", "knotmm.cli", "run", "--out", str(directory), "--duration",
            "500", "--set", "output.frame_interval=0.1", *RUN_OPTIONS]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_default_sigint)
    try:
        assert _wait_running(directory, proc, timeout=120)
        _wait_frames(directory, proc, 24)
        code = main(["analyze", str(directory), "--knot-samples", "0", "--no-plots"])
        shown = capsys.readouterr()
        assert code == 0 and "Traceback" not in shown.err, shown.err
        shown = shown.out
        analysis = json.loads((directory / "analysis.json").read_text())
        notes = analysis["notes"]
        assert any(n.startswith("run still running at t = ") for n in notes), notes
        assert not any("stopped early" in n for n in notes), notes
        assert analysis["run_still_running"]["process"] == proc.pid
        assert "note: run still running at t = " in shown, shown
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        _kill(proc)
    assert proc.returncode == 130, err
    assert _status(directory) == "interrupted"
    # the run went on after the analysis: its end removed the stale analysis.json
    assert not (directory / "analysis.json").exists()
    code, _ = _call(["analyze", str(directory), "--knot-samples", "0", "--no-plots"], capsys,
                    "ended")
    assert code == 0
    notes = json.loads((directory / "analysis.json").read_text())["notes"]
    assert not any("still running" in n for n in notes), notes


def test_a_run_that_finishes_after_an_analysis_retires_it(tmp_path, capsys):
    """The same with a run that reaches its duration: its end retires the analysis made
    while it ran, or (when it ended during the analysis) the analysis was made again."""
    directory = tmp_path / "live"
    argv = [sys.executable, "-m", "knotmm.cli", "run", "--out", str(directory), "--duration",
            "40", "--set", "output.frame_interval=0.1", *RUN_OPTIONS]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert _wait_running(directory, proc, timeout=120)
        _wait_frames(directory, proc, 24)
        code, _ = _call(["analyze", str(directory), "--knot-samples", "0", "--no-plots"],
                        capsys, "live")
        assert code == 0
        _, err = proc.communicate(timeout=120)
    finally:
        _kill(proc)
    assert proc.returncode == 0, err
    assert _status(directory) == "finished"
    path = directory / "analysis.json"
    if path.exists():  # made again, of the whole run, because the run ended meanwhile
        analysis = json.loads(path.read_text())
        assert analysis["n_frames"] == 401 and "run_still_running" not in analysis
