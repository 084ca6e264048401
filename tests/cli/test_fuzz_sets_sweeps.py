"""Fuzz replica sets and sweeps of several chains, links and open filaments (issue 30).

``test_fuzz_systems.py`` fuzzes single runs of every system kind; this file puts the same
hostile inputs, with the helpers of the ring's fuzz files, to

* a replica set (:data:`SET_TOML`: a T(2,3) and an open arc in ``[[chains]]``, Pe = 5,
  ``replicas = 3``): a signal at a random moment of a random replica, then ``--resume``
  (every replica equals the uninterrupted set's, frames and topology record); a disk that
  fills up during the set, then ``--resume``; a damaged ``replicas.toml``; ``--overwrite``
  of a live single run, of a live set and of a finished set with a run file that cannot run
  (all refused, with nothing lost); ``analyze`` of the set onto a failing disk
  (``replicas.json`` whole, or as it was) and while a replica runs;
* sweeps (:data:`SWEEPS`) of ``[[chains]]`` points (with ``seeds``), of an open helix and,
  in the slow set, of a hopf link: ``--dry-run``, the same command again, a signal then the
  same command again (the points equal the uninterrupted sweep's), a failing disk, and a
  sweep of points with ``run.replicas``.

The invariants: no traceback; exit 0, 2, 3 (1 for a sweep with failed points, 130 when
stopped); one stderr line for 2 and 3; nothing already written lost (a refused command
leaves every file as it was; ``replicas.toml`` and ``replicas.json`` are whole, or as they
were). Every random choice comes from a fixed seed; the slow variants draw more cases.
"""

from __future__ import annotations

import errno
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import test_run_fuzz
from test_fuzz_analyze_sweep import _call_sweep, _temporaries, _whole_pngs
from test_fuzz_systems import FailingDisk, _model_time, assert_kept, assert_same_run, snapshot
from test_run_fuzz import _call, _default_sigint, _facts, _kill, _set_status, _status

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

from knotmm.cli.main import main
from knotmm.io.rundir import RunLock
from knotmm.sweep import read_summary

SEED = 20261205
_CHAINS = """
[[chains]]
beads = 30
offset = [{a}, 0.0, 0.0]
[[chains]]
kind = "arc"
beads = 20
offset = [4.0, 0.0, 0.0]
"""
#: The replica set: two chains, Brownian, three replicas of 2 tau_d.
SET_TOML = _CHAINS.format(a=-4.0) + """
[run]
duration = 2.0
peclet = 5.0
seed = 11
replicas = 3
topology_check_interval = 0.5
[output]
frame_interval = 0.1
checkpoint_interval = 0.5
"""
#: SET_TOML with the chains on top of each other (refused when the template is built).
OVERLAP_TOML = SET_TOML.replace("offset = [4.0, 0.0, 0.0]", "offset = [-4.0, 0.0, 0.0]")
_SWEEP = """
[output]
frame_interval = 0.1
[sweep]
"model.bending_stiffness" = [3.0, 6.0]
knot_samples = 0
plots = false
"""
#: The sweeps: ``[[chains]]`` points with two seeds each, an open helix, a hopf link.
SWEEPS = {
    "chains": _CHAINS.format(a=-4.0) + """
[run]
duration = 2.0
peclet = 10.0
topology_check_interval = 0.0
""" + _SWEEP + "seeds = 2\n",
    "open": """
[knot]
kind = "helix"
beads = 30
[run]
duration = 2.0
topology_check_interval = 0.0
""" + _SWEEP,
    "link": """
[knot]
kind = "knotinfo"
name = "hopf"
beads = 40
[run]
duration = 2.0
topology_check_interval = 0.0
""" + _SWEEP,
}
SWEEP_KINDS = ("chains", "open")


def _write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def _replicas(root: Path) -> list[Path]:
    return sorted(p for p in root.iterdir() if p.is_dir() and p.name.startswith("replica_"))


def _whole_set(root: Path, case: str, killed: bool = False,
               record: bytes | None = None) -> None:
    """Every record of the set is whole (or absent): replicas.toml (or ``record``, what it
    was before the command), replicas.json and each replica's run.toml; no temporary file
    is left (unless the process was ``killed`` inside an atomic write)."""
    if not killed:
        assert _temporaries(root) == [], case
    for path in [root / "replicas.toml", *(p / "run.toml" for p in _replicas(root))]:
        if path == root / "replicas.toml" and record is not None and (
                path.exists() and path.read_bytes() == record):
            continue
        if path.exists():
            try:
                tomllib.loads(path.read_text())
            except ValueError as exc:
                pytest.fail(f"{case}: {path.relative_to(root)} is not whole ({exc}): "
                            f"{path.stat().st_size} bytes")
    if (root / "replicas.json").exists():
        json.loads((root / "replicas.json").read_text())


# -- the replica set ------------------------------------------------------------------------
@pytest.fixture(scope="module")
def finished_set(tmp_path_factory):
    """The uninterrupted replica set, with its replicas.json (copied, never changed)."""
    base = tmp_path_factory.mktemp("fuzz_set")
    root = base / "set"
    assert main(["run", str(_write(base / "set.toml", SET_TOML)), "--out", str(root),
                 "--no-progress"]) == 0
    assert main(["analyze", str(root), "--knot-samples", "0", "--no-plots"]) == 0
    assert [_status(p) for p in _replicas(root)] == ["finished"] * 3
    return root


def _same_set(reference: Path, root: Path, case: str) -> None:
    """``root`` holds the set of ``reference``: same seeds, every replica the same run."""
    with open(reference / "replicas.toml", "rb") as fh:
        seeds = tomllib.load(fh)["replicas"]["seeds"]
    with open(root / "replicas.toml", "rb") as fh:
        assert tomllib.load(fh)["replicas"]["seeds"] == seeds, case
    assert [p.name for p in _replicas(root)] == [p.name for p in _replicas(reference)], case
    for replica in _replicas(reference):
        assert _status(root / replica.name) == "finished", f"{case}: {replica.name}"
        assert_same_run(replica, root / replica.name, f"{case}: {replica.name}")


def _check_set_signal(finished_set, tmp_path, capsys, kind: str, index: int,
                      seed: int) -> None:
    rng = np.random.default_rng([seed, index])
    k = int(rng.integers(0, 3))
    moment = float(rng.uniform(0.1, 1.8))
    root = tmp_path / "set"
    case = f"set: {kind} at t = {moment:.2f} of replica {k} (case {index}, seed {seed})"
    argv = [sys.executable, "-m", "knotmm.cli", "run", str(_write(tmp_path / "s.toml",
                                                                  SET_TOML)),
            "--out", str(root), "--no-progress"]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_default_sigint)
    try:
        end = time.monotonic() + 180
        while proc.poll() is None and _model_time(root / f"replica_{k}") < moment:
            assert time.monotonic() < end, f"{case}: no progress"
            time.sleep(0.01)
        if proc.poll() is None:
            os.kill(proc.pid, getattr(signal, kind))
        _, err = proc.communicate(timeout=90)
    finally:
        _kill(proc)
    code = proc.returncode
    assert "Traceback" not in err, f"{case}:\n{err}"
    expected = (0, -signal.SIGKILL) if kind == "SIGKILL" else (0, 130, -getattr(signal, kind))
    assert code in expected, f"{case}: exit {code}\n{err}"
    if code == 130:  # besides the warnings of topology changes before the stop
        lines = [line for line in err.strip().splitlines() if "changed from" not in line]
        assert len(lines) <= 2, f"{case}: stderr:\n{err}"
    _whole_set(root, case, killed=kind == "SIGKILL")
    if code != 0:
        again, err = _call(["run", "--resume", str(root), "--no-progress"], capsys, case)
        assert again == 0, f"{case}, --resume: {err}"
    _same_set(finished_set, root, case)


@pytest.mark.parametrize("kind", ["SIGTERM", "SIGKILL"])
def test_set_signal_then_resume_equals_the_uninterrupted_set(finished_set, tmp_path, capsys,
                                                             kind):
    _check_set_signal(finished_set, tmp_path, capsys, kind, ("SIGTERM", "SIGKILL").index(kind),
                      SEED)


@pytest.mark.slow
@pytest.mark.parametrize("index", range(9))
def test_set_signal_then_resume_equals_the_uninterrupted_set_long(finished_set, tmp_path,
                                                                  capsys, index):
    kind = ("SIGINT", "SIGTERM", "SIGKILL")[index % 3]
    _check_set_signal(finished_set, tmp_path, capsys, kind, index, SEED + 1)


def _check_set_disk(finished_set, tmp_path, capsys, monkeypatch, index: int, seed: int,
                    spread: tuple[float, float], code: int | None = None) -> None:
    """A set onto a read-only or filling disk: one line, exit 2 only before anything was
    written, else 3; every record whole; ``--resume`` with room again finishes the set."""
    rng = np.random.default_rng([seed, index])
    drawn = int(rng.choice([errno.EROFS, errno.ENOSPC, errno.ENOSPC]))
    code = drawn if code is None else code
    # what a set writes: its checkpoints and run.toml files are rewritten as it goes, about
    # 2.5 times the bytes it leaves (``spread`` is a fraction of that)
    total = 2.5 * sum(len(v) for k, v in snapshot(finished_set).items()
                      if "analysis" not in k and k != "replicas.json")
    budget = int(total * rng.uniform(*spread))
    root = tmp_path / "out" / "set"
    argv = ["run", str(_write(tmp_path / "s.toml", SET_TOML)), "--out", str(root),
            "--no-progress"]
    case = f"set case {index} (seed {seed}): {errno.errorcode[code]} after {budget} bytes"
    disk = FailingDisk(tmp_path / "out", code, budget)
    disk.install(monkeypatch)
    try:
        status, err = _call(argv, capsys, case)
    finally:
        monkeypatch.undo()
    if status == 2 or code == errno.EROFS:
        assert status == 2, f"{case}: exit {status}: {err}"
        left = sorted(p.name for p in root.iterdir()) if root.exists() else []
        assert not left, f"{case}: exit 2 (nothing done) but the set wrote {left}: {err}"
    elif disk.failures:
        assert status == 3, f"{case}: exit {status}: {err}"
    if status:
        assert str(root) in err, f"{case}: the line names no output path: {err}"
    if root.exists():
        _whole_set(root, case)
    if status == 3:
        again, err = _call(["run", "--resume", str(root), "--no-progress"], capsys,
                           case + ", --resume")
        assert again == 0, f"{case}, --resume with room again: {err}"
    elif status == 2:
        again, err = _call(argv, capsys, case + ", run again")
        assert again == 0, f"{case}, the same command with room again: {err}"
    _same_set(finished_set, root, case)


@pytest.mark.parametrize("index", range(2))
def test_set_onto_a_filling_disk_then_resumed(finished_set, tmp_path, capsys, monkeypatch,
                                              index):
    """BUG-8: a disk that fills up during the set (replica 1 or 2)."""
    _check_set_disk(finished_set, tmp_path, capsys, monkeypatch, index, SEED, (0.4, 0.9),
                    errno.ENOSPC)


@pytest.mark.slow
@pytest.mark.parametrize("index", range(12))
def test_set_onto_a_failing_disk_then_resumed_long(finished_set, tmp_path, capsys,
                                                   monkeypatch, index):
    _check_set_disk(finished_set, tmp_path, capsys, monkeypatch, index, SEED + 1, (0.0, 1.0))


# -- a damaged replicas.toml ----------------------------------------------------------------
def _cut_record(text: str) -> str:
    return text[:text.index("[run_file")]


#: Damages of replicas.toml: the audit's (BUG-19) and others of the same kinds.
RECORD_DAMAGES = {
    "empty": lambda text: "",
    "no_run_file": _cut_record,
    "seeds_int": lambda text: re.sub(r"(?ms)^seeds = \[.*?\]", "seeds = 5", text),
    "bare_count": lambda text: "replicas = 3\n",
    "seeds_strings": lambda text: re.sub(r"(?ms)^seeds = \[.*?\]", 'seeds = ["a", "b", "c"]',
                                         text),
    "run_file_string": lambda text: _cut_record(text) + 'run_file = "set.toml"\n',
    "count_more": lambda text: text.replace("count = 3", "count = 5"),
    "seeds_negative": lambda text: re.sub(r"(?ms)^seeds = \[.*?\]", "seeds = [-1, 2, 3]",
                                          text),
}


def _check_record(finished_set, tmp_path, capsys, monkeypatch, damage: str, seed: int,
                  index: int = 0) -> None:
    rng = np.random.default_rng([seed, index])
    root = tmp_path / "set"
    shutil.copytree(finished_set, root)
    record = root / "replicas.toml"
    if damage in RECORD_DAMAGES:
        record.write_text(RECORD_DAMAGES[damage](record.read_text()))
        what = damage
    else:
        monkeypatch.setattr(test_run_fuzz, "TARGETS", ("replicas.toml",))
        what = test_run_fuzz._damage(root, rng)
        monkeypatch.undo()
    extend = bool(rng.integers(0, 2)) or damage in RECORD_DAMAGES
    if not extend:
        _set_status(root / "replica_2", "interrupted")
    case = f"replicas.toml {what} (seed {seed}, case {index}), extend {extend}"
    before = snapshot(root)
    argv = ["run", "--resume", str(root), "--no-progress"] + (["--duration", "2.5"]
                                                            if extend else [])
    code, err = _call(argv, capsys, case)
    if code == 2:  # refused: the set is as it was
        assert_kept(before, root, case)
    elif code == 0:
        for replica in _replicas(root):
            assert _status(replica) == "finished", f"{case}: {replica.name}"
            assert _facts(replica)["time_reached"] == pytest.approx(2.5 if extend else 2.0)
    damaged = before.get("replicas.toml")  # the test's damage, left by a refused command
    _whole_set(root, case, record=damaged)
    json_before = (root / "replicas.json").read_bytes()
    code, err = _call(["analyze", str(root), "--knot-samples", "0", "--no-plots"], capsys,
                      case + ", analyze")
    if code != 0:
        assert (root / "replicas.json").read_bytes() == json_before, case
    _whole_set(root, case, record=damaged)


@pytest.mark.parametrize("damage", ["empty", "no_run_file", "seeds_int", "bare_count",
                                    "seeds_strings", "cut"])
def test_damaged_replica_record_resumes_or_fails_clearly(finished_set, tmp_path, capsys,
                                                         monkeypatch, damage):
    _check_record(finished_set, tmp_path, capsys, monkeypatch, damage, SEED)


@pytest.mark.slow
@pytest.mark.parametrize("index", range(16))
def test_damaged_replica_record_resumes_or_fails_clearly_long(finished_set, tmp_path, capsys,
                                                              monkeypatch, index):
    names = [*RECORD_DAMAGES, "random", "random"]
    _check_record(finished_set, tmp_path, capsys, monkeypatch, names[index % len(names)],
                  SEED + 1, index)


# -- refused --overwrite: nothing lost ------------------------------------------------------
def test_refused_overwrite_keeps_a_live_single_run(finished_set, tmp_path, capsys):
    """BUG-1: a set's ``--overwrite`` into the directory of a single run that is running."""
    live = tmp_path / "live"
    shutil.copytree(finished_set / "replica_0", live)
    _set_status(live, "running")
    before = snapshot(live)
    case = "run SET --overwrite into a live single run"
    with RunLock(live, "run"):  # the live run's lock (held by this process here)
        code, err = _call(["run", str(_write(tmp_path / "s.toml", SET_TOML)), "--out",
                           str(live), "--overwrite", "--no-progress"], capsys, case)
        assert code == 2, f"{case}: exit {code}: {err}"
        assert_kept(before, live, case)


@pytest.mark.parametrize("count", [2, 3])
def test_refused_overwrite_keeps_a_live_set(finished_set, tmp_path, capsys, count):
    """BUG-2: ``--overwrite`` into a replica set that is running (replica 1)."""
    root = tmp_path / "set"
    shutil.copytree(finished_set, root)
    _set_status(root / "replica_1", "running")
    before = snapshot(root)
    case = f"run SET (replicas = {count}) --overwrite into a live set"
    with RunLock(root, "run"):
        code, err = _call(["run", str(_write(tmp_path / "s.toml", SET_TOML)), "--out",
                           str(root), "--overwrite", "--no-progress", "--set",
                           f"run.replicas={count}"], capsys, case)
        assert code == 2, f"{case}: exit {code}: {err}"
        assert_kept(before, root, case)


@pytest.mark.parametrize("bad", ["overlap", "integrator", "lj_sigma", "beads_option"])
def test_refused_overwrite_of_a_set_keeps_the_set(finished_set, tmp_path, capsys, bad):
    """BUG-3: ``--overwrite`` of a finished set with a run file that cannot run."""
    root = tmp_path / "set"
    shutil.copytree(finished_set, root)
    before = snapshot(root)
    text, extra = SET_TOML, ["--set", "run.replicas=2"]
    if bad == "overlap":
        text = OVERLAP_TOML
    elif bad == "integrator":
        extra += ["--set", "run.integrator=heun"]
    elif bad == "lj_sigma":
        extra += ["--set", "model.lj_sigma=-1"]
    else:
        extra += ["--beads", "3"]
    case = f"run --overwrite of a finished set, {bad}"
    code, err = _call(["run", str(_write(tmp_path / "s.toml", text)), "--out", str(root),
                       "--overwrite", "--no-progress", *extra], capsys, case)
    assert code == 2, f"{case}: exit {code}: {err}"
    assert_kept(before, root, case)


@pytest.mark.slow
def test_two_new_sets_into_one_directory_at_once(finished_set, tmp_path, capsys):
    """Two sets started into one new directory at once: one is refused, the other whole."""
    root = tmp_path / "set"
    path = _write(tmp_path / "s.toml", SET_TOML)
    proc = subprocess.Popen([sys.executable, "-m", "knotmm.cli", "run", str(path), "--out",
                             str(root), "--no-progress"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        end = time.monotonic() + 120
        while not (root / ".knotmm.lock").exists() and proc.poll() is None:
            assert time.monotonic() < end
            time.sleep(0.01)
        code, err = _call(["run", str(path), "--out", str(root), "--no-progress"], capsys,
                          "the second set")
        _, err_first = proc.communicate(timeout=120)
    finally:
        _kill(proc)
    assert sorted([code, proc.returncode]) == [0, 2], (code, err, proc.returncode, err_first)
    _same_set(finished_set, root, "two sets at once")


# -- analyze of the set ---------------------------------------------------------------------
def _check_analyze_set(finished_set, tmp_path, capsys, monkeypatch, index: int, seed: int,
                       code: int | None = None, budget: int | None = None) -> None:
    rng = np.random.default_rng([seed, index])
    code = code if code is not None else int(rng.choice([errno.EROFS, errno.ENOSPC]))
    budget = budget if budget is not None else int(rng.integers(0, 150_000))
    plots = ["--no-plots"] if rng.integers(0, 3) else []
    root = tmp_path / "set"
    shutil.copytree(finished_set, root)
    before = (root / "replicas.json").read_bytes()
    runs = {p.name: snapshot(p) for p in _replicas(root)}
    case = (f"analyze set case {index} (seed {seed}): {errno.errorcode[code]} after {budget} "
            f"bytes, plots {not plots}")
    disk = FailingDisk(root, code, budget)
    disk.install(monkeypatch)
    try:
        status, err = _call(["analyze", str(root), "--knot-samples", "0", *plots], capsys,
                            case)
    finally:
        monkeypatch.undo()
    if code == errno.EROFS or budget == 0:
        assert status in (2, 3), f"{case}: nothing could be written, yet exit {status}: {err}"
    now = (root / "replicas.json").read_bytes()
    if now != before:
        data = json.loads(now)
        assert len(data["points"]["all"]["runs"]) == 3, f"{case}: replicas.json now {data}"
    for name, files in runs.items():  # the runs' own files are never touched
        for file in ("trajectory.dcd", "run.toml", "checkpoint.npz", "observables.csv"):
            assert (root / name / file).read_bytes() == files[file], f"{case}: {name}/{file}"
    _whole_set(root, case)
    _whole_pngs(root, case)


@pytest.mark.parametrize(("code", "budget"), [(errno.ENOSPC, 0), (errno.EROFS, 0),
                                              (errno.ENOSPC, None)])
def test_analyze_set_onto_a_failing_disk(finished_set, tmp_path, capsys, monkeypatch, code,
                                         budget):
    """BUG-5, BUG-6: replicas.json is whole and never replaced by one of fewer runs."""
    _check_analyze_set(finished_set, tmp_path, capsys, monkeypatch, 0, SEED, code, budget)


@pytest.mark.slow
@pytest.mark.parametrize("index", range(12))
def test_analyze_set_onto_a_failing_disk_long(finished_set, tmp_path, capsys, monkeypatch,
                                              index):
    _check_analyze_set(finished_set, tmp_path, capsys, monkeypatch, index, SEED + 1)


def test_analyze_set_says_which_replicas_are_not_in_it(finished_set, tmp_path, capsys):
    """BUG-17: replica 1 still running, replica 2 never started: replicas.json does not
    count the first as finished without a word, nor leave the second out silently."""
    root = tmp_path / "set"
    shutil.copytree(finished_set, root)
    (root / "replicas.json").unlink()
    shutil.rmtree(root / "replica_2")
    _set_status(root / "replica_1", "running")
    case = "analyze a set with replica 1 running and replica 2 not started"
    with RunLock(root / "replica_1", "run"):
        code, err = _call(["analyze", str(root), "--knot-samples", "0", "--no-plots"],
                          capsys, case)
    if code == 0:
        text = (root / "replicas.json").read_text()
        runs = json.loads(text)["points"]["all"]["runs"]
        assert "replica_2" in text, f"{case}: replicas.json does not name replica_2"
        assert "replica_1" not in runs or "running" in text, (
            f"{case}: replica_1 counted among the runs: {runs}")


# -- sweeps of several chains, links and open filaments -------------------------------------
@pytest.fixture(scope="module")
def finished_sweep(tmp_path_factory):
    """``finished_sweep(kind)``: (sweep file, a finished sweep of it), made on first use."""
    base = tmp_path_factory.mktemp("fuzz_sweeps")
    made: dict[str, tuple[Path, Path]] = {}

    def get(kind: str) -> tuple[Path, Path]:
        if kind not in made:
            path = _write(base / f"{kind}.toml", SWEEPS[kind])
            out = base / kind
            assert main(["sweep", str(path), "--out", str(out), "--workers", "0",
                         "--no-progress"]) == 0, kind
            made[kind] = (path, out)
        return made[kind]

    return get


def _points(directory: Path) -> list[Path]:
    return sorted(p.parent for p in directory.glob("*/run.toml"))


def _whole_sweep(directory: Path, count: int, case: str, killed: bool = False) -> None:
    """The sweep's own files are whole (or absent); no temporary is left (unless the
    process was ``killed`` inside an atomic write)."""
    if not killed:
        assert _temporaries(directory) == [], case
    if (directory / "sweep.toml").exists():
        tomllib.loads((directory / "sweep.toml").read_text())
    if (directory / "summary.csv").exists():
        rows = read_summary(directory)
        assert len(rows) == count and all(r["status"] for r in rows), f"{case}: {rows}"
    for point in _points(directory):
        tomllib.loads((point / "run.toml").read_text())


def _same_sweep(reference: Path, directory: Path, case: str) -> None:
    rows = read_summary(directory)
    assert [r["status"] for r in rows] == ["finished"] * len(read_summary(reference)), case
    for point in _points(reference):
        assert_same_run(point, directory / point.name, f"{case}: {point.name}")


@pytest.mark.parametrize("kind", SWEEP_KINDS)
def test_sweep_dry_run_accepts_the_system(finished_sweep, tmp_path, capsys, kind):
    """BUG-12: ``--dry-run`` checks each point as the sweep runs it."""
    path, _ = finished_sweep(kind)
    code, err = _call_sweep(["sweep", str(path), "--out", str(tmp_path / "dry"), "--dry-run"],
                            capsys, f"{kind} sweep --dry-run")
    assert code == 0, f"{kind} sweep --dry-run: {err}"


@pytest.mark.parametrize("kind", SWEEP_KINDS)
def test_sweep_same_command_again_skips_finished_points(finished_sweep, tmp_path, capsys,
                                                        kind):
    """BUG-7: the same command on a finished sweep of ``[[chains]]`` points."""
    path, base = finished_sweep(kind)
    directory = tmp_path / "sweep"
    shutil.copytree(base, directory)
    before = snapshot(directory)
    case = f"{kind} sweep, the same command again"
    capsys.readouterr()
    try:
        code = main(["sweep", str(path), "--out", str(directory), "--workers", "0",
                     "--no-progress"])
    except BaseException as exc:  # noqa: BLE001 - the point of the test
        pytest.fail(f"{case}: raised {exc!r}")
    out, err = capsys.readouterr()
    assert code == 0, f"{case}: exit {code}: {err}"
    assert "Traceback" not in err and "already finished" in out, f"{case}: {out}{err}"
    for name, data in before.items():  # the points were not run again
        if name.endswith(("trajectory.dcd", "checkpoint.npz")):
            assert (directory / name).read_bytes() == data, f"{case}: {name} rewritten"


def _check_sweep_signal(finished_sweep, tmp_path, capsys, kind: str, sig: str, index: int,
                        seed: int) -> None:
    rng = np.random.default_rng([seed, index, SWEEP_KINDS.index(kind) if kind in SWEEP_KINDS
                                 else 9])
    path, base = finished_sweep(kind)
    names = [p.name for p in _points(base)]
    point = names[int(rng.integers(0, len(names)))]
    moment = float(rng.uniform(0.1, 1.8))
    workers = str(rng.choice(["0", "0", "1"]))
    directory = tmp_path / "sweep"
    case = f"{kind} sweep: {sig} at t = {moment:.2f} of {point}, {workers} workers"
    argv = [sys.executable, "-m", "knotmm.cli", "sweep", str(path), "--out", str(directory),
            "--workers", workers, "--no-progress"]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_default_sigint)
    try:
        end = time.monotonic() + 180
        while proc.poll() is None and _model_time(directory / point) < moment:
            assert time.monotonic() < end, f"{case}: no progress"
            time.sleep(0.01)
        if proc.poll() is None:
            os.kill(proc.pid, getattr(signal, sig))
        _, err = proc.communicate(timeout=90)
    finally:
        _kill(proc)
    code = proc.returncode
    assert "Traceback" not in err, f"{case}:\n{err}"
    allowed = (0, -signal.SIGKILL) if sig == "SIGKILL" else (0, 130, -getattr(signal, sig))
    assert code in allowed, f"{case}: exit {code}\n{err}"
    if sig != "SIGKILL":
        for run_dir in _points(directory):
            assert _status(run_dir) != "running", f"{case}: {run_dir.name} left running"
    _whole_sweep(directory, len(names), case, killed=sig == "SIGKILL")
    code, err = _call_sweep(["sweep", str(path), "--out", str(directory), "--workers", "0",
                             "--no-progress"], capsys, case + ", run again", codes=(0,))
    _same_sweep(base, directory, case)
    assert not (directory / ".knotmm.lock").exists(), case


@pytest.mark.parametrize(("kind", "sig"), [("chains", "SIGKILL"), ("open", "SIGINT")])
def test_sweep_signal_then_same_command_finishes_it(finished_sweep, tmp_path, capsys, kind,
                                                    sig):
    _check_sweep_signal(finished_sweep, tmp_path, capsys, kind, sig, 0, SEED)


@pytest.mark.slow
@pytest.mark.parametrize("index", range(9))
def test_sweep_signal_then_same_command_finishes_it_long(finished_sweep, tmp_path, capsys,
                                                         index):
    kind = ("chains", "open", "link")[index % 3]
    sig = ("SIGINT", "SIGTERM", "SIGKILL")[(index // 3) % 3]
    _check_sweep_signal(finished_sweep, tmp_path, capsys, kind, sig, index, SEED + 1)


def _check_sweep_disk(finished_sweep, tmp_path, capsys, monkeypatch, kind: str, index: int,
                      seed: int) -> None:
    rng = np.random.default_rng([seed, index])
    path, base = finished_sweep(kind)
    count = len(read_summary(base))
    code = int(rng.choice([errno.EROFS, errno.ENOSPC, errno.ENOSPC]))
    budget = int(rng.integers(0, sum(len(v) for v in snapshot(base).values())))
    directory = tmp_path / "sweep"
    case = f"{kind} sweep case {index} (seed {seed}): {errno.errorcode[code]} after {budget}"
    argv = ["sweep", str(path), "--out", str(directory), "--workers", "0", "--no-progress"]
    disk = FailingDisk(directory, code, budget)
    disk.install(monkeypatch)
    try:
        status, err = _call_sweep(argv, capsys, case)
    finally:
        monkeypatch.undo()
    if code == errno.EROFS:
        assert status == 2, f"{case}: exit {status}: {err}"
    if status in (2, 3):
        assert str(directory) in err, f"{case}: the line names no output path: {err}"
    if directory.exists():
        _whole_sweep(directory, count, case)
    code, err = _call_sweep(argv, capsys, case + ", run again", codes=(0,))
    _same_sweep(base, directory, case)


@pytest.mark.parametrize("kind", SWEEP_KINDS)
def test_sweep_onto_a_failing_disk_then_run_again(finished_sweep, tmp_path, capsys,
                                                  monkeypatch, kind):
    _check_sweep_disk(finished_sweep, tmp_path, capsys, monkeypatch, kind, 0, SEED)


@pytest.mark.slow
@pytest.mark.parametrize("index", range(9))
def test_sweep_onto_a_failing_disk_then_run_again_long(finished_sweep, tmp_path, capsys,
                                                       monkeypatch, index):
    kind = ("chains", "open", "link")[index % 3]
    _check_sweep_disk(finished_sweep, tmp_path, capsys, monkeypatch, kind, index, SEED + 1)


def test_sweep_of_replica_sets_runs_the_replicas_or_refuses(tmp_path, capsys):
    """BUG-9: a sweep whose points ask for ``run.replicas = 2`` runs two replicas per point
    (or refuses in one line, with ``--dry-run`` alike); never one run recorded as two.

    The points are one ring at Pe = 10 (``--dry-run`` of ``[[chains]]`` and open points is
    BUG-12, tested above).
    """
    text = """
[knot]
beads = 30
[run]
duration = 2.0
peclet = 10.0
replicas = 2
topology_check_interval = 0.0
""" + _SWEEP.replace("[3.0, 6.0]", "[3.0]")
    path = _write(tmp_path / "rep.toml", text)
    directory = tmp_path / "sweep"
    dry, err_dry = _call_sweep(["sweep", str(path), "--out", str(directory), "--dry-run"],
                               capsys, "sweep --dry-run of replica sets")
    code, err = _call_sweep(["sweep", str(path), "--out", str(directory), "--workers", "0",
                             "--no-progress"], capsys, "sweep of replica sets")
    assert (dry == 2) == (code == 2), f"--dry-run exit {dry} ({err_dry}), the sweep {code}"
    if code == 2:
        return
    assert code == 0, err
    # two runs with their own seeds: replica_0/ and replica_1/ of a point, or two points
    runs = sorted(p.parent for p in directory.rglob("run.toml"))
    seeds = {tomllib.loads((run / "run.toml").read_text())["run"]["seed"] for run in runs}
    assert len(runs) == 2 and len(seeds) == 2, (
        f"one swept value with run.replicas = 2 made the runs {[str(r) for r in runs]} "
        f"(seeds {seeds})")
