"""Sweeps on a real Dask cluster: `dask scheduler` and `dask worker` as separate processes.

Issue 11 item 6: with a scheduler and workers started from the command line, every point
failed with ``OSError: [Errno 9] Bad file descriptor`` (topoly ran inside the worker process
while knotmm swapped its file descriptors). Here the cluster is made of real processes, the
sweep runs through ``knotmm sweep --scheduler``, and every process started is ended by its
process id. The knot-type checks run (when topoly is installed), so topoly is exercised; it
must never be imported by a Dask worker process itself.
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from knotmm.analysis import load_run
from knotmm.config import read_toml
from knotmm.knots.identify import topoly_available
from knotmm.sweep import load_sweep_file, read_summary, run_sweep

distributed = pytest.importorskip("distributed")

DASK = Path(sys.executable).with_name("dask")
pytestmark = pytest.mark.skipif(not DASK.exists(), reason="no `dask` command next to python")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def end(proc: subprocess.Popen) -> None:
    """End a process started here (and its process group, which it leads), by its id."""
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            pass
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(proc.pid, signal.SIGKILL)  # its nannies and workers, if any are left
    proc.wait(timeout=30)


@contextlib.contextmanager
def dask_cluster(directory: Path, nworkers: int = 2):
    """``dask scheduler`` and ``dask worker ADDRESS --nworkers N --nthreads 1``, as separate
    processes; yields ``(address, client)`` once every worker has joined."""
    directory.mkdir(parents=True, exist_ok=True)
    address = f"tcp://127.0.0.1:{free_port()}"
    procs: list[subprocess.Popen] = []
    client = None
    try:
        for name, cmd in (
            ("scheduler", [DASK, "scheduler", "--host", "127.0.0.1", "--port"]),
            ("worker", [DASK, "worker", address, "--nworkers", str(nworkers)]),
        ):
            if name == "scheduler":
                cmd = [*cmd, address.rsplit(":", 1)[1]]
            else:
                cmd = [*cmd, "--nthreads", "1", "--local-directory", str(directory / "space")]
            log = open(directory / f"{name}.log", "w")  # noqa: SIM115 - closed with the process
            procs.append(
                subprocess.Popen(
                    [*map(str, cmd), "--no-dashboard"],
                    stdout=log,
                    stderr=subprocess.STDOUT,
                    start_new_session=True,  # one process group per command, ended by its id
                )
            )
            log.close()
        client = distributed.Client(address, timeout="60s")
        client.wait_for_workers(nworkers, timeout=180)
        yield address, client
    finally:
        if client is not None:
            client.close()
        for proc in reversed(procs):
            end(proc)


def sweep_file(path: Path, out: Path, sweep: str, checks: bool, run: str = "") -> Path:
    interval = 1.0 if checks else 0.0
    path.write_text(
        "[knot]\nbeads = 30\nperturbation = 0.01\n"
        f"[run]\nduration = 9.0\ntopology_check_interval = {interval}\n{run}"
        f'[output]\nframe_interval = 0.5\ndirectory = "{out}"\n'
        f"[sweep]\n{sweep}\nknot_samples = {5 if checks else 0}\nplots = false\n"
    )
    return path


def knotmm_sweep(path: Path, address: str, **popen) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "knotmm.cli", "sweep", str(path), "--scheduler", address]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **popen)


def same_rows_and_trajectories(a: Path, b: Path) -> None:
    rows_a, rows_b = read_summary(a), read_summary(b)
    assert len(rows_a) == len(rows_b)
    for x, y in zip(rows_a, rows_b, strict=True):
        differ = {k: (x[k], y[k]) for k in x if x[k] != y[k]}
        assert not differ, f"{x['point']}: {differ}"
        pa, pb = load_run(a / x["directory"]).positions, load_run(b / y["directory"]).positions
        assert np.array_equal(pa, pb), x["point"]


def test_sweep_on_a_real_scheduler_and_worker_processes(tmp_path):
    checks = topoly_available()
    out = tmp_path / "out"
    path = sweep_file(tmp_path / "s.toml", out, '"run.duration" = [9.0, 9.5]', checks)
    with dask_cluster(tmp_path / "cluster") as (address, client):
        proc = knotmm_sweep(path, address)
        try:
            stdout, stderr = proc.communicate(timeout=600)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        imported = client.run(lambda: "topoly" in __import__("sys").modules)
    assert proc.returncode == 0, stdout + stderr
    rows = read_summary(out)
    assert [r["status"] for r in rows] == ["finished", "finished"], rows
    assert [r["time_reached"] for r in rows] == [9.0, 9.5]
    assert not any(imported.values()), f"topoly imported in a Dask worker: {imported}"
    for row in rows:
        facts = read_toml(out / row["directory"] / "run.toml")["knotmm"]
        if checks:  # the run's knot-type checks ran, off the worker process
            assert facts["knot_type_checks"] > 0
            assert row["knot_type_start"] == "+3_1"
    log = (tmp_path / "cluster" / "worker.log").read_text()
    assert "Bad file descriptor" not in log


@pytest.mark.slow
def test_killing_a_worker_mid_sweep_loses_nothing(tmp_path):
    """A 20-point sweep on a scheduler with two worker processes; one worker process is
    killed (SIGKILL) while it runs a point; every point still finishes, equal to a local
    sweep of the same file."""
    checks = topoly_available()
    out = tmp_path / "dask"
    # each seed a task of its own (stepped together, the 20 would be two tasks, over before
    # a worker could be seen busy after the first rows)
    path = sweep_file(tmp_path / "s.toml", out, "seeds = 20", checks,
                      run='replica_stepping = "one_after_another"\n')
    with dask_cluster(tmp_path / "cluster") as (address, client):
        pids = client.run(os.getpid)  # worker address -> its process id
        proc = knotmm_sweep(path, address)
        killed = None
        try:
            deadline = time.monotonic() + 600
            while killed is None and time.monotonic() < deadline and proc.poll() is None:
                time.sleep(0.2)
                summary = out / "summary.csv"
                if not summary.exists() or summary.read_text().count(",finished,") < 2:
                    continue
                busy = [a for a, keys in client.processing().items() if keys and a in pids]
                if busy:
                    killed = pids[busy[0]]
                    os.kill(killed, signal.SIGKILL)
            stdout, stderr = proc.communicate(timeout=900)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        after = client.run(os.getpid)
    assert killed is not None, "no worker was busy mid-sweep"
    assert killed not in after.values()  # it is gone (its nanny started another)
    assert proc.returncode == 0, stdout + stderr
    rows = read_summary(out)
    assert len(rows) == 20 and {r["status"] for r in rows} == {"finished"}
    assert "Bad file descriptor" not in (tmp_path / "cluster" / "worker.log").read_text()

    local = load_sweep_file(path, directory=tmp_path / "local")
    result = run_sweep(local, workers=2, progress=False)
    assert not result.failed
    same_rows_and_trajectories(out, tmp_path / "local")
