"""Who holds a run directory's lock, and a stale analysis retired when a run ends (issue 23,
item 4): :func:`knotmm.io.rundir.lock_owner`, :func:`knotmm.io.rundir.retire_stale_analysis`.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from test_rundir import _HOLDER  # a child that holds a directory's lock and waits

from knotmm.io.rundir import (
    ANALYSIS_FILE,
    LOCK_FILE,
    TRAJECTORY_FILE,
    RunLock,
    lock_owner,
    retire_stale_analysis,
)


def test_lock_owner_names_a_live_owner_only(tmp_path):
    directory = tmp_path / "run"
    assert lock_owner(directory) is None  # no directory
    directory.mkdir()
    assert lock_owner(directory) is None  # no lock file
    with RunLock(directory):
        assert lock_owner(directory) == os.getpid()
    holder = subprocess.Popen([sys.executable, "-c", _HOLDER, str(directory)],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        assert lock_owner(directory) == holder.pid
        with pytest.raises(Exception, match=f"process {holder.pid}"):
            RunLock(directory)  # the probe left the owner's lock as it was
    finally:
        holder.kill()  # SIGKILL: the lock file stays behind, with a dead pid
        holder.wait()
    assert (directory / LOCK_FILE).read_text().strip() == str(holder.pid)
    assert lock_owner(directory) is None
    with RunLock(directory):  # and the probe did not keep it either
        pass


def _analysis(directory, **extra):
    (directory / ANALYSIS_FILE).write_text(json.dumps({"n_frames": 3, "notes": [], **extra}))


def _age(path, seconds):
    st = path.stat()
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns - int(seconds * 1e9)))


def test_an_analysis_of_the_running_run_is_removed(tmp_path):
    (tmp_path / TRAJECTORY_FILE).write_bytes(b"frames")
    _analysis(tmp_path, run_still_running={"time": 1.5, "process": 123})
    _age(tmp_path / TRAJECTORY_FILE, 10)  # even when it was made after the last frame
    assert retire_stale_analysis(tmp_path) is True
    assert not (tmp_path / ANALYSIS_FILE).exists()


def test_an_analysis_older_than_the_last_frame_is_removed(tmp_path):
    _analysis(tmp_path)
    (tmp_path / TRAJECTORY_FILE).write_bytes(b"frames")
    _age(tmp_path / ANALYSIS_FILE, 10)
    assert retire_stale_analysis(tmp_path) is True
    assert not (tmp_path / ANALYSIS_FILE).exists()


def test_an_analysis_of_the_whole_run_is_kept(tmp_path):
    (tmp_path / TRAJECTORY_FILE).write_bytes(b"frames")
    _age(tmp_path / TRAJECTORY_FILE, 10)
    _analysis(tmp_path)
    assert retire_stale_analysis(tmp_path) is False
    assert (tmp_path / ANALYSIS_FILE).exists()


@pytest.mark.parametrize("content", [None, b"", b"{not json", b"\xff\xfe"])
def test_retiring_never_raises(tmp_path, content):
    (tmp_path / TRAJECTORY_FILE).write_bytes(b"frames")
    _age(tmp_path / TRAJECTORY_FILE, 10)
    if content is not None:
        (tmp_path / ANALYSIS_FILE).write_bytes(content)
    assert retire_stale_analysis(tmp_path) is False  # not an analysis of a running run
    assert retire_stale_analysis(tmp_path / "missing") is False


def test_the_shape_series_goes_with_a_retired_analysis(tmp_path):
    """``analysis_shape.csv`` belongs to the analysis it was written with: retired with it,
    kept with a current one."""
    from knotmm.io.rundir import SHAPE_FILE

    _analysis(tmp_path)
    (tmp_path / SHAPE_FILE).write_text("time,rg\n0,1\n")
    (tmp_path / TRAJECTORY_FILE).write_bytes(b"frames")
    _age(tmp_path / TRAJECTORY_FILE, 10)  # the analysis is newer than the last frame: kept
    assert retire_stale_analysis(tmp_path) is False
    assert (tmp_path / SHAPE_FILE).exists()
    _age(tmp_path / ANALYSIS_FILE, 20)  # now older than the last frame: retired, with it
    assert retire_stale_analysis(tmp_path) is True
    assert not (tmp_path / ANALYSIS_FILE).exists() and not (tmp_path / SHAPE_FILE).exists()
