"""Fuzz ``knotmm orbit`` and ``knotmm movie`` (issue 23, "Also"), as ``test_run_fuzz.py``
fuzzes ``knotmm run``, with its helpers and the same invariants:

* damaged inputs: a run directory with ``trajectory.dcd``, ``topology.pdb`` or ``run.toml``
  cut at a random byte, emptied, removed or with bytes flipped (``test_run_fuzz._damage``),
  or ``run.toml`` replaced by garbage;
* failing outputs: a read-only output place (refused before the computation, exit 2), or a
  full disk or a read-only file system while one randomly chosen file is written (ENOSPC,
  EROFS, simulated where the temporary file is made or renamed: exit 3);
* signals: SIGINT, SIGTERM, two SIGINTs or SIGKILL at a random moment of an orbit, a
  continuation or a movie.

Every case: no traceback, one line on stderr for a failure, the documented exit code (0, 2
or 3; 1 for an orbit whose Newton did not converge; 130 when stopped), and nothing
half-written under a final name (every file there is whole: JSON parses, DCDs and PDBs load,
images open). Random choices come from fixed seeds; the slow variants draw more cases.
"""

from __future__ import annotations

import errno
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest
import test_run_fuzz
from test_run_fuzz import SEED, SIGNALS, _default_sigint, _kill, _send

from knotmm.cli.main import main

ORBIT = ["--modes", "1", "--tolerance", "1e-6"]
MOVIE = ["--dpi", "20", "--stride", "20", "--no-progress"]  # the error alone on stderr
INPUTS = ("trajectory.dcd", "topology.pdb", "run.toml")
#: Files each command writes (a failure is simulated while one of them is written).
OUTPUTS = {"orbit": ("orbit.json", "topology.pdb", "orbit.dcd", "mode_1.dcd",
                     "orbit_multipliers.png"),
           "movie": ("m.gif",)}
ERRNOS = (errno.ENOSPC, errno.EROFS)


# -- fixtures -------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def swirling_run(tmp_path_factory):
    """T(2,3), N = 40, 60 tau_d: swirls from ~15 tau_d (an orbit converges from it)."""
    directory = tmp_path_factory.mktemp("fuzz_orbit") / "run"
    assert main(["run", "--beads", "40", "--duration", "60", "--out", str(directory),
                 "--set", "output.frame_interval=0.25", "--set", "run.topology_check_interval=0",
                 "--no-progress"]) == 0
    return directory


# -- helpers --------------------------------------------------------------------------------
def _cli(argv: list[str], capsys, case: str, allowed=(0, 2, 3)) -> tuple[int, str]:
    """The CLI in this process: the exit code is documented, stderr one line on failure."""
    try:
        code = main(argv)
    except BaseException as exc:  # noqa: BLE001 - the point of the test
        pytest.fail(f"{case}: knotmm {' '.join(argv)} raised {exc!r}")
    err = capsys.readouterr().err
    assert code in allowed, f"{case}: exit {code}\n{err}"
    assert "Traceback" not in err, f"{case}:\n{err}"
    if code not in (0, 1):
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("knotmm: error: "), f"{case}:\n{err}"
    return code, err


def _damage_input(directory: Path, rng: np.random.Generator, monkeypatch) -> str:
    """test_run_fuzz's damages on an orbit's or a movie's inputs, or run.toml as garbage."""
    if rng.integers(0, 5) == 0:
        junk = rng.integers(0, 256, size=int(rng.integers(1, 400)), dtype=np.uint8).tobytes()
        (directory / "run.toml").write_bytes(junk if rng.integers(0, 2)
                                             else b"[knot\nbeads = = 'x'\n" + junk)
        return "run.toml replaced by garbage"
    monkeypatch.setattr(test_run_fuzz, "TARGETS", INPUTS)
    return test_run_fuzz._damage(directory, rng)


def _whole(directory: Path, case: str) -> None:
    """Every file under a final name in ``directory`` is complete (temporaries start '.')."""
    import mdtraj
    from PIL import Image

    if not directory.exists():
        return
    for p in directory.iterdir():
        if p.name.startswith("."):
            continue
        if p.suffix == ".json":
            json.loads(p.read_text())
        elif p.suffix == ".dcd":
            n = mdtraj.load_dcd(str(p), top=str(directory / "topology.pdb")).n_frames
            assert n == 61, f"{case}: {p.name} has {n} frames"
        elif p.suffix == ".pdb":
            mdtraj.load_pdb(str(p))
        elif p.suffix in (".png", ".gif"):
            with Image.open(p) as im:
                im.seek(getattr(im, "n_frames", 1) - 1)  # reads up to the last frame
                im.load()
        elif p.suffix == ".csv":
            rows = p.read_text().splitlines()
            points = json.loads((directory / "continuation.json").read_text())["points"]
            assert len(rows) == len(points) + (1 if points else 0), case
        elif p.suffix == ".npz":
            from knotmm.orbit.output import read_branch

            read_branch(directory)


def _no_temporaries(directory: Path, case: str) -> None:
    if directory.exists():
        left = [p.name for p in directory.iterdir() if p.name.startswith(".")]
        assert not left, f"{case}: left {left}"


# -- damaged inputs -------------------------------------------------------------------------
def _check_damaged(swirling_run, tmp_path, capsys, monkeypatch, index: int, seed: int) -> None:
    rng = np.random.default_rng([seed, index])
    directory = tmp_path / f"case{index}"
    shutil.copytree(swirling_run, directory)
    case = f"case {index} (seed {seed}): {_damage_input(directory, rng, monkeypatch)}"
    out = tmp_path / "orbit"
    _cli(["movie", str(directory), "--out", str(tmp_path / "m.gif"), *MOVIE], capsys, case)
    _whole(tmp_path, case)
    _cli(["orbit", str(directory), "--modes", "0", "--tolerance", "1e-6", "--out", str(out)],
         capsys, case, allowed=(0, 1, 2, 3))
    _whole(out, case)
    _no_temporaries(out, case)


# (the seed's cases 1, 5, 10: run.toml garbage, trajectory.dcd cut, run.toml cut; the slow
# variant draws 24 more)
@pytest.mark.parametrize("index", [1, 5, 10])
def test_damaged_inputs_fail_clearly(swirling_run, tmp_path, capsys, monkeypatch, index):
    _check_damaged(swirling_run, tmp_path, capsys, monkeypatch, index, SEED)


@pytest.mark.slow
@pytest.mark.parametrize("index", range(24))
def test_damaged_inputs_fail_clearly_long(swirling_run, tmp_path, capsys, monkeypatch,
                                          index):
    _check_damaged(swirling_run, tmp_path, capsys, monkeypatch, index, SEED + 1)


# -- failing outputs ------------------------------------------------------------------------
def _fail_writing(monkeypatch, target: str, code: int, at: str) -> None:
    """Make the write of the file ``target`` fail with ``code``: when its temporary file is
    made (``at = "create"``) or renamed into place (``"rename"``); every knotmm writer
    (atomic.write_atomic, atomic.replacing, io.dcd.write_dcd) goes through both."""
    mkstemp, replace = tempfile.mkstemp, os.replace

    def failing_mkstemp(*args, prefix=None, **kwargs):
        if at == "create" and prefix == f".{target}.":
            raise OSError(code, os.strerror(code))
        return mkstemp(*args, prefix=prefix, **kwargs)

    def failing_replace(src, dst, *args, **kwargs):
        if at == "rename" and Path(dst).name == target:
            raise OSError(code, os.strerror(code), str(dst))
        return replace(src, dst, *args, **kwargs)

    monkeypatch.setattr(tempfile, "mkstemp", failing_mkstemp)
    monkeypatch.setattr(os, "replace", failing_replace)


def _read_only(monkeypatch, place: Path) -> None:
    """Nothing can be made under ``place`` (a read-only file system)."""
    mkdir, mkstemp = os.mkdir, tempfile.mkstemp

    def no_mkdir(path, *args, **kwargs):
        if str(path).startswith(str(place) + os.sep):
            raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(path))
        return mkdir(path, *args, **kwargs)

    def no_mkstemp(*args, dir=None, **kwargs):
        if dir is not None and str(dir).startswith(str(place)):
            raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(dir))
        return mkstemp(*args, dir=dir, **kwargs)

    monkeypatch.setattr(os, "mkdir", no_mkdir)
    monkeypatch.setattr(tempfile, "mkstemp", no_mkstemp)


def _check_output(swirling_run, tmp_path, capsys, monkeypatch, command: str, index: int,
                  seed: int) -> None:
    rng = np.random.default_rng([seed, index, len(command)])
    place = tmp_path / "place"
    place.mkdir()
    out = place / ("o" if command == "orbit" else "m.gif")
    argv = [command, str(swirling_run), "--out", str(out),
            *(ORBIT if command == "orbit" else MOVIE)]
    if rng.integers(0, 3) == 0:
        case = f"{command} case {index} (seed {seed}): read-only output place"
        _read_only(monkeypatch, place)
        code, err = _cli(argv, capsys, case)
        assert code == 2 and "read-only file system" in err, f"{case}: {err}"
        assert list(place.iterdir()) == [], case
        return
    target = str(rng.choice(OUTPUTS[command]))
    code_no = int(rng.choice(ERRNOS))
    at = str(rng.choice(("create", "rename")))
    case = (f"{command} case {index} (seed {seed}): {errno.errorcode[code_no]} when "
            f"{target} is {'made' if at == 'create' else 'renamed into place'}")
    _fail_writing(monkeypatch, target, code_no, at)
    code, err = _cli(argv, capsys, case)
    monkeypatch.undo()
    assert code == 3, f"{case}: exit {code}\n{err}"
    assert target in err and errno.errorcode[code_no] in err, f"{case}: {err}"
    directory = out if command == "orbit" else place
    # (an orbit directory this command made and left empty is removed again)
    assert not (directory / target).exists(), case
    _whole(directory, case)
    _no_temporaries(directory, case)


# (the seed's cases: orbit 0 read-only, orbit 4 ENOSPC renaming orbit_multipliers.png, movie 0
# read-only, movie 4 EROFS making m.gif's temporary file)
@pytest.mark.parametrize(("command", "index"), [("orbit", 0), ("orbit", 4), ("movie", 0),
                                                ("movie", 4)])
def test_failing_outputs_are_one_line(swirling_run, tmp_path, capsys, monkeypatch, command,
                                      index):
    _check_output(swirling_run, tmp_path, capsys, monkeypatch, command, index, SEED)


@pytest.mark.slow
@pytest.mark.parametrize("index", range(16))
@pytest.mark.parametrize("command", ["orbit", "movie"])
def test_failing_outputs_are_one_line_long(swirling_run, tmp_path, capsys, monkeypatch,
                                           command, index):
    _check_output(swirling_run, tmp_path, capsys, monkeypatch, command, index, SEED + 1)


# -- signals --------------------------------------------------------------------------------
def _check_signal(swirling_run, tmp_path, capsys, command: str, kind: str, index: int,
                  seed: int, longest: float) -> None:
    """Signal a ``knotmm orbit``, ``knotmm orbit --continue`` or ``knotmm movie`` child at a
    random moment, check how it ended and what it left; a continuation is then resumed to
    its end."""
    rng = np.random.default_rng([seed, index, len(command)])
    delay = float(rng.uniform(0.5, longest))
    out = tmp_path / ("m.gif" if command == "movie" else "o")
    if command == "continue":
        argv = ["orbit", str(swirling_run), "--modes", "0", "--tolerance", "1e-6",
                "--continue", "model.bending_stiffness=5:6", "--points", "3", "--out", str(out)]
    elif command == "orbit":
        argv = ["orbit", str(swirling_run), *ORBIT, "--out", str(out)]
    else:
        argv = ["movie", str(swirling_run), "--out", str(out), "--dpi", "30"]
    case = f"{command}: {kind} {delay:.2f} s after the start (case {index}, seed {seed})"
    proc = subprocess.Popen([sys.executable, "-m", "knotmm.cli", *argv],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_default_sigint)
    try:
        time.sleep(delay)
        if proc.poll() is None:
            _send(proc, kind, rng)
        _, err = proc.communicate(timeout=300)
    finally:
        _kill(proc)
    code = proc.returncode
    assert "Traceback" not in err, f"{case}:\n{err}"
    # 0: done before the signal; 130: stopped (one line); < 0: killed (SIGKILL, or a signal
    # after the command had returned, while the interpreter shut down)
    assert code in (0, 130) or code < 0, f"{case}: exit {code}\n{err}"
    if code == 130:  # one line, after the progress lines a log shows (off a terminal)
        lines = [line for line in err.strip().splitlines() if not PROGRESS_LINE.match(line)]
        assert len(lines) == 1, f"{case}:\n{err}"
        assert "knotmm run --resume" not in err, f"{case}: {err}"
    directory = out.parent if command == "movie" else out
    _whole(directory, case)
    if kind != "SIGKILL":
        _no_temporaries(directory, case)
    if command != "continue" or not (out / "continuation_state.npz").exists():
        return
    code, err = _cli([*argv, "--resume"], capsys, case)
    assert code == 0, f"{case}: {err}"
    data = json.loads((out / "continuation.json").read_text())
    assert data["complete"] and len(data["points"]) == 3, case
    _whole(out, case)


#: A progress line of a command run off a terminal (knotmm.progress.Progress).
PROGRESS_LINE = re.compile(r"knotmm: \w+: [\d.]+ / [\d.]+ \w+ \(\d+ %\)")

#: Seconds after the start within which the signal comes (the command's usual length).
LONGEST = {"continue": 10.0, "orbit": 6.0, "movie": 5.0}


# (the seed's delays: 3.8 s into the continuation, 2.5 s into the movie's rendering)
@pytest.mark.parametrize(("command", "kind", "index"), [("continue", "SIGTERM", 2),
                                                        ("movie", "SIGINT", 3)])
def test_signal_at_a_random_moment(swirling_run, tmp_path, capsys, command, kind, index):
    _check_signal(swirling_run, tmp_path, capsys, command, kind, index, SEED,
                  longest=LONGEST[command])


@pytest.mark.slow
@pytest.mark.parametrize("index", range(8))
@pytest.mark.parametrize("command", ["continue", "orbit", "movie"])
def test_signal_at_a_random_moment_long(swirling_run, tmp_path, capsys, command, index):
    _check_signal(swirling_run, tmp_path, capsys, command, SIGNALS[index % len(SIGNALS)],
                  index, SEED + 1, longest=LONGEST[command])
