"""Fuzz ``knotmm analyze`` and ``knotmm sweep`` (issue 23, "Also"), as ``test_run_fuzz.py``
fuzzes ``knotmm run``, with its helpers and the same promises:

* damaged inputs: a finished run with ``trajectory.dcd``, ``topology.pdb`` or ``run.toml``
  cut, emptied, removed or with bytes flipped, for ``analyze``; a finished sweep with its
  ``sweep.toml``, ``summary.csv`` or a point's files damaged, and damaged sweep files, for
  ``sweep``;
* failing outputs: a read-only file system (EROFS) or one that fills up (ENOSPC) after a
  random number of bytes, simulated in this process by :class:`FailingDisk` (root ignores
  file permissions, and CI cannot mount a small tmpfs);
* signals: ``knotmm sweep`` gets SIGINT, SIGTERM or SIGKILL at a random moment, then is
  run again to the end.

The invariants: no traceback; exit 0, 2 (bad input, or an output place refused before any
work), 3 (a failure while writing, after work was done), 1 for a sweep with failed points,
130 when stopped; one line on stderr for 2 and 3; nothing half-written under a final name
(``analysis.json``, ``sweep.toml`` and ``summary.csv`` are whole, or absent, or what they
were; no temporary file of an atomic write is left behind). Every random choice comes from
a fixed seed; the slow variants draw more cases.
"""

from __future__ import annotations

import builtins
import errno
import io
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import test_run_fuzz
from test_run_fuzz import _call, _default_sigint, _kill, _status

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

from knotmm.cli.main import main
from knotmm.sweep import read_summary

SEED = 20261202
#: Files of a run directory that ``knotmm analyze`` reads.
ANALYZE_TARGETS = ("trajectory.dcd", "trajectory.dcd", "topology.pdb", "run.toml")
#: The sweep: three tiny points, analysed without knot identification or plots.
SWEEP_TOML = """\
[knot]
beads = 30
[run]
duration = {duration}
topology_check_interval = 0.0
[output]
directory = "{directory}"
frame_interval = 0.1
[sweep]
"knot.beads" = [30, 32, 34]
knot_samples = 0
plots = false
"""


# -- a failing file system, simulated -------------------------------------------------------
class FailingDisk:
    """Make writes under ``root`` fail as on a read-only (EROFS) or full (ENOSPC) disk.

    EROFS: creating or opening a file for writing, making a directory, renaming or removing
    under ``root`` fail at once. ENOSPC: the first ``budget`` bytes written under ``root``
    (all files together) go through, then a write fails after writing what still fitted,
    as a disk that fills up leaves a file cut short. Python-level I/O only (``open``,
    ``os.open``/``os.write``, ``os.fdopen``): C code writing to a descriptor it was given
    is not limited.
    """

    _WRITE_FLAGS = os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_APPEND | os.O_TRUNC

    def __init__(self, root: Path, code: int, budget: int = 0):
        self.root = os.path.abspath(root)
        self.code, self.budget, self.used = code, budget, 0
        self.fds: set[int] = set()
        self.failures = 0

    def under(self, path) -> bool:
        if isinstance(path, int):
            return path in self.fds
        try:
            p = os.path.abspath(os.fsdecode(os.fspath(path)))
        except TypeError:
            return False
        return p == self.root or p.startswith(self.root + os.sep)

    def error(self, path=None) -> OSError:
        self.failures += 1
        return OSError(self.code, os.strerror(self.code),
                       None if isinstance(path, int) or path is None else os.fspath(path))

    def room(self) -> int:
        return max(0, self.budget - self.used)

    def install(self, monkeypatch) -> None:
        real_open, real_os_open, real_write = io.open, os.open, os.write
        real_mkdir, real_replace, real_rename, real_unlink = (os.mkdir, os.replace,
                                                              os.rename, os.unlink)
        disk = self

        def fake_open(file, mode="r", *args, **kwargs):
            writing = any(c in mode for c in "wax+")
            if writing and disk.under(file):
                if disk.code == errno.EROFS and not isinstance(file, int):
                    raise disk.error(file)
                return _Capped(real_open(file, mode, *args, **kwargs), disk, file)
            return real_open(file, mode, *args, **kwargs)

        def fake_os_open(path, flags, mode=0o777, *args, **kwargs):
            if flags & disk._WRITE_FLAGS and disk.under(path):
                if disk.code == errno.EROFS:
                    raise disk.error(path)
                fd = real_os_open(path, flags, mode, *args, **kwargs)
                disk.fds.add(fd)
                return fd
            return real_os_open(path, flags, mode, *args, **kwargs)

        def fake_write(fd, data):
            if fd in disk.fds and disk.code == errno.ENOSPC:
                data = bytes(data)
                if len(data) > disk.room():
                    real_write(fd, data[:disk.room()])
                    disk.used = disk.budget
                    raise disk.error()
                disk.used += len(data)
            return real_write(fd, data)

        def guard(real):
            def fake(path, *args, **kwargs):
                if disk.code == errno.EROFS and (disk.under(path) or any(
                        isinstance(a, (str, os.PathLike)) and disk.under(a) for a in args)):
                    raise disk.error(path)
                return real(path, *args, **kwargs)
            return fake

        monkeypatch.setattr(io, "open", fake_open)
        monkeypatch.setattr(builtins, "open", fake_open)
        monkeypatch.setattr(os, "open", fake_os_open)
        monkeypatch.setattr(os, "write", fake_write)
        for name, real in (("mkdir", real_mkdir), ("replace", real_replace),
                           ("rename", real_rename), ("unlink", real_unlink)):
            monkeypatch.setattr(os, name, guard(real))


class _Capped:
    """A file object whose writes count against a :class:`FailingDisk`'s budget."""

    def __init__(self, fh, disk: FailingDisk, name):
        self._fh, self._disk, self._name = fh, disk, name

    def write(self, data):
        size = len(data.encode("utf-8")) if isinstance(data, str) else memoryview(data).nbytes
        if self._disk.code == errno.ENOSPC and size > self._disk.room():
            room = self._disk.room()
            if room:
                self._fh.write(data[:room])
                self._fh.flush()
            self._disk.used = self._disk.budget
            raise self._disk.error(self._name)
        self._disk.used += size
        return self._fh.write(data)

    def writelines(self, lines):
        for line in lines:
            self.write(line)

    def __getattr__(self, name):
        return getattr(self._fh, name)

    def __iter__(self):
        return iter(self._fh)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self._fh.close()


# -- checks ---------------------------------------------------------------------------------
def _temporaries(directory: Path) -> list[str]:
    """Files an atomic write would have left behind (``.NAME.xxxx.tmp``)."""
    return sorted(str(p.relative_to(directory)) for p in directory.rglob(".*.tmp*"))


#: The last chunk of every PNG file.
PNG_END = b"IEND\xaeB`\x82"


def _whole_pngs(directory: Path, case: str) -> None:
    """Every plot under ``directory`` is a whole PNG (a full disk leaves none cut short)."""
    for png in directory.rglob("*.png"):
        data = png.read_bytes()
        assert data.startswith(b"\x89PNG") and data.endswith(PNG_END), (
            f"{case}: half-written {png.relative_to(directory)} ({len(data)} bytes)")


def _whole_json(path: Path, before: bytes | None, case: str) -> None:
    """``path`` is absent, what it was, or whole JSON."""
    if not path.exists():
        return
    data = path.read_bytes()
    if data == before:
        return
    try:
        json.loads(data)
    except ValueError as exc:
        pytest.fail(f"{case}: half-written {path.name} ({exc}): {data[:80]!r}")


def _whole_sweep(directory: Path, case: str, killed: bool = False) -> None:
    """The sweep directory's own files are whole (or absent); no temporary is left (by a
    SIGKILLed sweep, which cannot clean up, none after the next command on it)."""
    if not killed:
        assert _temporaries(directory) == [], case
    if (directory / "sweep.toml").exists():
        tomllib.loads((directory / "sweep.toml").read_text())
    if (directory / "summary.csv").exists():
        rows = read_summary(directory)
        assert len(rows) == 3 and all(r["status"] for r in rows), f"{case}: {rows}"
    for analysis in directory.glob("*/analysis.json"):
        _whole_json(analysis, None, case)
    _whole_pngs(directory, case)


def _call_sweep(argv: list[str], capsys, case: str, codes=(0, 1, 2, 3)) -> tuple[int, str]:
    """``knotmm sweep`` in this process: its codes include 1 (some point failed)."""
    try:
        code = main(argv)
    except BaseException as exc:  # noqa: BLE001 - the point of the test
        pytest.fail(f"{case}: knotmm {' '.join(argv)} raised {exc!r}")
    err = capsys.readouterr().err
    assert code in codes, f"{case}: exit {code}\n{err}"
    assert "Traceback" not in err, f"{case}:\n{err}"
    if code in (2, 3):
        lines = [line for line in err.strip().splitlines() if "note:" not in line]
        assert len(lines) == 1 and lines[0].startswith("knotmm: error: "), f"{case}: {err}"
    return code, err


# -- analyze: damaged inputs and failing outputs --------------------------------------------
#: The finished 2 tau_d run of test_run_fuzz.py (module-scoped: made once for this module).
finished_run = test_run_fuzz.finished_run

@pytest.fixture(scope="module")
def old_analysis(finished_run, tmp_path_factory) -> bytes:
    """An analysis.json of the finished run, put beside a damaged run in some cases."""
    out = tmp_path_factory.mktemp("fuzz_analysis")
    assert main(["analyze", str(finished_run), "--knot-samples", "0", "--no-plots",
                 "--out", str(out)]) == 0
    return (out / "analysis.json").read_bytes()


def _check_analyze_damaged(finished_run, old_analysis, tmp_path, capsys, monkeypatch,
                           index: int, seed: int) -> None:
    rng = np.random.default_rng([seed, index])
    directory = tmp_path / f"case{index}"
    shutil.copytree(finished_run, directory)
    before = old_analysis if rng.integers(0, 2) else None
    if before is not None:
        (directory / "analysis.json").write_bytes(before)
    monkeypatch.setattr(test_run_fuzz, "TARGETS", ANALYZE_TARGETS)  # _damage picks from it
    what = test_run_fuzz._damage(directory, rng)
    monkeypatch.undo()
    plots = [] if rng.integers(0, 2) else ["--no-plots"]
    case = f"analyze case {index} (seed {seed}): {what}, plots {not plots}"
    code, err = _call(["analyze", str(directory), "--knot-samples", "0", *plots], capsys, case)
    assert code in (0, 2), f"{case}: exit {code}: {err}"
    if code == 2:  # refused: what was there before is there still
        path = directory / "analysis.json"
        assert (path.read_bytes() if path.exists() else None) == before, case
    else:
        json.loads((directory / "analysis.json").read_text())
    assert _temporaries(directory) == [], case


@pytest.mark.parametrize("index", range(6))
def test_analyze_of_a_damaged_run(finished_run, old_analysis, tmp_path, capsys, monkeypatch,
                                  index):
    _check_analyze_damaged(finished_run, old_analysis, tmp_path, capsys, monkeypatch, index,
                           SEED)


@pytest.mark.slow
@pytest.mark.parametrize("index", range(40))
def test_analyze_of_a_damaged_run_long(finished_run, old_analysis, tmp_path, capsys,
                                       monkeypatch, index):
    _check_analyze_damaged(finished_run, old_analysis, tmp_path, capsys, monkeypatch, index,
                           SEED + 1)


def _check_analyze_output(finished_run, old_analysis, tmp_path, capsys, monkeypatch,
                          index: int, seed: int) -> None:
    rng = np.random.default_rng([seed, index])
    code = int(rng.choice([errno.EROFS, errno.ENOSPC, errno.ENOSPC]))
    budget = int(rng.integers(0, 400_000))
    into_out = bool(rng.integers(0, 2))
    plots = [] if rng.integers(0, 2) else ["--no-plots"]
    directory = tmp_path / "run"
    shutil.copytree(finished_run, directory)
    before = old_analysis if rng.integers(0, 2) else None
    if before is not None:
        (directory / "analysis.json").write_bytes(before)
    out = tmp_path / "out" if into_out else directory
    argv = ["analyze", str(directory), "--knot-samples", "0", *plots]
    if into_out:
        argv += ["--out", str(out)]
    case = (f"analyze output case {index} (seed {seed}): {errno.errorcode[code]} after "
            f"{budget} bytes, into {'--out' if into_out else 'the run'}, plots {not plots}")
    disk = FailingDisk(out, code, budget)
    disk.install(monkeypatch)
    try:
        status, err = _call(argv, capsys, case)
    finally:
        monkeypatch.undo()
    if code == errno.EROFS:
        assert status == 2, f"{case}: exit {status}: {err}"  # refused before the analysis
    else:
        assert status in ((0, 3) if disk.failures or status == 0 else (3,)), f"{case}: {err}"
    if status:
        assert str(out) in err, f"{case}: the line names no output path: {err}"
    _whole_json(out / "analysis.json", before if out == directory else None, case)
    if out.exists():
        assert _temporaries(out) == [], case
        _whole_pngs(out, case)


@pytest.mark.parametrize("index", range(5))
def test_analyze_into_a_failing_disk(finished_run, old_analysis, tmp_path, capsys,
                                     monkeypatch, index):
    _check_analyze_output(finished_run, old_analysis, tmp_path, capsys, monkeypatch, index,
                          SEED)


@pytest.mark.slow
@pytest.mark.parametrize("index", range(30))
def test_analyze_into_a_failing_disk_long(finished_run, old_analysis, tmp_path, capsys,
                                          monkeypatch, index):
    _check_analyze_output(finished_run, old_analysis, tmp_path, capsys, monkeypatch, index,
                          SEED + 1)


# -- sweep: damaged inputs and failing outputs ----------------------------------------------
@pytest.fixture(scope="module")
def finished_sweep(tmp_path_factory):
    """A finished sweep of three 2 tau_d points (copied for each case, never changed)."""
    base = tmp_path_factory.mktemp("fuzz_sweep")
    path = base / "sweep file.toml"
    path.write_text(SWEEP_TOML.format(duration=2.0, directory=base / "sweep"))
    assert main(["sweep", str(path), "--workers", "0", "--no-progress"]) == 0
    return path, base / "sweep"


def _garbage_sweep_file(text: str, rng) -> tuple[str, str]:
    """A sweep file damaged at random (cut, bytes flipped, a value of the wrong kind)."""
    how = str(rng.choice(["cut", "flip", "value", "key"]))
    if how == "cut":
        at = int(rng.integers(0, len(text)))
        return text[:at], f"cut at {at}"
    if how == "flip":
        data = bytearray(text.encode())
        where = rng.integers(0, len(data), size=int(rng.integers(1, 6)))
        for i in where:
            data[int(i)] ^= int(rng.integers(1, 256))
        return data.decode("utf-8", "replace"), f"bytes flipped at {sorted(map(int, where))}"
    if how == "value":
        bad = str(rng.choice(['"many"', "-3", "[]", "1e400", "nan", '["a", 2]']))
        return text.replace("[30, 32, 34]", bad), f"knot.beads = {bad}"
    return text.replace('"knot.beads"', '"knot.beadz"'), "an unknown swept key"


SWEEP_DAMAGES = ("sweep.toml", "summary.csv", "point run.toml", "point trajectory.dcd",
                 "point analysis.json", "sweep file")


def _check_sweep_damaged(finished_sweep, tmp_path, capsys, monkeypatch, index: int,
                         seed: int) -> None:
    rng = np.random.default_rng([seed, index])
    path, base = finished_sweep
    directory = tmp_path / "sweep"
    shutil.copytree(base, directory)
    sweep_file = tmp_path / "s.toml"
    text = path.read_text().replace(str(base), str(directory))
    target = str(rng.choice(SWEEP_DAMAGES))
    if target == "sweep file":
        text, what = _garbage_sweep_file(text, rng)
    else:
        folder = directory / "knot.beads=32" if target.startswith("point") else directory
        name = target.split()[-1]
        monkeypatch.setattr(test_run_fuzz, "TARGETS", (name,))
        what = test_run_fuzz._damage(folder, rng)
        monkeypatch.undo()
    sweep_file.write_text(text)
    case = f"sweep case {index} (seed {seed}): {target}: {what}"
    code, err = _call_sweep(["sweep", str(sweep_file), "--workers", "0", "--no-progress"],
                            capsys, case)
    if target != "sweep file":
        assert code == 0, f"{case}: a damaged sweep is repaired by running it: {err}"
    _whole_sweep(directory, case)
    assert not (directory / ".knotmm.lock").exists(), case


@pytest.mark.parametrize("index", range(5))
def test_sweep_of_damaged_inputs(finished_sweep, tmp_path, capsys, monkeypatch, index):
    _check_sweep_damaged(finished_sweep, tmp_path, capsys, monkeypatch, index, SEED)


@pytest.mark.slow
@pytest.mark.parametrize("index", range(30))
def test_sweep_of_damaged_inputs_long(finished_sweep, tmp_path, capsys, monkeypatch, index):
    _check_sweep_damaged(finished_sweep, tmp_path, capsys, monkeypatch, index, SEED + 1)


def _check_sweep_output(finished_sweep, tmp_path, capsys, monkeypatch, index: int,
                        seed: int) -> None:
    rng = np.random.default_rng([seed, index])
    path, base = finished_sweep
    code = int(rng.choice([errno.EROFS, errno.ENOSPC, errno.ENOSPC]))
    budget = int(rng.integers(0, 300_000))
    fresh = bool(rng.integers(0, 2))  # a new sweep, or one whose first point is done
    directory = tmp_path / "sweep"
    if not fresh:
        shutil.copytree(base, directory)
        shutil.rmtree(directory / "knot.beads=34")
    sweep_file = tmp_path / "s.toml"
    sweep_file.write_text(path.read_text().replace(str(base), str(directory)))
    case = (f"sweep output case {index} (seed {seed}): {errno.errorcode[code]} after "
            f"{budget} bytes, {'fresh' if fresh else 'partly done'}")
    listing = sorted(p.name for p in directory.iterdir()) if directory.exists() else None
    disk = FailingDisk(directory, code, budget)
    disk.install(monkeypatch)
    try:
        status, err = _call_sweep(["sweep", str(sweep_file), "--workers", "0",
                                   "--no-progress"], capsys, case)
    finally:
        monkeypatch.undo()
    if code == errno.EROFS:
        assert status == 2, f"{case}: exit {status}: {err}"
        now = sorted(p.name for p in directory.iterdir()) if directory.exists() else None
        assert now == listing, f"{case}: a refused sweep wrote {now}"
    if status in (2, 3):
        assert str(directory) in err, f"{case}: the line names no output path: {err}"
    if directory.exists():
        _whole_sweep(directory, case)
    # with room again, the same command finishes the sweep
    code, err = _call_sweep(["sweep", str(sweep_file), "--workers", "0", "--no-progress"],
                            capsys, case + ", run again")
    assert code == 0, f"{case}, run again: {err}"
    assert [r["status"] for r in read_summary(directory)] == ["finished"] * 3, case


@pytest.mark.parametrize("index", range(3))
def test_sweep_into_a_failing_disk(finished_sweep, tmp_path, capsys, monkeypatch, index):
    _check_sweep_output(finished_sweep, tmp_path, capsys, monkeypatch, index, SEED)


@pytest.mark.slow
@pytest.mark.parametrize("index", range(20))
def test_sweep_into_a_failing_disk_long(finished_sweep, tmp_path, capsys, monkeypatch,
                                        index):
    _check_sweep_output(finished_sweep, tmp_path, capsys, monkeypatch, index, SEED + 1)


# -- sweep: a signal at a random moment -----------------------------------------------------
SWEEP_SIGNALS = ("SIGINT", "SIGTERM", "SIGKILL")


def _check_sweep_signal(tmp_path, capsys, kind: str, index: int, seed: int) -> None:
    rng = np.random.default_rng([seed, index])
    delay = float(rng.uniform(0.0, 4.0))
    workers = str(rng.choice(["0", "1"]))
    directory = tmp_path / "sweep"
    sweep_file = tmp_path / "s.toml"
    sweep_file.write_text(SWEEP_TOML.format(duration=3.0, directory=directory))
    case = f"sweep {kind} {delay:.2f} s after its start, {workers} workers (case {index})"
    argv = [sys.executable, "-m", "knotmm.cli", "sweep", str(sweep_file), "--workers",
            workers, "--no-progress"]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_default_sigint)
    try:
        end = time.monotonic() + 120  # from the sweep's lock on (its imports are done)
        while not (directory / ".knotmm.lock").exists() and proc.poll() is None:
            assert time.monotonic() < end, case
            time.sleep(0.02)
        time.sleep(delay)
        if proc.poll() is None:
            os.kill(proc.pid, getattr(signal, kind))
        _, err = proc.communicate(timeout=90)
    finally:
        _kill(proc)
    code = proc.returncode
    assert "Traceback" not in err, f"{case}:\n{err}"
    if kind == "SIGKILL":
        assert code in (0, -signal.SIGKILL), f"{case}: exit {code}\n{err}"
    else:
        # 130; 0 when it had finished; the signal itself when it came while the interpreter
        # shut down after the command (console_main restores the default handlers then)
        assert code in (0, 130, -getattr(signal, kind)), f"{case}: exit {code}\n{err}"
        if code == 130:
            assert len(err.strip().splitlines()) <= 2, f"{case}: stderr:\n{err}"
    if kind != "SIGKILL":
        for run_toml in directory.glob("*/run.toml"):  # no point left "running" by a stop
            assert _status(run_toml.parent) != "running", f"{case}: {run_toml.parent.name}"
    _whole_sweep(directory, case, killed=kind == "SIGKILL")
    # run again: the sweep finishes, a killed sweep's lock and temporaries taken over
    code, err = _call_sweep(["sweep", str(sweep_file), "--workers", "0", "--no-progress"],
                            capsys, case + ", run again", codes=(0,))
    assert [r["status"] for r in read_summary(directory)] == ["finished"] * 3, case
    assert _temporaries(directory) == [], case
    assert not (directory / ".knotmm.lock").exists(), case


@pytest.mark.parametrize("kind", ["SIGINT", "SIGKILL"])
def test_sweep_signal_then_run_again(tmp_path, capsys, kind):
    _check_sweep_signal(tmp_path, capsys, kind, SWEEP_SIGNALS.index(kind), SEED)


@pytest.mark.slow
@pytest.mark.parametrize("index", range(12))
def test_sweep_signal_then_run_again_long(tmp_path, capsys, index):
    kind = SWEEP_SIGNALS[index % len(SWEEP_SIGNALS)]
    _check_sweep_signal(tmp_path, capsys, kind, index, SEED + 1)


# -- a real full disk: a small tmpfs, where this machine lets the tests mount one -----------
@pytest.fixture
def small_disk(tmp_path):
    """Mount tmpfs file systems of a given size under tmp_path (skip where not allowed)."""
    mounted: list[Path] = []

    def mount(name: str, size: str) -> Path:
        where = tmp_path / name
        where.mkdir()
        done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs",
                               str(where)], capture_output=True, text=True)
        if done.returncode != 0:
            pytest.skip(f"cannot mount a tmpfs here: {done.stderr.strip()}")
        mounted.append(where)
        return where

    yield mount
    for where in mounted:
        subprocess.run(["umount", str(where)], check=False)


@pytest.mark.slow
@pytest.mark.parametrize("size", ["24k", "40k", "160k"])
def test_analyze_and_sweep_onto_a_real_full_disk(finished_run, small_disk, tmp_path, capsys,
                                                 size):
    disk = small_disk("disk", size)
    out = disk / "analysis"
    case = f"analyze onto a {size} tmpfs"
    code, err = _call(["analyze", str(finished_run), "--knot-samples", "0", "--out",
                       str(out)], capsys, case)
    assert code in (0, 2, 3), err
    _whole_json(out / "analysis.json", None, case)
    if out.exists():
        assert _temporaries(out) == [], case
        _whole_pngs(out, case)
    sweep_file = tmp_path / "s.toml"
    sweep_file.write_text(SWEEP_TOML.format(duration=2.0, directory=disk / "sweep"))
    case = f"sweep onto a {size} tmpfs"
    _call_sweep(["sweep", str(sweep_file), "--workers", "0", "--no-progress"], capsys, case)
    if (disk / "sweep").exists():
        _whole_sweep(disk / "sweep", case)
