"""Issue 30 (BUG-8): ``run.toml`` is written whole or not at all, on a full disk too."""

from __future__ import annotations

import errno
import os

import pytest

import knotmm.io.atomic
from knotmm.config import RunConfig
from knotmm.io.rundir import RUN_FILE, OutputError, write_run_toml


class FullDisk:
    """Every write finds the disk full after ``room`` bytes (the bytes before it land)."""

    def __init__(self, monkeypatch, room: int = 0):
        self.room = room
        real_write = os.write

        def write(fd, data):
            data = bytes(data)
            if len(data) > self.room:
                real_write(fd, data[: self.room])
                self.room = 0
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            self.room -= len(data)
            return real_write(fd, data)

        monkeypatch.setattr(os, "write", write)
        real_open = open

        class Capped:
            def __init__(self, fh):
                self.fh = fh

            def write(self, data):
                return write(self.fh.fileno(), data)

            def __getattr__(self, name):
                return getattr(self.fh, name)

            def __enter__(self):
                return self

            def __exit__(self, *exc):
                self.fh.close()

        def opening(file, mode="r", *args, **kwargs):
            fh = real_open(file, mode, *args, **kwargs)
            return Capped(fh) if any(c in mode for c in "wax+") else fh

        import builtins
        import io

        monkeypatch.setattr(builtins, "open", opening)
        monkeypatch.setattr(io, "open", opening)
        monkeypatch.setattr(os, "fdopen", lambda fd, mode="r", *a, **k: Capped(
            io.FileIO(fd, mode.replace("b", ""), closefd=True)))


@pytest.mark.parametrize("room", [0, 100])
def test_a_new_run_toml_on_a_full_disk_is_not_left_empty_or_cut(tmp_path, monkeypatch, room):
    cfg = RunConfig.from_dict({})
    FullDisk(monkeypatch, room)
    with pytest.raises(OutputError, match="no space left"):
        write_run_toml(tmp_path, cfg, {"status": "running"})
    monkeypatch.undo()
    assert list(tmp_path.iterdir()) == []  # not there at all (no temporary file either)


@pytest.mark.parametrize("room", [0, 100, 1000])
def test_a_run_toml_rewritten_on_a_full_disk_keeps_its_former_content(tmp_path, monkeypatch,
                                                                       room):
    cfg = RunConfig.from_dict({})
    write_run_toml(tmp_path, cfg, {"status": "running"})
    old = (tmp_path / RUN_FILE).read_bytes()
    FullDisk(monkeypatch, room)
    with pytest.raises(OutputError, match="no space left"):
        write_run_toml(tmp_path, cfg, {"status": "fault", "message": "disk full " * 200})
    monkeypatch.undo()
    assert (tmp_path / RUN_FILE).read_bytes() == old
    assert [p.name for p in tmp_path.iterdir()] == [RUN_FILE]


def test_when_only_the_temporary_copy_fails_the_file_is_kept_as_it_was(tmp_path, monkeypatch):
    cfg = RunConfig.from_dict({})
    write_run_toml(tmp_path, cfg, {"status": "running"})
    old = (tmp_path / RUN_FILE).read_bytes()

    def full(path, text):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))

    monkeypatch.setattr(knotmm.io.atomic, "write_text_atomic", full)
    with pytest.raises(OutputError, match="no space left"):
        write_run_toml(tmp_path, cfg, {"status": "fault", "message": "disk full"})
    assert (tmp_path / RUN_FILE).read_bytes() == old


@pytest.mark.parametrize("room", [0, 10])
def test_cutting_observables_back_on_a_full_disk_loses_no_row_it_keeps(tmp_path, monkeypatch,
                                                                       room):
    """A run that finds the disk full cuts observables.csv back to its counted rows: the
    rows kept must stay (the file was rewritten, emptied by the full disk)."""
    from knotmm.io.observables import truncate_csv

    path = tmp_path / "observables.csv"
    rows = [b"time,step"] + [f"{0.1 * k:g},{k}".encode() for k in range(6)]
    path.write_bytes(b"\r\n".join(rows) + b"\r\n" + b"0.6,6")  # a last row cut short
    FullDisk(monkeypatch, room)
    truncate_csv(path, 4)
    monkeypatch.undo()
    assert path.read_bytes() == b"\r\n".join(rows[:5]) + b"\r\n"
    truncate_csv(path, 4)  # a file that ends with its rows is kept as it is
    assert path.read_bytes() == b"\r\n".join(rows[:5]) + b"\r\n"
