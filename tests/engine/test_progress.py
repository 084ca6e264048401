"""Progress: a line every 10 % of the run or every 30 s when the stream is not a terminal."""

from __future__ import annotations

import io
import re

import knotmm.progress as progress
from knotmm.engine.reporters import ProgressReporter


class _Clock:
    def __init__(self):
        self.now = 1000.0

    def __call__(self):
        return self.now


class _Sim:
    time = 0.0


def _drive(bar, times, clock=None, seconds_per_report=0.0):
    sim = _Sim()
    for t in times:
        sim.time = t
        if clock is not None:
            clock.now += seconds_per_report
        bar.report(sim, None)


def test_a_line_at_every_tenth_of_the_run(monkeypatch):
    monkeypatch.setattr(progress.time, "monotonic", _Clock())
    out = io.StringIO()
    bar = ProgressReporter(0.0, 20.0, 0.5, stream=out)  # StringIO: not a terminal
    _drive(bar, [0.5 * k for k in range(1, 41)])
    lines = out.getvalue().splitlines()
    percents = [int(re.search(r"\((\d+) %\)", line).group(1)) for line in lines]
    assert percents == [10, 20, 30, 40, 50, 60, 70, 80, 90, 100]
    assert lines[0].startswith("knotmm: t = 2 / 20 tau_d (10 %)")


def test_a_line_every_30_s_between_tenths(monkeypatch):
    clock = _Clock()
    monkeypatch.setattr(progress.time, "monotonic", clock)
    out = io.StringIO()
    bar = ProgressReporter(10.0, 110.0, 0.5, stream=out)  # a resumed run: from t = 10
    # 0.5 tau_d per report, 7 s per report: 30 s pass after 5 reports (2.5 % of the run)
    _drive(bar, [10.0 + 0.5 * k for k in range(1, 21)], clock, seconds_per_report=7.0)
    lines = out.getvalue().splitlines()
    assert len(lines) == 4  # at 35, 70, 105, 140 s; no tenth of the run reached yet
    assert "t = 12.5 / 110 tau_d (2 %)" in lines[0]


def test_no_lines_when_disabled_and_none_on_a_terminal_bar():
    out = io.StringIO()
    bar = ProgressReporter(0.0, 10.0, 0.5, enabled=False, stream=out)
    _drive(bar, [0.5 * k for k in range(1, 21)])
    assert out.getvalue() == ""


def test_the_run_shows_its_progress_through_the_one_display(monkeypatch):
    """Issue 31: one progress display; the run's reporter only tells it the simulated time,
    so the display's rules (its line cadence, its last line) are the run's too."""
    from knotmm.progress import Progress

    clock = _Clock()
    monkeypatch.setattr(progress.time, "monotonic", clock)
    monkeypatch.setattr(Progress, "line_seconds", 5.0)
    out = io.StringIO()
    bar = ProgressReporter(0.0, 100.0, 0.5, stream=out)
    assert isinstance(bar.progress, Progress)
    _drive(bar, [0.5 * k for k in range(1, 5)], clock, seconds_per_report=3.0)
    assert len(out.getvalue().splitlines()) == 2  # at 6 s and 12 s: every 5 s, not 30 s
    _drive(bar, [100.0], clock, seconds_per_report=3.0)
    last = out.getvalue().splitlines()[-1]
    assert last.startswith("knotmm: t = 100 / 100 tau_d (100 %)") and "left" not in last


def test_the_run_bar_on_a_terminal_counts_tau_d():
    class _Terminal(io.StringIO):
        def isatty(self):
            return True

    term = _Terminal()
    bar = ProgressReporter(10.0, 30.0, 0.5, stream=term)  # resumed at t = 10
    _drive(bar, [10.0 + 0.5 * k for k in range(1, 41)])
    bar.close()
    shown = term.getvalue()
    assert "20.0/20.0 tau_d" in shown and "100%" in shown and "knotmm: t =" not in shown
