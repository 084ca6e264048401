"""Fuzz ``knotmm run``, ``--resume`` and ``analyze`` on every system kind (issue 30).

``test_run_fuzz.py`` and ``test_fuzz_analyze_sweep.py`` fuzz one ring; this file puts the
same hostile inputs to the other systems a run file can describe, each a short, small
variant (:data:`SYSTEMS`):

* ``ring``: one T(2,3) of 30 beads at Pe = 1 that unties at t = 8 tau_d (a knot-type change
  in the run's topology record);
* ``two``: ``[[chains]]`` of a T(2,3) and an open "arc" chain, offsets apart, Pe = 5;
* ``link``: the hopf link (``kind = "knotinfo"``, ``name = "hopf"``, 40 beads) at Pe = 1,
  whose linking number changes from 1 to 0 at t = 10.5 tau_d;
* ``open``: an open helix (``kind = "helix"``);
* (slow set) ``open_torus`` (``closed = false``) and ``mix`` (a hopf link, a helix and a
  rod in ``[[chains]]``).

The hostile inputs, with the helpers of those files (``_call``, ``_kill``, ``_status``,
``_damage``, :class:`FailingDisk`):

* damaged run directories (a file cut, emptied, removed, bytes flipped, or an edited
  ``[knotmm.layout]``), then ``--resume`` and ``analyze``;
* a signal (SIGINT, SIGTERM, two SIGINTs, SIGKILL) at a random moment of the run's model
  time, then ``--resume``;
* a failing disk (EROFS, or ENOSPC after a random number of bytes) under ``run`` and under
  ``analyze``, then the run finished with room again;
* command-line options that do not fit the system (``--beads`` with ``[[chains]]``, ...)
  with ``--overwrite`` over a finished run.

The invariants are those of the ring's fuzz files: no traceback; exit 0, 2 or 3 (130 when
stopped); one stderr line for 2 and 3; nothing already written lost (a refused command
leaves the run's files as they were); ``--resume`` after any stop finishes with frames and
observables equal to the uninterrupted run's, and the same topology record
(``[knotmm] knot_type_start``, ``knot_type_changes``, ``linking_number_changes``, ...).
Every random choice comes from a fixed seed; the slow variants draw more cases.
"""

from __future__ import annotations

import errno
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import test_fuzz_analyze_sweep
import test_run_fuzz
from test_fuzz_analyze_sweep import _temporaries, _whole_json, _whole_pngs
from test_run_fuzz import (
    _call,
    _default_sigint,
    _facts,
    _kill,
    _send,
    _set_status,
    _status,
)

from knotmm.cli.main import main
from knotmm.io.dcd import read_dcd

SEED = 20261204
_OUTPUT = """
[output]
frame_interval = 0.1
checkpoint_interval = 0.5
"""
#: The systems: run file, and the files of a run directory (all short: a few tau_d).
SYSTEMS = {
    "ring": """
[knot]
beads = 30
[run]
duration = 10.0
peclet = 1.0
seed = 3
topology_check_interval = 0.5
""",
    "two": """
[[chains]]
kind = "torus"
beads = 30
offset = [-4.0, 0.0, 0.0]
[[chains]]
kind = "arc"
beads = 20
offset = [4.0, 0.0, 0.0]
[run]
duration = 3.0
peclet = 5.0
seed = 11
topology_check_interval = 0.5
""",
    "link": """
[knot]
kind = "knotinfo"
name = "hopf"
beads = 40
[run]
duration = 12.0
peclet = 1.0
seed = 1
topology_check_interval = 0.5
""",
    "open": """
[knot]
kind = "helix"
beads = 30
[run]
duration = 3.0
topology_check_interval = 0.5
""",
    "open_torus": """
[knot]
kind = "torus"
beads = 40
closed = false
[run]
duration = 3.0
peclet = 10.0
seed = 2
topology_check_interval = 0.5
""",
    "mix": """
[[chains]]
kind = "knotinfo"
name = "hopf"
beads = 40
offset = [-6.0, 0.0, 0.0]
[[chains]]
kind = "helix"
beads = 20
offset = [6.0, 0.0, 0.0]
[[chains]]
kind = "straight"
beads = 10
offset = [0.0, 8.0, 0.0]
rotation = [0.0, 1.0, 0.0, 90.0]
[run]
duration = 3.0
peclet = 10.0
seed = 4
topology_check_interval = 0.5
""",
}
SYSTEMS = {name: text + _OUTPUT for name, text in SYSTEMS.items()}
#: When a system's topology changes (``ring``: its knot type; ``link``: its linking number),
#: in tau_d: a signal after it tests that the change survives ``--resume``.
EVENTS = {"ring": 8.0, "link": 10.5}
#: The default set's systems (the slow set adds the others).
DEFAULT = ("ring", "two", "link", "open")
SLOW = tuple(SYSTEMS)
RUN_FILES = ("trajectory.dcd", "observables.csv", "checkpoint.npz", "run.toml",
             "topology.pdb", "view.vmd")
#: The topology record of run.toml that a resumed run shares with the uninterrupted one.
KNOT_KEYS = ("template_knot_type", "knot_type_start", "knot_type", "knot_type_changes",
             "knot_type_checks")
LINK_KEYS = ("linking_numbers", "linking_numbers_now", "linking_number_changes",
             "linking_checks")


# -- helpers --------------------------------------------------------------------------------
class _Refunding(test_fuzz_analyze_sweep._Capped):
    """A file of a :class:`FailingDisk` whose room comes back when it is cut short."""

    def truncate(self, size=None):
        before = os.fstat(self._fh.fileno()).st_size
        done = self._fh.truncate(size)
        freed = before - os.fstat(self._fh.fileno()).st_size
        self._disk.used = max(0, self._disk.used - max(0, freed))
        return done


class FailingDisk(test_fuzz_analyze_sweep.FailingDisk):
    """:class:`test_fuzz_analyze_sweep.FailingDisk`, where a file truncated in place gives
    its bytes back, as on a real full disk (knotmm rewrites run.toml in place when there is
    no room for a temporary copy; without the refund that rewrite could never succeed)."""

    def install(self, monkeypatch) -> None:
        monkeypatch.setattr(test_fuzz_analyze_sweep, "_Capped", _Refunding)
        super().install(monkeypatch)


def run_file(system: str, where: Path) -> Path:
    """Write the run file of ``system`` into ``where``; return its path."""
    path = where / f"{system}.toml"
    if not path.exists():
        where.mkdir(parents=True, exist_ok=True)
        path.write_text(SYSTEMS[system])
    return path


def snapshot(directory: Path) -> dict[str, bytes]:
    """Every file under ``directory`` (relative name -> bytes), for "nothing was lost"."""
    if not directory.exists():
        return {}
    return {str(p.relative_to(directory)): p.read_bytes()
            for p in sorted(directory.rglob("*")) if p.is_file() and p.name != ".knotmm.lock"}


def assert_kept(before: dict[str, bytes], directory: Path, case: str) -> None:
    """The files of ``before`` are all still in ``directory``, byte for byte."""
    after = snapshot(directory)
    lost = sorted(name for name in before if name not in after)
    changed = sorted(name for name in before if name in after and after[name] != before[name])
    assert not lost and not changed, f"{case}: lost {lost}, changed {changed}"


def topology_record(directory: Path) -> tuple[dict, bool]:
    """run.toml's topology record, and whether every knot-type check was made (the knot
    worker starts beside a run: a check it could not answer in time is dropped, and the
    knot-type keys of such a run are then not compared)."""
    facts = _facts(directory)
    complete = not facts.get("knot_type_checks_dropped") and not any(
        "not checked" in str(n) and "open chain" not in str(n)
        for n in facts.get("notes", []) or [])
    return {key: facts.get(key) for key in (*KNOT_KEYS, *LINK_KEYS)}, complete


def assert_same_run(reference: Path, directory: Path, case: str) -> None:
    """``directory`` holds the run of ``reference``: same frames (float32 bit for bit),
    same observables, same topology record."""
    a, _ = read_dcd(reference / "trajectory.dcd")
    b, _ = read_dcd(directory / "trajectory.dcd")
    assert a.shape == b.shape, f"{case}: {b.shape[0]} frames, the uninterrupted run {a.shape[0]}"
    assert np.array_equal(a, b), f"{case}: frames differ from the uninterrupted run's"
    rows_a = (reference / "observables.csv").read_text().splitlines()
    rows_b = (directory / "observables.csv").read_text().splitlines()
    assert rows_a == rows_b, f"{case}: observables.csv differs from the uninterrupted run's"
    ref, ref_complete = topology_record(reference)
    got, complete = topology_record(directory)
    keys = LINK_KEYS if not (ref_complete and complete) else (*KNOT_KEYS, *LINK_KEYS)
    wrong = {k: (ref[k], got[k]) for k in keys if ref[k] != got[k]}
    assert not wrong, f"{case}: topology record (uninterrupted, resumed): {wrong}"


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """``reference(system)``: a finished, uninterrupted run of ``system`` (made once, on
    first use; copied by the tests, never changed)."""
    base = tmp_path_factory.mktemp("fuzz_systems")
    made: dict[str, Path] = {}

    def get(system: str) -> Path:
        if system not in made:
            directory = base / system
            code = main(["run", str(run_file(system, base)), "--out", str(directory),
                         "--no-progress"])
            assert code == 0, system
            assert _status(directory) == "finished", system
            made[system] = directory
        return made[system]

    get.base = base
    return get


def _model_time(directory: Path) -> float:
    """The time of the last row of observables.csv (-1 when there is none yet)."""
    try:
        last = (directory / "observables.csv").read_text().strip().splitlines()[-1]
        return float(last.split(",")[0])
    except (OSError, IndexError, ValueError):
        return -1.0


# -- damaged run directories ----------------------------------------------------------------
def _edit_layout(directory: Path, rng) -> str:
    """Edit run.toml's ``[knotmm.layout]`` as a user might (BUG-20 of the audit)."""
    path = directory / "run.toml"
    text = path.read_text()
    table = re.search(r"(?ms)^\[knotmm\.layout\]\n.*?(?=^\[|\Z)", text)
    match = re.search(r"(?ms)^(\[knotmm\.layout\]\nlengths = )\[(.*?)\]", text)
    if table is None or match is None:  # a single ring records no layout
        return test_run_fuzz._damage(directory, rng)
    lengths = [int(v) for v in re.findall(r"\d+", match.group(2))]
    how = str(rng.choice(["sum", "string", "split", "closed", "drop"]))
    if how == "closed":
        new = re.sub(r"(?m)^(closed = \[\n\s+)(true|false)",
                     lambda m: m.group(1) + ("false" if m.group(2) == "true" else "true"),
                     text, count=1)
        what = "closed[0] flipped"
    elif how == "drop":
        new = text[:table.start()] + text[table.end():]
        what = "removed"
    else:
        if how == "string":
            literal = '"abc"'
        elif how == "split" and len(lengths) > 1:
            literal = str([lengths[0] - 5, *lengths[1:-1], lengths[-1] + 5])
        else:
            literal = str([*lengths[:-1], lengths[-1] + 1])
        new = text[:match.start()] + match.group(1) + literal + text[match.end():]
        what = f"lengths = {literal} (was {lengths})"
    path.write_text(new)
    return f"run.toml [knotmm.layout] {what}"


def _check_damaged(reference, tmp_path, capsys, system: str, index: int, seed: int) -> None:
    rng = np.random.default_rng([seed, index, SLOW.index(system)])
    directory = tmp_path / system
    shutil.copytree(reference(system), directory)
    mark = str(rng.choice(test_run_fuzz.MARKS))
    _set_status(directory, mark)
    layout = rng.integers(0, 3) == 0
    what = _edit_layout(directory, rng) if layout else test_run_fuzz._damage(directory, rng)
    # an edit that contradicts the run file must stop the run (a removed table may be
    # made again from the run file)
    layout = layout and "layout" in what and "removed" not in what
    duration = float(_facts(reference(system))["time_reached"])
    case = f"{system} case {index} (seed {seed}): status {mark}, {what}"
    extend = mark == "finished" or bool(rng.integers(0, 2))
    argv = ["run", "--resume", str(directory), "--no-progress"]
    target = None
    if extend:
        target = duration + 0.5
        argv += ["--duration", str(target)]
    before = snapshot(directory)
    code, err = _call(argv, capsys, case)
    status = _status(directory)
    if code == 0:
        assert status == "finished", f"{case}: resumed with exit 0, status {status}"
        reached = _facts(directory)["time_reached"]
        assert reached == pytest.approx(target if extend else duration), case
    elif code == 3:
        assert status == "fault", f"{case}: exit 3, status {status}"
    else:
        # refused before it started: nothing it found was changed or removed
        assert_kept(before, directory, case)
    if layout and code == 0:
        pytest.fail(f"{case}: a run resumed from an edited layout (exit 0): {err}")
    _call(["analyze", str(directory), "--knot-samples", "0", "--no-plots"], capsys, case)


@pytest.mark.parametrize("index", range(2))
@pytest.mark.parametrize("system", DEFAULT)
def test_damaged_system_resumes_or_fails_clearly(reference, tmp_path, capsys, system, index):
    _check_damaged(reference, tmp_path, capsys, system, index, SEED)


@pytest.mark.slow
@pytest.mark.parametrize("index", range(12))
@pytest.mark.parametrize("system", SLOW)
def test_damaged_system_resumes_or_fails_clearly_long(reference, tmp_path, capsys, system,
                                                      index):
    _check_damaged(reference, tmp_path, capsys, system, index, SEED + 1)


#: Edits of the "two" run's ``[knotmm.layout] lengths`` (30 and 20 beads).
LAYOUT_EDITS = {"sum": "[30, 21]", "string": '"abc"', "split": "[25, 25]"}


@pytest.mark.parametrize("edit", sorted(LAYOUT_EDITS))
def test_edited_layout_is_refused_in_one_line(reference, tmp_path, capsys, edit):
    """BUG-20: an edited ``[knotmm.layout]`` stops ``--resume`` with one line, not a
    traceback, and the run's files stay as they were."""
    directory = tmp_path / "two"
    shutil.copytree(reference("two"), directory)
    _set_status(directory, "interrupted")
    path = directory / "run.toml"
    text, count = re.subn(r"(?ms)^(\[knotmm\.layout\]\nlengths = )\[.*?\]",
                          lambda m: m.group(1) + LAYOUT_EDITS[edit], path.read_text())
    assert count == 1
    path.write_text(text)
    before = snapshot(directory)
    case = f"--resume with [knotmm.layout] lengths = {LAYOUT_EDITS[edit]}"
    code, err = _call(["run", "--resume", str(directory), "--duration", "3.5",
                       "--no-progress"], capsys, case)
    assert code in (2, 3), f"{case}: exit {code}: {err}"
    if code == 2:
        assert_kept(before, directory, case)


# -- signals --------------------------------------------------------------------------------
def _check_signal(reference, tmp_path, capsys, system: str, kind: str, index: int, seed: int,
                  late: bool) -> None:
    """Signal a ``knotmm run`` child of ``system`` when its model time passes a random
    moment (``late``: after the system's topology changes), then resume it to the end and
    compare it with the uninterrupted run."""
    rng = np.random.default_rng([seed, index, SLOW.index(system)])
    ref = reference(system)
    duration = float(_facts(ref)["time_reached"])
    after = EVENTS.get(system, 0.5 * duration) + 0.2 if late else 0.05 * duration
    moment = float(rng.uniform(after, duration - 0.3))
    directory = tmp_path / system
    case = f"{system}: {kind} at t = {moment:.2f} tau_d (case {index}, seed {seed})"
    argv = [sys.executable, "-m", "knotmm.cli", "run", str(run_file(system, tmp_path)),
            "--out", str(directory), "--no-progress"]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_default_sigint)
    try:
        end = time.monotonic() + 180
        while proc.poll() is None and _model_time(directory) < moment:
            assert time.monotonic() < end, f"{case}: no progress in {directory}"
            time.sleep(0.01)
        if proc.poll() is None:
            _send(proc, kind, rng)
        _, err = proc.communicate(timeout=90)
    finally:
        _kill(proc)
    code = proc.returncode
    assert "Traceback" not in err, f"{case}:\n{err}"
    status = _status(directory)
    if code < 0:
        allowed = ("running", "finished") if kind == "SIGKILL" else ("finished",)
        assert status in allowed, f"{case}: exit {code}, status {status}\n{err}"
    else:
        assert code in (0, 130), f"{case}: exit {code}\n{err}"
        if code == 130 and status == "finished":  # the signal landed after the last step:
            # the run is whole (run.toml written before the signal is raised)
            assert _facts(directory)["time_reached"] == pytest.approx(duration), case
        else:
            assert status == ("finished" if code == 0 else "interrupted"), f"{case}: {status}"
        if code == 130:  # besides the warnings of topology changes before the stop
            lines = [line for line in err.strip().splitlines() if "changed from" not in line]
            assert len(lines) <= 2, f"{case}: stderr:\n{err}"
    if status != "finished":
        code, err = _call(["run", "--resume", str(directory), "--no-progress"], capsys, case)
        assert code == 0, f"{case}: {err}"
        assert _status(directory) == "finished", case
        assert _facts(directory)["time_reached"] == pytest.approx(duration), case
    assert_same_run(ref, directory, case)


@pytest.mark.parametrize(("system", "kind"), [("ring", "SIGKILL"), ("two", "SIGTERM"),
                                              ("link", "SIGINT"), ("open", "SIGINT2")])
def test_signal_then_resume_equals_the_uninterrupted_run(reference, tmp_path, capsys, system,
                                                         kind):
    _check_signal(reference, tmp_path, capsys, system, kind, 0, SEED, late=True)


@pytest.mark.slow
@pytest.mark.parametrize("kind", test_run_fuzz.SIGNALS)
@pytest.mark.parametrize("system", SLOW)
def test_signal_then_resume_equals_the_uninterrupted_run_long(reference, tmp_path, capsys,
                                                              system, kind):
    index = test_run_fuzz.SIGNALS.index(kind)
    _check_signal(reference, tmp_path, capsys, system, kind, index, SEED + 1,
                  late=bool(index % 2))


# -- a failing disk -------------------------------------------------------------------------
def _size(directory: Path) -> int:
    return sum(len(data) for data in snapshot(directory).values())


def _check_run_disk(reference, tmp_path, capsys, monkeypatch, system: str, index: int,
                    seed: int) -> None:
    """A run onto a read-only or filling disk fails in one line and is then finished."""
    rng = np.random.default_rng([seed, index, SLOW.index(system)])
    ref = reference(system)
    code = int(rng.choice([errno.EROFS, errno.ENOSPC, errno.ENOSPC]))
    budget = int(rng.integers(0, _size(ref)))
    directory = tmp_path / "out" / system
    path = run_file(system, tmp_path)
    argv = ["run", str(path), "--out", str(directory), "--no-progress"]
    case = (f"{system} run case {index} (seed {seed}): {errno.errorcode[code]} after "
            f"{budget} bytes")
    disk = FailingDisk(tmp_path / "out", code, budget)
    disk.install(monkeypatch)
    try:
        status, err = _call(argv, capsys, case)
    finally:
        monkeypatch.undo()
    if code == errno.EROFS:
        assert status == 2, f"{case}: exit {status}: {err}"
    if status == 2:  # refused before the run: nothing of it is left (BUG-23)
        left = sorted(p.name for p in directory.iterdir()) if directory.exists() else []
        assert not left, f"{case}: exit 2, yet the run left {left}: {err}"
    elif status:
        assert disk.failures, f"{case}: exit {status} with no write refused: {err}"
    if status:
        assert str(directory) in err, f"{case}: the line names no output path: {err}"
    if directory.exists():
        assert _temporaries(directory) == [], case
        if (directory / "run.toml").exists():  # whole, never cut or emptied (BUG-8)
            assert _status(directory) is not None, (
                f"{case}: run.toml is not whole ({(directory / 'run.toml').stat().st_size} "
                f"bytes): {err}")
    # with room again: --resume where the run had started, else the same command again
    if status == 0:
        pass
    elif (directory / "run.toml").is_file() and _status(directory) not in (None, "finished"):
        again, err = _call(["run", "--resume", str(directory), "--no-progress"], capsys,
                           case + ", --resume")
        assert again == 0, f"{case}, --resume: {err}"
    else:
        again, err = _call(argv, capsys, case + ", run again")
        assert again == 0, f"{case}, the same command again: {err}"
    assert_same_run(ref, directory, case)


@pytest.mark.parametrize("system", DEFAULT)
def test_run_onto_a_failing_disk_then_finished(reference, tmp_path, capsys, monkeypatch,
                                               system):
    _check_run_disk(reference, tmp_path, capsys, monkeypatch, system, 0, SEED)


@pytest.mark.slow
@pytest.mark.parametrize("index", range(6))
@pytest.mark.parametrize("system", SLOW)
def test_run_onto_a_failing_disk_then_finished_long(reference, tmp_path, capsys, monkeypatch,
                                                    system, index):
    _check_run_disk(reference, tmp_path, capsys, monkeypatch, system, index, SEED + 1)


def _check_analyze_disk(reference, tmp_path, capsys, monkeypatch, system: str, index: int,
                        seed: int) -> None:
    """``analyze`` of a system onto a failing disk: exit 2 (refused) or 3 in one line, or
    0; no file left half-written (BUG-26: a 0-byte PNG)."""
    rng = np.random.default_rng([seed, index, SLOW.index(system)])
    code = int(rng.choice([errno.EROFS, errno.ENOSPC, errno.ENOSPC]))
    budget = int(rng.integers(0, 200_000))
    directory = tmp_path / system
    shutil.copytree(reference(system), directory)
    before = None
    if rng.integers(0, 2):
        assert main(["analyze", str(directory), "--knot-samples", "0", "--no-plots"]) == 0
        before = (directory / "analysis.json").read_bytes()
    capsys.readouterr()
    case = f"{system} analyze case {index} (seed {seed}): {errno.errorcode[code]} after {budget}"
    kept = snapshot(directory)
    disk = FailingDisk(directory, code, budget)
    disk.install(monkeypatch)
    try:
        status, err = _call(["analyze", str(directory), "--knot-samples", "0"], capsys, case)
    finally:
        monkeypatch.undo()
    if code == errno.EROFS:
        assert status == 2, f"{case}: exit {status}: {err}"
    if status:
        assert str(directory) in err, f"{case}: the line names no output path: {err}"
    for name in RUN_FILES:  # the run's own files are never touched by its analysis
        assert (directory / name).read_bytes() == kept[name], f"{case}: {name} changed"
    _whole_json(directory / "analysis.json", before, case)
    assert _temporaries(directory) == [], case
    _whole_pngs(directory, case)


@pytest.mark.parametrize("system", DEFAULT)
def test_analyze_of_a_system_onto_a_failing_disk(reference, tmp_path, capsys, monkeypatch,
                                                 system):
    _check_analyze_disk(reference, tmp_path, capsys, monkeypatch, system, 0, SEED)


@pytest.mark.slow
@pytest.mark.parametrize("index", range(8))
@pytest.mark.parametrize("system", SLOW)
def test_analyze_of_a_system_onto_a_failing_disk_long(reference, tmp_path, capsys,
                                                      monkeypatch, system, index):
    _check_analyze_disk(reference, tmp_path, capsys, monkeypatch, system, index, SEED + 1)


# -- options that do not fit the system -----------------------------------------------------
#: Command-line options drawn for a run over a finished run (``--overwrite``).
OPTIONS = (["--beads", "40"], ["--beads", "3"], ["--set", "knot.beads=40"],
           ["--set", "knot.closed=false"], ["--set", "run.replicas=0"],
           ["--set", "run.integrator=heun"], ["--duration", "nan"], ["--duration", "-1"],
           ["--set", "knot.kind=straight"], ["--set", "model.lj_sigma=-1"],
           ["--set", "knot.name=hopff"], ["--set", "run.peclet=0"])


def _check_options(reference, tmp_path, capsys, system: str, options: list[list[str]],
                   case: str) -> None:
    directory = tmp_path / system
    shutil.copytree(reference(system), directory)
    before = snapshot(directory)
    argv = ["run", str(run_file(system, tmp_path)), "--out", str(directory), "--overwrite",
            "--no-progress", "--duration", "0.3", *(word for o in options for word in o)]
    case = f"{system}: {' '.join(argv[6:])} ({case})"
    code, err = _call(argv, capsys, case)
    if code == 2:  # bad input: the finished run there is kept as it was
        assert_kept(before, directory, case)
    elif code == 0:
        assert _status(directory) == "finished", case


@pytest.mark.parametrize("system", ["two", "mix"])
def test_beads_option_with_chains(reference, tmp_path, capsys, system):
    """BUG-14: ``--beads`` with a ``[[chains]]`` run file: one line, no traceback."""
    _check_options(reference, tmp_path, capsys, system, [["--beads", "40"]], "BUG-14")


@pytest.mark.parametrize("index", range(4))
def test_options_that_do_not_fit_the_system(reference, tmp_path, capsys, index):
    rng = np.random.default_rng([SEED, index])
    system = DEFAULT[index % len(DEFAULT)]
    chosen = [OPTIONS[int(i)] for i in rng.choice(len(OPTIONS), size=int(rng.integers(1, 3)),
                                                  replace=False)]
    _check_options(reference, tmp_path, capsys, system, chosen, f"case {index}, seed {SEED}")


@pytest.mark.slow
@pytest.mark.parametrize("index", range(24))
def test_options_that_do_not_fit_the_system_long(reference, tmp_path, capsys, index):
    rng = np.random.default_rng([SEED + 1, index])
    system = SLOW[index % len(SLOW)]
    chosen = [OPTIONS[int(i)] for i in rng.choice(len(OPTIONS), size=int(rng.integers(1, 4)),
                                                  replace=False)]
    _check_options(reference, tmp_path, capsys, system, chosen,
                   f"case {index}, seed {SEED + 1}")
