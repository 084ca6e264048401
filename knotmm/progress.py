"""One progress display for every long command (``knotmm movie``, ``knotmm sweep``, ...).

:class:`Progress` counts work done out of a known total: a bar (tqdm) when standard error is
a terminal, else one line each time another 10 % is done or :attr:`Progress.line_seconds`
have passed since the last line (``knotmm: movie: 30 / 300 frames (10 %), 5 s, about 45 s
left``), so a log shows progress while the command runs. ``enabled=False`` (``-q``,
``--no-progress``) shows nothing, ``enabled=True`` (``--progress``) always a bar.
``knotmm run``'s :class:`knotmm.engine.reporters.ProgressReporter` shows simulated time
through it (``knotmm: t = 20 / 200 tau_d (10 %), ...``).
"""

from __future__ import annotations

import math
import sys
import time

__all__ = ["Progress"]


class Progress:
    """Progress of ``total`` units of work: a bar on a terminal, else a line every 10 %.

    Parameters
    ----------
    total : float
        Work to do (frames, points), > 0.
    what : str
        The command, e.g. ``"movie"``; the lines start ``knotmm: <what>:``.
    unit : str
        Plural name of a unit of work (``"frames"``, ``"points"``).
    enabled : bool or None
        True: always a bar; False: nothing; None: a bar on a terminal, else lines.
    initial : float
        Work already done when it starts (e.g. points skipped as finished); it counts
        towards the fraction shown.
    stream : file, optional
        Default: standard error.
    label : str, optional
        What a line shows before the count; default ``"<what>: "``.
    origin : float
        Added to the count and the total a line shows (not to the fraction): a run resumed
        at ``t = 10`` shows ``t = 12.5 / 110 tau_d (2 %)`` for 2.5 of its 100 tau_d.
    bar_format : str, optional
        tqdm's ``bar_format`` for the bar (default: tqdm's own).
    """

    #: Seconds between two progress lines, at most (when no 10 % step comes sooner).
    line_seconds = 30.0

    def __init__(self, total: float, what: str, unit: str, enabled: bool | None = None,
                 initial: float = 0.0, stream=None, *, label: str | None = None,
                 origin: float = 0.0, bar_format: str | None = None):
        self.stream = sys.stderr if stream is None else stream
        self.total = float(total)
        self.what = what
        self.unit = unit
        self.label = f"{what}: " if label is None else label
        self.origin = float(origin)
        self.done = float(initial)
        self._initial = float(initial)
        self._bar = None
        self._lines = False
        self._extra = ""
        terminal = hasattr(self.stream, "isatty") and self.stream.isatty()
        if self.total <= 0:
            return
        if enabled or (enabled is None and terminal):
            from tqdm import tqdm

            whole = self.total.is_integer() and self.done.is_integer()
            self._bar = tqdm(total=int(self.total) if whole else round(self.total, 6),
                             initial=int(self.done) if whole else self.done, desc=what or None,
                             unit=unit.rstrip("s"), file=self.stream, dynamic_ncols=True,
                             bar_format=bar_format)
        elif enabled is None:
            self._lines = True
            self._wall0 = self._last = time.monotonic()
            self._tenths = int(math.floor(10 * self.done / self.total + 1e-9))

    def update(self, amount: float = 1.0, note: str = "") -> None:
        """Count ``amount`` more units done; ``note`` (e.g. ``"1 failed"``) is shown too."""
        self._reach(min(self.total, self.done + amount), amount, note)

    def update_to(self, done: float, note: str = "") -> None:
        """Set the units done to ``done`` (at most ``total``), e.g. the simulated time so far."""
        done = min(self.total, float(done))
        self._reach(done, done - self.done, note)

    def _reach(self, done: float, amount: float, note: str) -> None:
        self.done = done
        self._extra = note
        if self._bar is not None:
            self._bar.update(amount)
            if note:
                self._bar.set_postfix_str(note)
        elif self._lines:
            self._line()

    def _line(self) -> None:
        now = time.monotonic()
        fraction = self.done / self.total
        tenths = int(math.floor(fraction * 10 + 1e-9))
        if tenths <= self._tenths and now - self._last < self.line_seconds:
            return
        self._tenths = max(self._tenths, tenths)
        self._last = now
        elapsed = now - self._wall0
        new = (self.done - self._initial) / self.total
        left = (f", about {elapsed * (1 - fraction) / new:.0f} s left"
                if 0 < new and fraction < 1 else "")
        note = f", {self._extra}" if self._extra else ""
        print(f"knotmm: {self.label}{self.origin + self.done:g} / {self.origin + self.total:g} "
              f"{self.unit} "
              f"({100 * fraction:.0f} %){note}, {elapsed:.0f} s{left}",
              file=self.stream, flush=True)

    def close(self) -> None:
        """Close the bar (lines need nothing)."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
