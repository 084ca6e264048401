"""One progress behaviour for the long commands (knotmm.progress; issue 24, item 2).

Off a terminal a line every 10 % of the work, on a terminal a bar, nothing with
``--no-progress`` or ``-q``: for ``knotmm movie`` and ``knotmm sweep`` as for ``knotmm run``.
"""

from __future__ import annotations

import io
import re

import pytest

from knotmm.cli.main import main
from knotmm.progress import Progress


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def test_lines_every_tenth_off_a_terminal():
    out = io.StringIO()
    shown = Progress(20, "movie", "frames", stream=out)
    for _ in range(20):
        shown.update(1)
    shown.close()
    lines = out.getvalue().splitlines()
    # 20 frames: one line at each 10 % (every second frame), none in between
    assert len(lines) == 10
    assert lines[0].startswith("knotmm: movie: 2 / 20 frames (10 %), ")
    assert lines[-1].startswith("knotmm: movie: 20 / 20 frames (100 %), ")


def test_a_line_after_line_seconds_even_without_a_new_tenth(monkeypatch):
    clock = iter([0.0, 0.0, 100.0, 100.0])
    monkeypatch.setattr("knotmm.progress.time.monotonic", lambda: next(clock))
    out = io.StringIO()
    shown = Progress(1000, "sweep", "points", stream=out)
    shown.update(1)  # 0.1 %: too early
    shown.update(1)  # 100 s later: a line anyway
    assert out.getvalue().splitlines() == [
        "knotmm: sweep: 2 / 1000 points (0 %), 100 s, about 49900 s left"]


def test_bar_on_a_terminal_and_nothing_when_disabled():
    term = _Terminal()
    with Progress(5, "movie", "frames", stream=term) as shown:
        for _ in range(5):
            shown.update(1)
    assert "5/5" in term.getvalue() and "knotmm: movie:" not in term.getvalue()
    quiet = _Terminal()
    with Progress(5, "movie", "frames", enabled=False, stream=quiet) as shown:
        shown.update(5)
    assert quiet.getvalue() == ""


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("progress_all") / "run"
    assert main(["run", "--beads", "30", "--duration", "2", "--out", str(out),
                 "--set", "run.topology_check_interval=0", "--no-progress"]) == 0
    return out


def test_movie_writes_progress_lines_off_a_terminal(short_run, tmp_path, capsys):
    capsys.readouterr()
    assert main(["movie", str(short_run), "--out", str(tmp_path / "m.gif"), "--dpi", "20"]) == 0
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.startswith("knotmm: movie: ")]
    n = int(re.match(r"knotmm: movie: (\d+) / \1 frames \(100 %\)", lines[-1]).group(1))
    assert len(lines) == min(n, 10), err  # one a frame, or one each 10 %


@pytest.mark.parametrize("flags", [["--no-progress"], ["-q"]])
def test_movie_progress_off(short_run, tmp_path, capsys, flags):
    capsys.readouterr()
    assert main(["movie", str(short_run), "--out", str(tmp_path / "m.gif"), "--dpi", "20",
                 *flags]) == 0
    assert "knotmm: movie: " not in capsys.readouterr().err


def test_sweep_writes_a_line_per_point_off_a_terminal(tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_text(
        "[run]\nduration = 9.0\ntopology_check_interval = 0.0\n[output]\n"
        f"frame_interval = 0.5\ndirectory = \"{(tmp_path / 'out').as_posix()}\"\n"
        '[sweep]\n"knot.beads" = [30, 36]\nknot_samples = 0\nplots = false\n')
    capsys.readouterr()
    assert main(["sweep", str(path), "--workers", "0"]) == 0
    lines = [ln for ln in capsys.readouterr().err.splitlines()
             if ln.startswith("knotmm: sweep: ")]
    assert [ln.split(" (")[0] for ln in lines] == ["knotmm: sweep: 1 / 2 points",
                                                   "knotmm: sweep: 2 / 2 points"]
