"""Running sweeps: local processes, failing points, resume, a crashed worker, Dask.

The runs are tiny (30-36 beads, 9 tau_d, no knot-type checks, analysis without knot
identification or plots); the mixed sweep whose summary is checked runs 20 tau_d, long
enough to swirl (below).
"""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from knotmm.analysis import load_run
from knotmm.config import read_toml
from knotmm.errors import ConfigError
from knotmm.sweep import Sweep, read_summary, run_point, run_sweep
from knotmm.sweep.plan import plan_point

TINY = {
    "knot": {"beads": 30},
    # no knot-type checks during the runs: these tests are about the sweep machinery
    "run": {"duration": 9.0, "topology_check_interval": 0.0},
    "output": {"frame_interval": 0.5},
}


#: The mixed sweep's duration, tau_d. N = 30 and 36 swirl with tau_swirl = 4.8 and 4.9 tau_d;
#: the detector needs two periods in the window after the relaxation (at 9 tau_d N = 36 has
#: 7.5 tau_d: a red spectrum, no tau_swirl), 20 tau_d gives about three.
SWIRLING = 20.0


def tiny_sweep(directory, run_duration: float | None = None, **sweep) -> Sweep:
    data = {k: dict(v) for k, v in TINY.items()}
    if run_duration is not None:
        data["run"]["duration"] = run_duration
    data["output"]["directory"] = str(directory)
    data["sweep"] = {"knot_samples": 0, "plots": False, **sweep}
    return Sweep.from_dict(data)


# four points: two that finish, one whose template is invalid, one that faults at once
MIXED = {
    "mode": "zip",
    "knot.beads": [30, 36, 20, 30],
    "run.max_bond_length": [3.0, 3.0, 3.0, 0.6001],
}


@pytest.fixture(scope="module")
def local_sweep(tmp_path_factory):
    directory = tmp_path_factory.mktemp("local") / "sweep"
    sweep = tiny_sweep(directory, SWIRLING, **MIXED)
    result = run_sweep(sweep, workers=2, progress=False)
    return sweep, result


def test_local_sweep_isolates_failing_points(local_sweep):
    sweep, result = local_sweep
    status = [r["status"] for r in result.rows]
    assert status == ["finished", "finished", "error", "fault"]
    bad_template, fault = result.rows[2], result.rows[3]
    assert bad_template["error"].startswith("TemplateError: knot.beads=20 is too few")
    assert fault["error"].startswith("SimulationFault: bond")
    assert result.ran == 4 and result.skipped == 0
    assert "2 failed" in result.report()


def test_summary_and_point_directories(local_sweep):
    sweep, result = local_sweep
    rows = read_summary(result.directory)
    assert [r["point"] for r in rows] == [p.name for p in sweep.points]
    assert [r["knot.beads"] for r in rows] == [30, 36, 20, 30]
    assert [r["run.max_bond_length"] for r in rows] == [3.0, 3.0, 3.0, 0.6001]
    for row in rows[:2]:
        for key in (
            "tau_swirl",
            "tau_sed",
            "tau_rot",
            "sedimentation_velocity",
            "major_radius",
            "swirl_amplitude",
            "tau_swirl_over_tau_sed",
            "tau_rot_over_tau_sed",
        ):
            assert isinstance(row[key], float) and row[key] > 0, key
        assert row["time_reached"] == SWIRLING
        point_dir = result.directory / row["directory"]
        assert (point_dir / "analysis.json").exists()
        data = load_run(point_dir)  # an ordinary run directory
        assert data.positions.shape == (41, row["knot.beads"], 3)
    assert rows[2]["tau_sed"] is None
    assert (result.directory / "ratios.png").stat().st_size > 1000
    assert (result.directory / "sweep.toml").exists()


def test_dask_cluster_gives_the_same_rows(local_sweep, tmp_path):
    distributed = pytest.importorskip("distributed")
    sweep, local = local_sweep
    directory = tmp_path / "dask"
    other = tiny_sweep(directory, SWIRLING, **MIXED)
    with distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
        worker_dashboard_address=None,
    ) as cluster:
        result = run_sweep(other, scheduler=cluster.scheduler_address, progress=False)
    dask_rows, local_rows = read_summary(directory), read_summary(local.directory)
    for a, b in zip(dask_rows, local_rows, strict=True):
        differ = {k: (a[k], b[k]) for k in a if a[k] != b[k]}
        assert not differ, f"{a['point']}: {differ}"
    assert [r["status"] for r in result.rows] == ["finished", "finished", "error", "fault"]


def test_dask_missing_is_a_clear_error(monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "distributed", None)
    sweep = tiny_sweep(tmp_path / "s", **{"knot.beads": [30]})
    with pytest.raises(ConfigError, match=r"Dask is not installed.*knotmm\[cluster\]"):
        run_sweep(sweep, scheduler="tcp://127.0.0.1:8786")
    assert not (tmp_path / "s").exists()


def interrupting_point(task):
    """Run the first point, then behave like Ctrl-C."""
    if task["name"] != "knot.beads=30":
        raise KeyboardInterrupt
    return run_point(task)


def test_resume_after_interrupted_sweep(tmp_path):
    directory = tmp_path / "resume"
    sweep = tiny_sweep(directory, **{"knot.beads": [30, 32, 34]})
    with pytest.raises(KeyboardInterrupt):
        run_sweep(sweep, workers=0, progress=False, _point_function=interrupting_point)
    rows = read_summary(directory)  # a valid summary is left behind
    assert [r["status"] for r in rows] == ["finished", "pending", "pending"]
    first = directory / "knot.beads=30" / "analysis.json"
    stamp = first.stat().st_mtime_ns

    result = run_sweep(sweep, workers=0, progress=False)
    assert (result.ran, result.resumed, result.analysed, result.skipped) == (2, 0, 0, 1)
    assert [r["status"] for r in result.rows] == ["finished"] * 3
    assert first.stat().st_mtime_ns == stamp
    assert read_summary(directory)[0] == rows[0]

    # an interrupted run is resumed, a run whose analysis never ran is analysed, a fault rerun
    toml = directory / "knot.beads=34" / "run.toml"
    toml.write_text(toml.read_text().replace('status = "finished"', 'status = "interrupted"'))
    (directory / "knot.beads=32" / "analysis.json").unlink()
    before = read_summary(directory)
    result = run_sweep(sweep, workers=0, progress=False)
    assert (result.ran, result.resumed, result.analysed, result.skipped) == (0, 1, 1, 1)
    assert read_summary(directory) == before  # deterministic: the same numbers again


def test_changed_parameters_are_run_again(local_sweep, tmp_path):
    sweep, result = local_sweep
    point = sweep.points[0]
    assert plan_point(point, result.directory / point.name, False)[0] == "skip"
    assert plan_point(point, result.directory / point.name, True)[0] == "analyze"
    changed = tiny_sweep(result.directory, SWIRLING, **{**MIXED, "knot.minor_radius": [0.5] * 4})
    assert plan_point(changed.points[0], result.directory / point.name, False)[0] == "run"


def test_foreign_directory_is_refused(tmp_path):
    from knotmm.errors import RunDirectoryError

    (tmp_path / "notes.txt").write_text("mine")
    with pytest.raises(RunDirectoryError, match="holds no knotmm sweep"):
        run_sweep(tiny_sweep(tmp_path, **{"knot.beads": [30]}), workers=0)


def crashing_point(task):
    """A point function whose third point kills its worker process."""
    if task["name"] == "knot.beads=34":
        os._exit(1)
    return {"name": task["name"], "status": "finished", "error": None, "values": {"tau_sed": 1.0}}


def test_a_crashed_worker_fails_only_its_point(tmp_path):
    sweep = tiny_sweep(tmp_path / "crash", **{"knot.beads": [30, 32, 34]})
    result = run_sweep(sweep, workers=2, progress=False, _point_function=crashing_point)
    assert [r["status"] for r in result.rows] == ["finished", "finished", "error"]
    assert "worker process died" in result.rows[2]["error"]


def sleeping_point(task):
    """A point function that waits long enough to be stopped."""
    import time

    Path(task["started"]).touch()
    time.sleep(60.0)
    return {"name": task["name"], "status": "finished", "error": None, "values": {}}


def test_a_stopped_pool_leaves_no_semaphore_behind(monkeypatch, tmp_path):
    """Ctrl-C: the pool's semaphores are unlinked before the sweep raises, even where its
    manager thread ends late (a loaded machine). ``knotmm sweep`` then exits at once
    (``os._exit``); a semaphore still registered then was reported by multiprocessing's
    resource tracker as "leaked semaphore objects" on the user's terminal."""
    import signal
    import threading
    import time
    from concurrent.futures import process
    from multiprocessing import resource_tracker

    from knotmm.sweep.local import run_local

    made, freed = set(), set()
    register, unregister = resource_tracker.register, resource_tracker.unregister

    def counted_register(name, rtype):
        made.add(name)
        register(name, rtype)

    def counted_unregister(name, rtype):
        freed.add(name)
        unregister(name, rtype)

    join = process._ExecutorManagerThread.join_executor_internals

    def slow_join(self):
        time.sleep(2.0)  # the manager thread of a loaded machine, which ends late
        join(self)

    monkeypatch.setattr(resource_tracker, "register", counted_register)
    monkeypatch.setattr(resource_tracker, "unregister", counted_unregister)
    monkeypatch.setattr(process._ExecutorManagerThread, "join_executor_internals", slow_join)
    started = tmp_path / "started"

    def stop_once_started():  # Ctrl-C while the point runs (not while the pool starts)
        end = time.monotonic() + 120
        while not started.exists() and time.monotonic() < end:
            time.sleep(0.05)
        os.kill(os.getpid(), signal.SIGINT)

    # Ctrl-C as the command line has it (an earlier test in this process may have left
    # another handler)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    stopper = threading.Thread(target=stop_once_started, daemon=True)
    stopper.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            run_local([{"name": n, "started": str(started)} for n in "ab"], 1,
                      lambda row: None, sleeping_point)
    finally:
        signal.signal(signal.SIGINT, previous)
    stopper.join()
    assert len(made) == 5  # one pool: its call queue (3) and its result queue (2)
    assert made - freed == set()
    assert not [t for t in threading.enumerate()
                if isinstance(t, process._ExecutorManagerThread) and t.is_alive()]


@pytest.mark.slow
def test_ctrl_c_then_resume_from_the_command_line(tmp_path):
    """Send SIGINT to `knotmm sweep` after its first point, then finish the sweep."""
    import signal
    import subprocess
    import time

    path = tmp_path / "s.toml"
    out = tmp_path / "out"
    path.write_text(
        f'[knot]\nbeads = 40\n[run]\nduration = 60.0\n[output]\ndirectory = "{out}"\n'
        f'[sweep]\n"knot.beads" = [40, 44, 48, 52, 56, 60]\nknot_samples = 0\nplots = false\n'
    )
    cmd = [sys.executable, "-m", "knotmm.cli", "sweep", str(path), "--workers", "2"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            summary = out / "summary.csv"
            if summary.exists() and "finished" in summary.read_text():
                break
            time.sleep(0.2)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    rows = read_summary(out)
    assert "finished" in [r["status"] for r in rows]
    assert "pending" in [r["status"] for r in rows]
    # a point stopped while simulating finished its step and checkpointed that state
    stopped = []
    for run_toml in out.glob("*/run.toml"):
        facts = read_toml(run_toml)["knotmm"]
        if facts.get("status") == "interrupted":
            with np.load(run_toml.parent / "checkpoint.npz") as data:
                stopped.append((float(data["time"]), facts["time_reached"]))
    assert all(a == b for a, b in stopped), stopped
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert [r["status"] for r in read_summary(out)] == ["finished"] * 6
    shutil.rmtree(out)
