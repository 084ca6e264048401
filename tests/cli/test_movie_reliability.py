"""Issue 23 for ``knotmm movie`` (item 1: an unwritable place refused before rendering, a
failure while writing in one line with exit code 3, never a truncated movie under its name)
and ``knotmm analyze --frame-interval 1e300`` (item 7).

An error is one line, the last on stderr. Off a terminal a movie that fails while it renders
has printed its progress lines before it (``knotmm: movie: 2 / 5 frames (40 %), ...``, as
``knotmm run`` does: a log shows how far it got); with ``-q`` or ``--no-progress`` the error
line is all there is.
"""

from __future__ import annotations

import errno
import importlib.util
import os
import re
import subprocess
from pathlib import Path

import pytest
from workflow.test_run_directory import _mount_tmpfs  # tests/ is on sys.path (conftest.py)

from knotmm.cli.main import main

HAVE_FFMPEG = importlib.util.find_spec("imageio_ffmpeg") is not None


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """T(2,3), N = 30, 4 tau_d, 17 frames (enough for knotmm analyze)."""
    directory = tmp_path_factory.mktemp("movie_io") / "run"
    assert main(["run", "--beads", "30", "--duration", "4", "--out", str(directory),
                 "--set", "output.frame_interval=0.25", "--set", "run.topology_check_interval=0",
                 "--no-progress"]) == 0
    return directory


#: A progress line of knotmm.progress.Progress off a terminal.
PROGRESS = re.compile(r"knotmm: movie: \d+ / \d+ frames \(\d+ %\), \d+ s(, about \d+ s left)?$")


def _one_line(capsys, argv, code, rendered: bool = False) -> str:
    """The one error line of ``knotmm ARGV``; ``rendered``: progress lines may come first."""
    got = main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert got == code, err
    assert err and err[-1].startswith("knotmm: error: "), err
    before = err[:-1]
    if rendered:
        assert all(PROGRESS.match(line) for line in before), before
    else:
        assert not before, before
    return err[-1]


def _only(directory: Path) -> set[str]:
    return {p.name for p in directory.iterdir()}


@pytest.fixture
def no_rendering(monkeypatch):
    import knotmm.movie

    def refused(*args, **kwargs):
        raise AssertionError("frames were rendered before the output was checked")

    monkeypatch.setattr(knotmm.movie, "render_frames", refused)


def test_an_unwritable_place_is_refused_before_rendering(tiny_run, tmp_path, capsys,
                                                        monkeypatch, no_rendering):
    import tempfile

    ro = tmp_path / "ro"
    ro.mkdir()
    real = tempfile.mkstemp

    def mkstemp(*args, dir=None, **kwargs):  # ro/ is on a read-only file system
        if dir is not None and str(dir).startswith(str(ro)):
            raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(dir))
        return real(*args, dir=dir, **kwargs)

    monkeypatch.setattr(tempfile, "mkstemp", mkstemp)
    line = _one_line(capsys, ["movie", str(tiny_run), "--out", str(ro / "m.gif")], 2)
    assert "read-only file system" in line and str(ro) in line, line
    (tmp_path / "file").write_text("x")
    line = _one_line(capsys, ["movie", str(tiny_run), "--out", str(tmp_path / "file" / "m.gif")],
                     2)
    assert "not a directory" in line, line
    (tmp_path / "d.gif").mkdir()
    line = _one_line(capsys, ["movie", str(tiny_run), "--out", str(tmp_path / "d.gif")], 2)
    assert "is a directory" in line, line


def test_a_full_disk_while_writing_a_gif_keeps_the_old_movie(tiny_run, tmp_path, capsys,
                                                            monkeypatch):
    from PIL import Image

    out = tmp_path / "m.gif"
    assert main(["movie", str(tiny_run), "--out", str(out), "--dpi", "20", "--stride", "4"]) == 0
    before = out.read_bytes()
    save = Image.Image.save

    def full(self, fp, *args, **kwargs):
        save(self, fp, *args, **kwargs)
        with open(fp, "r+b") as fh:  # the disk filled part way through
            fh.truncate(100)
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(Image.Image, "save", full)
    capsys.readouterr()
    line = _one_line(capsys, ["movie", str(tiny_run), "--out", str(out), "--dpi", "20",
                              "--stride", "8"], 3, rendered=True)
    assert "m.gif" in line and "no space left on the device (ENOSPC)" in line, line
    assert _only(tmp_path) == {"m.gif"}  # no temporary left
    assert out.read_bytes() == before  # the earlier movie, whole


@pytest.mark.parametrize("flags", [["-q"], ["--no-progress"]])
def test_a_failure_while_writing_is_the_only_line_without_progress(tiny_run, tmp_path, capsys,
                                                                   monkeypatch, flags):
    from PIL import Image

    def full(self, fp, *args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(Image.Image, "save", full)
    out = tmp_path / "m.gif"
    line = _one_line(capsys, ["movie", str(tiny_run), "--out", str(out), "--dpi", "20",
                              "--stride", "4", *flags], 3)
    assert "m.gif" in line and "no space left" in line, line
    assert _only(tmp_path) == set()
    # the same failure off a terminal without the flags: progress lines, then the error
    _one_line(capsys, ["movie", str(tiny_run), "--out", str(out), "--dpi", "20",
                       "--stride", "4"], 3, rendered=True)
    monkeypatch.undo()
    assert main(["movie", str(tiny_run), "--out", str(out), "--dpi", "20", "--stride", "4"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err and all(PROGRESS.match(line) for line in err), err
    assert err[-1].startswith("knotmm: movie: 5 / 5 frames (100 %)"), err


@pytest.mark.skipif(not HAVE_FFMPEG, reason="imageio-ffmpeg not installed")
def test_ffmpeg_failing_on_a_full_disk_leaves_no_truncated_mp4(tiny_run, tmp_path, capsys,
                                                               monkeypatch):
    """ffmpeg dies (broken pipe) or ends quietly with the trailer unwritten (a cut file)."""
    import imageio_ffmpeg

    import knotmm.io.rundir

    real = imageio_ffmpeg.write_frames

    def dies(path, *args, **kwargs):
        Path(path).write_bytes(b"\0" * 8192)  # the 8 KB that got out
        yield
        raise BrokenPipeError(errno.EPIPE, os.strerror(errno.EPIPE))

    monkeypatch.setattr(imageio_ffmpeg, "write_frames", dies)
    monkeypatch.setattr(knotmm.io.rundir, "disk_full", lambda directory, needed=0: True,
                        raising=False)
    out = tmp_path / "m.mp4"
    line = _one_line(capsys, ["movie", str(tiny_run), "--out", str(out), "--dpi", "20",
                              "--stride", "4"], 3, rendered=True)
    assert "m.mp4" in line and "no space left" in line, line
    assert _only(tmp_path) == set()

    def quiet_ffmpeg(path, *args, **kwargs):
        inner = real(path, *args, **kwargs)
        inner.send(None)
        try:
            while True:
                inner.send((yield))
        finally:  # ffmpeg ended without an error, its trailer unwritten: the file cut short
            inner.close()
            with open(path, "r+b") as fh:
                fh.truncate(os.path.getsize(path) // 2)

    monkeypatch.setattr(imageio_ffmpeg, "write_frames", quiet_ffmpeg)
    line = _one_line(capsys, ["movie", str(tiny_run), "--out", str(out), "--dpi", "20",
                              "--stride", "4"], 3, rendered=True)
    assert "m.mp4" in line and "no space left" in line, line
    assert _only(tmp_path) == set()


@pytest.fixture
def small_disk(tmp_path):
    """A real 96 kB tmpfs (root only), unmounted after the test."""
    disk = tmp_path / "disk"
    if not _mount_tmpfs(disk, "96k"):
        pytest.skip("needs root and a mountable tmpfs")
    yield disk
    subprocess.run(["umount", str(disk)], check=True)


def test_a_real_full_disk_and_a_read_only_one(tiny_run, small_disk, capsys):
    (small_disk / "filler").write_bytes(b"\0" * 90000)  # two pages left
    for name in ("m.gif", "m.mp4") if HAVE_FFMPEG else ("m.gif",):
        line = _one_line(capsys, ["movie", str(tiny_run), "--out", str(small_disk / name),
                                  "--dpi", "40", "--stride", "4"], 3, rendered=True)
        assert name in line and "no space left" in line, line
        assert _only(small_disk) == {"filler"}
    subprocess.run(["mount", "-o", "remount,ro", str(small_disk)], check=True)
    line = _one_line(capsys, ["movie", str(tiny_run), "--out", str(small_disk / "x" / "m.gif")],
                     2)
    assert "read-only file system" in line, line


# -- item 7 ---------------------------------------------------------------------------------------
@pytest.mark.filterwarnings("error::RuntimeWarning")  # refused before any arithmetic overflows
@pytest.mark.parametrize("interval", ["1e300", "1e200", "1e-170"])
def test_analyze_with_an_absurd_frame_interval_is_one_line(tiny_run, tmp_path, capsys,
                                                          interval):
    line = _one_line(capsys, ["analyze", str(tiny_run), "--frame-interval", interval,
                              "--knot-samples", "0", "--no-plots", "--out", str(tmp_path)], 2)
    assert "frame interval" in line and f"{float(interval):g}" in line, line
