"""Issue 23 for ``knotmm orbit``: the output place checked before the computation, one-line
write failures (exit 3) with nothing half-written, the output directory locked and an
earlier orbit's files replaced, a continuation that keeps its points when stopped and
resumes, and extreme arguments refused in one line before any orbit is computed."""

from __future__ import annotations

import errno
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from knotmm.cli.main import main
from knotmm.io.rundir import LOCK_FILE, RunLock

ORBIT_FILES = {"orbit.json", "orbit.dcd", "topology.pdb", "mode_1.dcd", "orbit_multipliers.png"}


def _one_line(capsys, argv, code) -> str:
    got = main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert got == code, err
    assert len(err) == 1 and err[0].startswith("knotmm: error: "), err
    return err[0]


def _no_temporaries(directory) -> None:
    """Nothing half-written: no temporary file, no lock left in ``directory``."""
    left = [p.name for p in directory.iterdir() if p.name.startswith(".")]
    assert not left, left


@pytest.fixture
def no_computation(monkeypatch):
    """Fail the test if an orbit computation (a flow map) is started."""
    import knotmm.orbit.driver

    def refused(*args, **kwargs):
        raise AssertionError("the orbit computation started before the output was checked")

    monkeypatch.setattr(knotmm.orbit.driver, "make_flow", refused)


# -- item 1: the output place, checked first; failures while writing ----------------------------
def test_read_only_output_is_refused_before_the_computation(run40, tmp_path, capsys,
                                                            monkeypatch, no_computation):
    import tempfile

    ro = tmp_path / "ro"
    ro.mkdir()
    real_mkdir, real_mkstemp = os.mkdir, tempfile.mkstemp

    def mkdir(path, *args, **kwargs):  # a read-only file system: ro/ exists, nothing new
        if str(path).startswith(str(ro) + os.sep):
            raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(path))
        return real_mkdir(path, *args, **kwargs)

    def mkstemp(*args, dir=None, **kwargs):
        if dir is not None and str(dir).startswith(str(ro)):
            raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(dir))
        return real_mkstemp(*args, dir=dir, **kwargs)

    monkeypatch.setattr(os, "mkdir", mkdir)
    monkeypatch.setattr(tempfile, "mkstemp", mkstemp)
    line = _one_line(capsys, ["orbit", str(run40), "--modes", "1", "--out", str(ro / "orb")], 2)
    assert "read-only file system" in line and str(ro / "orb") in line, line
    line = _one_line(capsys, ["orbit", str(run40), "--modes", "0", "--out", str(ro)], 2)
    assert "read-only file system" in line and str(ro) in line, line
    assert list(ro.iterdir()) == []


def test_a_file_in_the_way_is_refused_before_the_computation(run40, tmp_path, capsys,
                                                             no_computation):
    (tmp_path / "f").write_text("x")
    line = _one_line(capsys, ["orbit", str(run40), "--out", str(tmp_path / "f")], 2)
    assert "is a file" in line, line
    line = _one_line(capsys, ["orbit", str(run40), "--out", str(tmp_path / "f" / "o")], 2)
    assert "not a directory" in line, line
    line = _one_line(capsys, ["orbit", str(run40), "--out", str(run40)], 2)
    assert "holds a knotmm run" in line, line  # the run's topology.pdb is never touched


def test_a_full_disk_while_writing_is_one_line_exit_3(run40, tmp_path, capsys, monkeypatch):
    import knotmm.io.dcd

    write_dcd = knotmm.io.dcd.write_dcd

    def full(path, positions):
        if path.name == "mode_1.dcd":
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
        write_dcd(path, positions)

    monkeypatch.setattr(knotmm.io.dcd, "write_dcd", full)
    out = tmp_path / "orb"
    line = _one_line(capsys, ["orbit", str(run40), "--modes", "1", "--out", str(out)], 3)
    assert "mode_1.dcd" in line and "no space left" in line and "orbit.json" in line, line
    assert {p.name for p in out.iterdir()} == {"orbit.json", "topology.pdb", "orbit.dcd"}
    assert json.loads((out / "orbit.json").read_text())["status"] == "converged"


def test_a_failing_writer_leaves_nothing_half_written(orbit40, tmp_path, monkeypatch):
    """mdtraj's DCD writer on a full disk raises a TypeError; a plot cut by EROFS."""
    import knotmm.io.dcd
    import knotmm.io.rundir
    import knotmm.orbit.output as output
    from knotmm.errors import KnotmmError

    flow, orbit, _ = orbit40
    result = _fake_floquet(orbit)
    out = tmp_path / "o"
    out.mkdir()

    def mdtraj_on_a_full_disk(path, positions):
        raise TypeError("'dict' object is not callable")

    monkeypatch.setattr(knotmm.io.dcd, "write_dcd", mdtraj_on_a_full_disk)
    monkeypatch.setattr(knotmm.io.rundir, "disk_full", lambda directory, needed=0: True,
                        raising=False)
    with pytest.raises(KnotmmError, match=r"orbit\.dcd.*no space left.*kept.*orbit\.json"):
        output.write_orbit_files(out, flow, orbit, result, {"status": "converged"})
    assert {p.name for p in out.iterdir()} == {"orbit.json", "topology.pdb"}
    monkeypatch.undo()

    def cut_plot(result, path, title=""):
        path.write_bytes(b"\x89PNG\r\n")  # part of the file got out
        raise OSError(errno.EROFS, os.strerror(errno.EROFS))

    monkeypatch.setattr(output, "plot_multipliers", cut_plot)
    with pytest.raises(KnotmmError, match=r"orbit_multipliers\.png.*read-only") as info:
        output.write_orbit_files(out, flow, orbit, result, {"status": "converged"})
    assert info.value.exit_code == 3
    assert {p.name for p in out.iterdir()} == ORBIT_FILES - {"orbit_multipliers.png"}


def _fake_floquet(orbit):
    from knotmm.orbit.floquet import FloquetResult

    mode = np.random.default_rng(1).standard_normal((1, *orbit.positions.shape))
    return FloquetResult(np.array([0.9 + 0.1j]), mode, np.ones(5, complex),
                         ["a", "b", "c", "d", "e"], orbit.period, 0)


# -- item 5: one writer, no stale files ---------------------------------------------------------
def test_a_new_orbit_removes_the_files_of_an_earlier_one(orbit40, tmp_path):
    from knotmm.orbit.output import write_orbit_files

    flow, orbit, _ = orbit40
    out = tmp_path / "o"
    out.mkdir()
    write_orbit_files(out, flow, orbit, _fake_floquet(orbit), {"modes": 1})
    (out / ".orbit.dcd.x1y2.tmp.dcd").write_bytes(b"half")  # left by a killed writer
    (out / "notes.txt").write_text("mine")
    assert ORBIT_FILES <= {p.name for p in out.iterdir()}
    write_orbit_files(out, flow, orbit, None, {"modes": 0})  # as --modes 0 does
    assert {p.name for p in out.iterdir()} == {"orbit.json", "orbit.dcd", "topology.pdb",
                                               "notes.txt"}
    assert json.loads((out / "orbit.json").read_text()) == {"modes": 0}


def test_a_second_writer_is_refused(run40, tmp_path, capsys, no_computation):
    out = tmp_path / "o"
    with RunLock(out, what="orbit"):  # another knotmm orbit writing there
        line = _one_line(capsys, ["orbit", str(run40), "--modes", "0", "--out", str(out)], 2)
        assert "in use by process" in line and LOCK_FILE in line, line
        line = _one_line(capsys, ["orbit", str(run40), "--continue",
                                  "model.bending_stiffness=5:6", "--out", str(out)], 2)
        assert "in use by process" in line, line


# -- item 7: extremes, refused before the computation -------------------------------------------
@pytest.mark.parametrize(("args", "message"), [
    (["--timestep", "0"], "--timestep 0.0: the orbit's fixed step must be in (0, 0.05]"),
    (["--timestep", "-0.01"], "--timestep -0.01"),
    (["--timestep", "nan"], "--timestep nan"),
    (["--timestep", "inf"], "--timestep inf"),
    (["--modes", "100000"], "at most 112 multipliers to compute (3N - 8)"),
    (["--continue", "knot.beads=60:60.5"], "knot.beads takes whole numbers"),
    (["--continue", "knot.beads=60:61", "--modes", "200"], "a chain of 40 beads has at most"),
    (["--continue", "knot.beads=2:40"], "2 is not a valid knot.beads"),
    (["--continue", "model.bending_stiffness=5:5.0000001"], "below the"),
    (["--continue", "model.bending_stiffness=-1:5"], "-1 is not a valid"),
    (["--continue", "model.bending_stiffness=5:6", "--points", "1"], "--points 1"),
    (["--resume"], "--resume goes on with a continuation"),
])
def test_extremes_are_one_line_before_the_computation(run40, tmp_path, capsys, no_computation,
                                                     args, message):
    line = _one_line(capsys, ["orbit", str(run40), "--out", str(tmp_path / "o"), *args], 2)
    assert message in line, line
    assert not (tmp_path / "o").exists()  # nothing created


def test_resume_with_nothing_to_resume_or_other_options(run40, tmp_path, capsys,
                                                        no_computation):
    out = tmp_path / "o"
    argv = ["orbit", str(run40), "--continue", "model.bending_stiffness=5:6", "--out", str(out)]
    line = _one_line(capsys, [*argv, "--resume"], 2)
    assert "holds no continuation to resume" in line, line
    assert not out.exists()


# -- item 2: a stopped continuation keeps its points and resumes --------------------------------
def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _points(out) -> list[dict]:
    return json.loads((out / "continuation.json").read_text())["points"]


def test_a_stopped_continuation_keeps_its_points_and_resumes(run40, tmp_path, capsys):
    out = tmp_path / "c"
    # the command with --modes 0 to keep it short; the slow test below has --modes 1
    argv = ["orbit", str(run40), "--modes", "0", "--continue", "model.bending_stiffness=5:6",
            "--points", "3", "--out", str(out)]
    proc = subprocess.Popen([sys.executable, "-m", "knotmm.cli", *argv], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, preexec_fn=_default_sigint)
    try:
        seen = []
        deadline = time.monotonic() + 300
        while len(seen) < 2:  # the CLI prints a line per converged point
            line = proc.stdout.readline()
            assert line and time.monotonic() < deadline, (seen, proc.stderr.read())
            if "T = " in line:
                seen.append(line)
        os.kill(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    assert proc.returncode == 130, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert "2 converged points are kept" in lines[0] and "--resume" in lines[0], lines
    assert "knotmm run --resume" not in err
    kept = _points(out)
    assert len(kept) == 2
    assert len((out / "continuation.csv").read_text().splitlines()) == 3
    _no_temporaries(out)
    assert main([*argv, "--resume"]) == 0, capsys.readouterr().err
    data = json.loads((out / "continuation.json").read_text())
    assert data["complete"] and data["reached_stop"] and len(data["points"]) == 3
    assert data["points"][:2] == kept  # the points kept are the points resumed from
    assert data["points"][2]["model.bending_stiffness"] == pytest.approx(6.0, abs=1e-3)
    # a finished continuation resumed again is written again, nothing computed
    assert main([*argv, "--resume"]) == 0
    assert json.loads((out / "continuation.json").read_text())["points"] == data["points"]
    line = _one_line(capsys, [*argv, "--modes", "1", "--resume"], 2)
    assert "was started with modes = 0, not 1" in line, line


@pytest.mark.slow
def test_a_resumed_continuation_equals_an_uninterrupted_one(run40, tmp_path):
    """Points 3 and 4 found after a stop at 2 are the points found without a stop."""
    from knotmm.orbit.driver import continuation_of_run
    from knotmm.orbit.output import read_branch, write_branch

    spec = "model.bending_stiffness=5:7"
    ref, _, _ = continuation_of_run(run40, spec, points=4, modes=1, out=tmp_path / "ref")
    meta, branch = read_branch(tmp_path / "ref")
    out = tmp_path / "cut"
    out.mkdir()
    write_branch(out, meta["parameter"], branch[:2], [], 1, {},
                 state=meta | {"finished": False})  # what a stop after 2 points leaves
    again, _, _ = continuation_of_run(run40, spec, points=4, modes=1, out=out, resume=True)
    assert len(again) == len(ref) == 4
    for a, b in zip(again, ref, strict=True):
        assert a.value == b.value and a.orbit.period == b.orbit.period
        np.testing.assert_array_equal(a.orbit.positions, b.orbit.positions)
        np.testing.assert_allclose(np.abs(a.floquet.multipliers),
                                   np.abs(b.floquet.multipliers), rtol=1e-6)
