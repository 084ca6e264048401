"""The run directory: one owner of its file names, run.toml writing, the directory lock."""

from __future__ import annotations

import ast
import errno
import os
import re
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

import knotmm
import knotmm.io.atomic
from knotmm.config import RunConfig, read_toml
from knotmm.errors import RunDirectoryError
from knotmm.io.rundir import (
    LOCK_FILE,
    RUN_FILE,
    RUN_FILES,
    OutputError,
    RunLock,
    describe_os_error,
    prepare_directory,
    run_status,
    write_run_toml,
)

PACKAGE = Path(knotmm.__file__).parent


def _path_like_constants(tree):
    """String constants that are not docstrings and look like paths (no spaces)."""
    docstrings = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
                docstrings.add(id(body[0].value))
    for node in ast.walk(tree):
        if (isinstance(node, ast.Constant) and isinstance(node.value, str)
                and id(node) not in docstrings and not re.search(r"\s", node.value)):
            yield node


def test_only_knotmm_io_spells_the_run_file_names():
    """Every module outside knotmm/io imports the run directory's file names from it."""
    names = (*RUN_FILES, LOCK_FILE)
    offenders = []
    for path in sorted(PACKAGE.rglob("*.py")):
        if path.relative_to(PACKAGE).parts[0] == "io":
            continue
        tree = ast.parse(path.read_text(), filename=str(path))
        for node in _path_like_constants(tree):
            if any(node.value == n or node.value.endswith("/" + n) for n in names):
                offenders.append(f"{path.relative_to(PACKAGE)}:{node.lineno}: {node.value!r}")
    assert offenders == []


def test_the_name_check_sees_a_spelled_name():
    """The check above is not blind: it finds a literal in code but not in a docstring."""
    tree = ast.parse(textwrap.dedent('''
        """Writes trajectory.dcd."""
        def f(d):
            """Reads topology.pdb"""
            return d / "trajectory.dcd"
    '''))
    assert [n.value for n in _path_like_constants(tree)] == ["trajectory.dcd"]


# -- run.toml ---------------------------------------------------------------------------------
def test_run_toml_is_a_run_file_plus_facts(tmp_path):
    cfg = RunConfig.from_dict({"knot": {"beads": 40}})
    write_run_toml(tmp_path, cfg, {"status": "running", "message": None, "n_beads": 40})
    data = read_toml(tmp_path / RUN_FILE)
    assert data["knotmm"] == {"status": "running", "n_beads": 40}  # None left out
    assert RunConfig.from_dict({k: v for k, v in data.items() if k != "knotmm"}) == cfg
    assert (tmp_path / RUN_FILE).read_text().startswith("# knotmm run file")
    assert run_status(tmp_path) == "running"
    assert run_status(tmp_path / "none") is None


def test_run_toml_is_kept_whole_when_the_atomic_copy_finds_no_space(tmp_path, monkeypatch):
    """A full disk has no room for the temporary copy: run.toml stays as it was, whole
    (issue 30, BUG-8: the in-place rewrite of issue 11 could leave it empty)."""
    cfg = RunConfig.from_dict({})
    write_run_toml(tmp_path, cfg, {"status": "running"})

    def full(path, text):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))

    monkeypatch.setattr(knotmm.io.atomic, "write_text_atomic", full)
    with pytest.raises(OutputError, match="no space left"):
        write_run_toml(tmp_path, cfg, {"status": "fault", "message": "disk full"})
    assert read_toml(tmp_path / RUN_FILE)["knotmm"]["status"] == "running"
    assert sorted(p.name for p in tmp_path.iterdir()) == [RUN_FILE]


def test_os_errors_are_one_line_naming_path_and_cause():
    exc = OSError(errno.ENOSPC, "No space left on device")
    assert describe_os_error("/x/run", exc) == (
        "cannot write '/x/run': no space left on the device (ENOSPC)")
    exc = PermissionError(errno.EACCES, "Permission denied", "/x/run/run.toml")
    assert describe_os_error("/x/run", exc) == (
        "cannot write '/x/run/run.toml': permission denied (EACCES)")


# -- preparing and locking --------------------------------------------------------------------
def test_the_lock_file_is_not_content(tmp_path):
    (tmp_path / LOCK_FILE).write_text("123\n")
    prepare_directory(tmp_path, overwrite=False)  # nothing but a stale lock: fine
    (tmp_path / "notes.txt").write_text("mine")
    with pytest.raises(RunDirectoryError, match="holds no knotmm run"):
        prepare_directory(tmp_path, overwrite=False)


_HOLDER = """
import sys, time
from knotmm.io.rundir import RunLock
lock = RunLock(sys.argv[1])
print("locked", flush=True)
time.sleep(60)
"""


def test_a_live_owner_is_named_and_a_dead_ones_lock_is_taken_over(tmp_path):
    directory = tmp_path / "run"
    holder = subprocess.Popen([sys.executable, "-c", _HOLDER, str(directory)],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        assert (directory / LOCK_FILE).read_text().strip() == str(holder.pid)
        with pytest.raises(RunDirectoryError, match=rf"in use by process {holder.pid}\b"):
            RunLock(directory, "--resume")
    finally:
        holder.kill()  # SIGKILL: no clean-up; the lock file stays with a dead pid
        holder.wait()
    assert (directory / LOCK_FILE).read_text().strip() == str(holder.pid)
    deadline = time.monotonic() + 10
    while True:  # the kernel drops the lock with the process
        try:
            lock = RunLock(directory)
            break
        except RunDirectoryError:
            assert time.monotonic() < deadline
            time.sleep(0.05)
    assert (directory / LOCK_FILE).read_text().strip() == str(os.getpid())
    lock.release()
    assert not (directory / LOCK_FILE).exists()
    with RunLock(directory) as again:  # and it can be taken again
        assert again.held
    assert not (directory / LOCK_FILE).exists()


def test_the_lock_is_exclusive_within_a_process_too(tmp_path):
    with RunLock(tmp_path), pytest.raises(RunDirectoryError, match=f"process {os.getpid()}"):
        RunLock(tmp_path)


def test_a_directory_that_cannot_be_created_is_one_output_error(tmp_path):
    (tmp_path / "file").write_text("x")
    with pytest.raises(OutputError, match=r"cannot write .*file.*\((ENOTDIR|EEXIST)\)"):
        RunLock(tmp_path / "file" / "run")
