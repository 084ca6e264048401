"""``knotmm analyze SET``: a full or read-only disk, and replicas that are not finished.

Issue 30 (audit "reliability, round four"):

* BUG-5: on a full disk every replica's analysis failed, and a good ``replicas.json`` was
  replaced by one with ``runs: []`` (exit 0). Now the earlier file is kept, one line says
  why, exit 3.
* BUG-6: ``replicas.json`` that could not be written gave a traceback and a 0-byte file.
  Now it is written atomically: one line naming it, exit 3 (exit 2 before any analysis when
  the set's directory is read-only).
* BUG-17: the statistics silently averaged a replica still running and a faulted one, and
  did not mention a replica not started. Now those are left out of the mean and named, with
  the reason, in ``replicas.json`` (``excluded``) and on screen.

The full disk is simulated (no root, no mount): files under a chosen place can be created,
but what is written to them never reaches the disk (``ENOSPC`` when it is flushed or
closed, as a buffered write on a full disk fails), or (``EACCES``) they cannot be created.
"""

from __future__ import annotations

import builtins
import errno
import io
import json
import math
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
import tomli_w
from synthetic import vortex_knot_positions, write_run_directory

from knotmm.cli.main import main
from knotmm.io.rundir import RunLock

DT = 0.5
DURATION = 40.0
CONFIG = {"knot": {"kind": "torus", "p": 2, "q": 3}, "model": {"bond_length": 0.6}}
ANALYZE = ["--no-plots", "--knot-samples", "0"]


def _replica(root: Path, k: int, speed: float, status: str = "finished",
             reached: float = DURATION, message: str | None = None) -> Path:
    """Write ``root/replica_k``: a synthetic run of ``reached`` tau_d out of DURATION."""
    times = np.arange(round(reached / DT) + 1) * DT
    x = vortex_knot_positions(times, n_beads=40, velocity=speed, noise=0.05, seed=k)
    facts = {"status": status, "time_reached": float(reached)}
    if message:
        facts["message"] = message
    config = {**CONFIG, "run": {"duration": DURATION, "replicas": 1}, "knotmm": facts}
    return write_run_directory(root / f"replica_{k}", x, DT, config)


def _record(root: Path, count: int) -> None:
    record = {"replicas": {"count": count, "seeds": list(range(count)),
                           "directories": [f"replica_{k}" for k in range(count)]},
              "run_file": {**CONFIG, "run": {"duration": DURATION, "replicas": count}}}
    (root / "replicas.toml").write_text(tomli_w.dumps(record))


@pytest.fixture(scope="module")
def finished_set(tmp_path_factory) -> Path:
    """Three finished replicas, analysed once (their analysis.json and replicas.json)."""
    root = tmp_path_factory.mktemp("finished") / "set"
    root.mkdir()
    _record(root, 3)
    for k, speed in enumerate((6.0, 6.2, 6.4)):
        _replica(root, k, speed)
    assert main(["analyze", str(root), *ANALYZE]) == 0
    return root


@pytest.fixture
def set_copy(finished_set, tmp_path) -> Path:
    copy = tmp_path / "set"
    shutil.copytree(finished_set, copy)
    return copy


# -- a failing disk, simulated ---------------------------------------------------------------
class _Unflushable:
    """A file opened for writing on a full disk: writes are buffered, flushing fails.

    As Python's buffered files: every flush fails while data is pending, and so does the
    first ``close`` (which closes the file all the same; a second one does nothing).
    """

    def __init__(self, fh, name):
        self._fh, self._name, self._pending = fh, os.fspath(name) if name else None, 0

    def _full(self) -> OSError:
        return OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), self._name)

    def write(self, data):
        self._pending += len(data)
        return len(data)

    def flush(self):
        if self._pending:
            raise self._full()

    def close(self):
        if self._fh.closed:
            return
        self._fh.close()
        if self._pending:
            raise self._full()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __getattr__(self, name):
        return getattr(self._fh, name)


def _failing_disk(monkeypatch, where, code: int = errno.ENOSPC) -> None:
    """Writes to the files ``where(path)`` picks fail with ``code`` (ENOSPC or EACCES).

    ENOSPC: the file is created (emptied) but nothing written to it reaches the disk.
    EACCES: it cannot be created or opened for writing. Python-level I/O only.
    """
    real_open, real_os_open = io.open, os.open
    fds: set[int] = set()
    write_flags = os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_TRUNC | os.O_APPEND

    def chosen(path) -> bool:
        if isinstance(path, int):
            return path in fds
        return where(Path(os.path.abspath(os.fsdecode(os.fspath(path)))))

    def fake_os_open(path, flags, mode=0o777, *args, **kwargs):
        if flags & write_flags and chosen(path):
            if code != errno.ENOSPC:
                raise OSError(code, os.strerror(code), os.fspath(path))
            fd = real_os_open(path, flags, mode, *args, **kwargs)
            fds.add(fd)
            return fd
        return real_os_open(path, flags, mode, *args, **kwargs)

    def fake_open(file, mode="r", *args, **kwargs):
        if any(c in mode for c in "wax+") and chosen(file):
            if code != errno.ENOSPC:
                raise OSError(code, os.strerror(code), os.fspath(file))
            return _Unflushable(real_open(file, mode, *args, **kwargs),
                                None if isinstance(file, int) else file)
        return real_open(file, mode, *args, **kwargs)

    monkeypatch.setattr(os, "open", fake_os_open)
    monkeypatch.setattr(io, "open", fake_open)
    monkeypatch.setattr(builtins, "open", fake_open)


def _temporaries(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob(".*.tmp*"))


def _call(argv, capsys) -> tuple[int, str, str]:
    code = main(argv)
    shown = capsys.readouterr()
    assert "Traceback" not in shown.err, shown.err
    return code, shown.out, shown.err


# -- BUG-5 / BUG-6 ------------------------------------------------------------------------------
@pytest.mark.parametrize("place", ["everywhere", "one replica"])
def test_a_full_disk_keeps_the_earlier_replicas_json(set_copy, capsys, monkeypatch, place):
    """BUG-5: the replicas' analyses cannot be written: the good replicas.json stays."""
    before = (set_copy / "replicas.json").read_bytes()
    assert json.loads(before)["points"]["all"]["runs"] == [f"replica_{k}" for k in range(3)]
    if place == "everywhere":
        _failing_disk(monkeypatch, lambda p: set_copy in p.parents)
    else:
        _failing_disk(monkeypatch, lambda p: set_copy / "replica_1" in p.parents)
    code, out, err = _call(["analyze", str(set_copy), *ANALYZE], capsys)
    monkeypatch.undo()
    assert code == 3, (out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "no space left on the device (ENOSPC)" in lines[0], lines[0]
    assert "replicas.json" in lines[0] and "kept" in lines[0], lines[0]
    assert (set_copy / "replicas.json").read_bytes() == before
    assert "wrote replicas.json" not in out
    assert _temporaries(set_copy) == []


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EACCES])
def test_replicas_json_that_cannot_be_written(set_copy, capsys, monkeypatch, code):
    """BUG-6: replicas.json itself cannot be written: one line naming it, exit 3, no
    half-written or empty file (here: no earlier one), the replicas' analyses written."""
    (set_copy / "replicas.json").unlink()
    for analysis in set_copy.glob("replica_*/analysis.json"):
        analysis.unlink()
    target = set_copy / "replicas.json"
    _failing_disk(monkeypatch, lambda p: p.parent == set_copy and p.name.startswith(
        (".replicas.json", "replicas.json")), code)
    exit_code, out, err = _call(["analyze", str(set_copy), *ANALYZE], capsys)
    monkeypatch.undo()
    assert exit_code == 3, (out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and f"cannot write {str(target)!r}" in lines[0], err
    assert errno.errorcode[code] in lines[0], lines[0]
    assert not target.exists()
    assert _temporaries(set_copy) == []
    assert len(list(set_copy.glob("replica_*/analysis.json"))) == 3


def test_a_read_only_set_directory_is_refused_before_the_analysis(set_copy, capsys,
                                                                  monkeypatch):
    """BUG-6: the set's directory cannot take a file: exit 2 before any replica is analysed
    (as for a single run), one line naming the directory."""
    for analysis in set_copy.glob("replica_*/analysis.json"):
        analysis.unlink()
    before = (set_copy / "replicas.json").read_bytes()
    _failing_disk(monkeypatch, lambda p: p.parent == set_copy, errno.EACCES)
    code, out, err = _call(["analyze", str(set_copy), *ANALYZE], capsys)
    monkeypatch.undo()
    assert code == 2, (out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and str(set_copy) in lines[0], err
    assert "permission denied (EACCES)" in lines[0], lines[0]
    assert not list(set_copy.glob("replica_*/analysis.json"))  # nothing computed
    assert (set_copy / "replicas.json").read_bytes() == before


# -- BUG-17 -------------------------------------------------------------------------------------
@pytest.fixture
def mixed_set(tmp_path):
    """Five replicas counted: 0 and 1 finished, 2 still running (a live lock) at t = 20, 3
    faulted at t = 12, 4 not started."""
    root = tmp_path / "set"
    root.mkdir()
    _record(root, 5)
    _replica(root, 0, 6.0)
    _replica(root, 1, 6.4)
    _replica(root, 2, 9.0, status="running", reached=20.0)
    _replica(root, 3, 12.0, status="fault", reached=12.0,
             message="the dynamics broke down: bond 3-4 overstretched")
    lock = RunLock(root / "replica_2", "run")  # a live process holds replica 2
    yield root
    lock.release()


def test_unfinished_replicas_are_named_and_left_out(mixed_set, capsys):
    code, out, err = _call(["analyze", str(mixed_set), *ANALYZE], capsys)
    assert code == 0, (out, err)
    point = json.loads((mixed_set / "replicas.json").read_text())["points"]["all"]
    assert point["runs"] == ["replica_0", "replica_1"]
    excluded = point["excluded"]
    assert list(excluded) == ["replica_2", "replica_3", "replica_4"], excluded
    assert excluded["replica_2"].startswith("still running (t = 20 of 40 tau_d")
    assert excluded["replica_3"].startswith("fault at t = 12 of 40 tau_d")
    assert "overstretched" in excluded["replica_3"]
    assert excluded["replica_4"].startswith("not started")
    v = point["statistics"]["sedimentation_velocity"]
    assert v["n"] == 2 and v["mean"] == pytest.approx(6.2, rel=1e-3)
    assert v["std_error"] == pytest.approx(0.2, rel=0.02)
    table = out.splitlines()
    assert table[1].split()[:2] == ["all", "2"], out
    for name in ("replica_2", "replica_3", "replica_4"):
        assert any(line.startswith("note: all: ") and name in line and "left out" in line
                   for line in table), out
    assert not err.strip(), err


def test_unfinished_replicas_can_be_included(mixed_set, capsys):
    code, out, err = _call(["analyze", str(mixed_set), *ANALYZE, "--include-partial"], capsys)
    assert code == 0, (out, err)
    point = json.loads((mixed_set / "replicas.json").read_text())["points"]["all"]
    assert point["runs"] == [f"replica_{k}" for k in range(4)]
    assert list(point["excluded"]) == ["replica_4"]  # not started: nothing to average
    assert point["partial"] == {
        "replica_2": point["partial"]["replica_2"], "replica_3": point["partial"]["replica_3"]}
    v = point["statistics"]["sedimentation_velocity"]
    assert v["n"] == 4 and v["mean"] == pytest.approx((6.0 + 6.4 + 9.0 + 12.0) / 4, rel=1e-3)
    assert math.isfinite(v["std_error"])


def test_nothing_to_average_keeps_the_earlier_replicas_json(tmp_path, capsys):
    """Only unfinished replicas: no statistics to write; the earlier file stays."""
    root = tmp_path / "set"
    root.mkdir()
    _record(root, 2)
    _replica(root, 0, 6.0, status="interrupted", reached=20.0)
    (root / "replicas.json").write_text('{"points": {"all": {"runs": ["replica_0"]}}}\n')
    before = (root / "replicas.json").read_bytes()
    code, out, err = _call(["analyze", str(root), *ANALYZE], capsys)
    assert code == 2, (out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "replica_0: interrupted at t = 20 of 40 tau_d" in lines[0], lines[0]
    assert "replica_1: not started" in lines[0] and "kept" in lines[0], lines[0]
    assert (root / "replicas.json").read_bytes() == before


# -- BUG-26 -------------------------------------------------------------------------------------
def test_a_full_disk_leaves_no_empty_plot(tmp_path, capsys, monkeypatch):
    """BUG-26: ``knotmm analyze RUN`` on a full disk: exit 3, and no 0-byte (or cut) PNG or
    CSV is left under its name; the earlier analysis.json is kept."""
    run = _replica(tmp_path, 0, 6.0)
    (run / "analysis.json").write_text('{"earlier": true}\n')
    _failing_disk(monkeypatch, lambda p: run in p.parents)
    code, out, err = _call(["analyze", str(run), "--knot-samples", "0"], capsys)
    monkeypatch.undo()
    assert code == 3, (out, err)
    assert "no space left on the device (ENOSPC)" in err and len(err.strip().splitlines()) == 1
    left = sorted(p.name for p in run.iterdir() if p.suffix in (".png", ".csv")
                  and p.name.startswith("analysis"))
    assert left == [], left
    assert _temporaries(run) == []
    assert (run / "analysis.json").read_text() == '{"earlier": true}\n'


def test_nothing_to_average_claims_no_earlier_file_that_was_not_there(tmp_path, capsys):
    """The refusal said "(an earlier one is kept)" with no replicas.json in the directory."""
    root = tmp_path / "set"
    root.mkdir()
    _record(root, 2)
    _replica(root, 0, 6.0, status="interrupted", reached=20.0)
    code, out, err = _call(["analyze", str(root), *ANALYZE], capsys)
    assert code == 2, (out, err)
    assert "not written" in err and "kept" not in err, err
    assert not (root / "replicas.json").exists()
