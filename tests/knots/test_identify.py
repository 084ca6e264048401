"""Tests of knotmm.knots.identify: knot types named by topoly, through the worker process."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from knotmm.knots import identify
from knotmm.knots.homfly import _fd_open
from knotmm.knots.identify import UNKNOWN, identify_knot, topoly_available

needs_topoly = pytest.mark.skipif(not topoly_available(), reason="topoly not installed")


@needs_topoly
@pytest.mark.parametrize(
    ("p", "q", "name"), [(2, 3, "3_1"), (3, 2, "3_1"), (2, 5, "5_1"), (2, 7, "7_1"), (3, 4, "8_19")]
)
def test_identify_torus_knots(p, q, name, torus_curve):
    assert identify_knot(torus_curve(p, q, 150)) == name


@needs_topoly
def test_identify_unknot_and_chirality(torus_curve):
    t = np.linspace(0.0, 2.0 * np.pi, 40, endpoint=False)
    assert identify_knot(np.c_[np.cos(t), np.sin(t), 0.1 * np.sin(2 * t)]) == "0_1"
    x = torus_curve(2, 3, 100)
    assert identify_knot(x, chiral=True) == "+3_1"
    assert identify_knot(x * np.array([1.0, 1.0, -1.0]), chiral=True) == "-3_1"


@needs_topoly
def test_identify_knot_lists_knots_with_the_same_polynomial(torus_curve):
    x = torus_curve(2, 5, 120)
    assert identify_knot(x) == "5_1"
    assert set(identify_knot(x, minimal=False).split("|")) == {"5_1", "10_132"}


@needs_topoly
def test_identify_knot_is_silent_and_keeps_stdin(capfd, torus_curve):
    has_stdin = _fd_open(0)
    before = os.fstat(0) if has_stdin else None
    for _ in range(3):
        identify_knot(torus_curve(2, 5, 80))
    out, err = capfd.readouterr()
    assert out == "" and err == ""
    if has_stdin:
        after = os.fstat(0)
        assert (after.st_ino, after.st_dev) == (before.st_ino, before.st_dev)


@needs_topoly
def test_identify_knot_too_complex_is_unknown(torus_curve):
    x = torus_curve(3, 7, 300)
    assert identify_knot(x, max_cross=5) == UNKNOWN


def test_identify_knot_without_topoly(monkeypatch, torus_curve):
    monkeypatch.setattr(identify, "topoly_available", lambda: False)
    assert identify_knot(torus_curve(2, 3, 60)) is None


def test_identify_knot_rejects_batches():
    with pytest.raises(ValueError, match="one frame"):
        identify_knot(np.zeros((2, 10, 3)))


def test_identify_knot_keeps_python_signal_handlers():
    """topoly's C code installs its own termination handlers; ours must survive a call."""
    import os
    import signal
    import time

    from knotmm.knots.identify import identify_knot, topoly_available
    from knotmm.shapes import torus_knot

    if not topoly_available():
        pytest.skip("needs topoly")
    hits = []
    previous = signal.signal(signal.SIGTERM, lambda *args: hits.append(1))
    try:
        assert identify_knot(torus_knot(2, 3, 60)) == "3_1"
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(0.05)
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert hits == [1]


def test_identify_knot_leaves_the_recursion_limit_alone():
    """topoly raises Python's recursion limit on every call; the caller's must come back."""
    import sys

    from knotmm.knots.identify import identify_knot, topoly_available
    from knotmm.shapes import torus_knot

    if not topoly_available():
        pytest.skip("needs topoly")
    before = sys.getrecursionlimit()
    sys.setrecursionlimit(1234)
    try:
        assert identify_knot(torus_knot(2, 3, 60)) == "3_1"
        assert sys.getrecursionlimit() == 1234
    finally:
        sys.setrecursionlimit(before)


@needs_topoly
def test_topoly_guard_in_the_process_that_runs_topoly(tmp_path):
    """In the worker's own process (here: a fresh interpreter) topoly closes descriptor 0,
    prints from C, installs signal handlers and raises the recursion limit; the guard
    undoes each, call after call."""
    script = tmp_path / "guard.py"
    script.write_text(
        "import os, signal, sys, time\n"
        "import numpy as np\n"
        "from knotmm.knots.homfly import identify_here\n"
        "t = np.linspace(0, 4 * np.pi, 80, endpoint=False)\n"
        "rho = 3 + np.sin(1.5 * t)\n"
        "x = np.c_[rho * np.cos(t), rho * np.sin(t), np.cos(1.5 * t)]\n"
        "before = os.fstat(0)\n"
        "hits = []\n"
        "signal.signal(signal.SIGTERM, lambda *a: hits.append(1))\n"
        "sys.setrecursionlimit(1234)\n"
        "names = [identify_here(x, chiral=True) for _ in range(3)]\n"
        "after = os.fstat(0)\n"
        "os.kill(os.getpid(), signal.SIGTERM)\n"
        "time.sleep(0.05)\n"
        "sys.stderr.write(repr((names, (before.st_ino, before.st_dev) == (after.st_ino,"
        " after.st_dev), hits, sys.getrecursionlimit())))\n"
    )
    with open(script) as stdin:
        done = subprocess.run(
            [sys.executable, str(script)], stdin=stdin, capture_output=True, text=True,
            timeout=120,
        )
    assert done.returncode == 0, done.stderr
    assert done.stdout == ""  # topoly's own prints were silenced
    assert done.stderr.strip() == repr((["+3_1"] * 3, True, [1], 1234))


def test_identify_knot_never_imports_topoly_here(torus_curve):
    """topoly runs in the worker only: its import, prints and handlers stay out of here."""
    assert identify_knot(torus_curve(2, 3, 60), chiral=True) in (None, "+3_1")
    assert "topoly" not in sys.modules
