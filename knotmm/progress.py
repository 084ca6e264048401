"""One progress display for every long command (``knotmm movie``, ``knotmm sweep``, ...).

:class:`Progress` counts work done out of a known total: a bar (tqdm) when standard error is
a terminal, else one line each time another 10 % is done or :attr:`Progress.line_seconds`
have passed since the last line (``knotmm: movie: 30 / 300 frames (10 %), 5 s, about 45 s
left``), so a log shows progress while the command runs. ``enabled=False`` (``-q``,
``--no-progress``) shows nothing, ``enabled=True`` (``--progress``) always a bar. These are
the rules of ``knotmm run``'s :class:`knotmm.engine.reporters.ProgressReporter`.
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
        Work already done when it starts (e.g. points skipped as finished).
    stream : file, optional
        Default: standard error.
    """

    #: Seconds between two progress lines, at most (when no 10 % step comes sooner).
    line_seconds = 30.0

    def __init__(self, total: float, what: str, unit: str, enabled: bool | None = None,
                 initial: float = 0.0, stream=None):
        self.stream = sys.stderr if stream is None else stream
        self.total = float(total)
        self.what = what
        self.unit = unit
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
            self._bar = tqdm(total=int(self.total) if whole else self.total,
                             initial=int(self.done) if whole else self.done, desc=what,
                             unit=unit.rstrip("s"), file=self.stream, dynamic_ncols=True)
        elif enabled is None:
            self._lines = True
            self._wall0 = self._last = time.monotonic()
            self._tenths = int(math.floor(10 * self.done / self.total + 1e-9))

    def update(self, amount: float = 1.0, note: str = "") -> None:
        """Count ``amount`` more units done; ``note`` (e.g. ``"1 failed"``) is shown too."""
        self.done = min(self.total, self.done + amount)
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
        print(f"knotmm: {self.what}: {self.done:g} / {self.total:g} {self.unit} "
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
