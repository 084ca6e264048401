"""Tests of knotmm.knots.worker: topoly in a process of knotmm's own, started as a module."""

from __future__ import annotations

import logging
import os
import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from knotmm.knots.identify import topoly_available
from knotmm.knots.worker import IsolatedKnotIdentifier, WorkerProcess, shared_worker

needs_topoly = pytest.mark.skipif(not topoly_available(), reason="topoly not installed")


@pytest.fixture
def trefoil(torus_curve):
    return torus_curve(2, 3, 60)


def mirror_image(x):
    return x * np.array([1.0, 1.0, -1.0])


@needs_topoly
def test_requests_are_answered_in_order_beside_the_caller(trefoil, torus_curve):
    worker = shared_worker()  # the one identify_knot uses (started once per process)
    mirror = mirror_image(trefoil)
    handles = [worker.submit(x, chiral=True) for x in (trefoil, mirror, torus_curve(2, 5, 100))]
    handles.append(worker.submit(torus_curve(2, 5, 100), chiral=False, minimal=False))
    names = [h.result() for h in handles]
    assert names[:3] == ["+3_1", "-3_1", "+5_1"]
    assert set(names[3].split("|")) == {"5_1", "10_132"}
    assert all(h.done() for h in handles)


@needs_topoly
def test_a_lost_worker_skips_its_checks_and_is_replaced(trefoil, caplog):
    """A worker that dies (a crash in topoly) or takes too long: its checks give None, a
    warning is logged, and the next check starts a new worker. The worker that takes too
    long is a stopped one (SIGSTOP): a slow knot as the test once used can come back as
    'unknown' within the timeout on a loaded machine."""
    ident = IsolatedKnotIdentifier(chiral=True, own_process=True)
    try:
        handle = ident.submit(trefoil)
        ident._worker._proc.kill()
        with caplog.at_level(logging.WARNING, logger="knotmm.knots.worker"):
            assert handle.result() is None
            assert "stopped" in caplog.text
            assert ident(trefoil) == "+3_1"  # a new worker
            first = ident._worker._proc
            os.kill(first.pid, signal.SIGSTOP)  # busy for ever: it cannot answer
            ident.timeout = 0.2
            assert ident(trefoil) is None
            assert "took over" in caplog.text
            assert first.poll() is not None  # the busy worker was stopped, not left running
        ident.timeout = 120.0
        assert ident(mirror_image(trefoil)) == "-3_1"
    finally:
        ident.close()
    assert not ident._worker.running


@needs_topoly
def test_identifiers_share_one_worker_unless_asked(trefoil):
    a, b = IsolatedKnotIdentifier(), IsolatedKnotIdentifier(chiral=False)
    assert a._worker is b._worker is shared_worker()
    assert (a(trefoil), b(trefoil)) == ("+3_1", "3_1")
    a.close()  # idle: the shared worker is kept for the next caller
    assert shared_worker().running


def test_no_worker_means_no_answer_and_a_warning(trefoil, monkeypatch, caplog):
    worker = WorkerProcess()
    monkeypatch.setattr(sys, "executable", "")
    with caplog.at_level(logging.WARNING, logger="knotmm.knots.worker"):
        assert worker.identify(trefoil) is None
    assert "not checked" in caplog.text


@needs_topoly
def test_the_worker_never_imports_the_callers_main(tmp_path):
    """A script without ``if __name__ == "__main__":`` runs once, not once per worker."""
    script = tmp_path / "unguarded.py"
    script.write_text(
        textwrap.dedent(
            """
            import numpy as np
            from knotmm.knots.worker import IsolatedKnotIdentifier

            print("script body", flush=True)
            t = np.linspace(0, 4 * np.pi, 60, endpoint=False)
            rho = 3 + np.sin(1.5 * t)
            x = np.c_[rho * np.cos(t), rho * np.sin(t), np.cos(1.5 * t)]
            ident = IsolatedKnotIdentifier()
            print(ident(x), flush=True)
            """
        )
    )
    done = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=120, cwd=tmp_path
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == ["script body", "+3_1"]
    assert done.stderr == ""


@needs_topoly
@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs fork")
def test_a_forked_child_starts_its_own_worker(trefoil):
    """A child forked from a process with a worker (a sweep's process pool) gets its own."""
    worker = shared_worker()
    assert worker.identify(trefoil, chiral=True) == "+3_1"
    parent_proc = worker._proc
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # pragma: no cover - the child
        ok = False
        try:
            ok = worker.identify(trefoil, chiral=True) == "+3_1" and worker._proc is not parent_proc
            worker.close()
        finally:
            os.write(write, b"1" if ok else b"0")
            os._exit(0)
    os.close(write)
    assert os.read(read, 1) == b"1"
    os.waitpid(pid, 0)
    os.close(read)
    assert worker._proc is parent_proc and worker.identify(trefoil) == "3_1"
