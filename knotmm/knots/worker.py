"""Knot identification in a separate worker process, for checks during long runs.

topoly's polynomial code runs in the Python process and has crashed the interpreter on
some inputs (segmentation faults on symmetric projections, see :mod:`knotmm.knots.identify`). A
crash there must not take a running simulation with it, so the run's knot-type watch calls
topoly in one persistent worker process: started at the first check (about a second), then
about 40 ms a check. If the worker dies, the check reports ``None`` (not checked), a warning
is logged, and the next check starts a new worker. Where a process may not start children
(a daemonic worker of some cluster schedulers), checks run in-process.
"""

from __future__ import annotations

import logging
import multiprocessing
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures import TimeoutError as FutureTimeout
from concurrent.futures.process import BrokenProcessPool

import numpy as np

__all__ = ["IsolatedKnotIdentifier"]


class _Done:
    def __init__(self, value):
        self._value = value

    def done(self) -> bool:
        return True

    def result(self):
        return self._value


class _Pending:
    def __init__(self, owner, future):
        self._owner = owner
        self._future = future

    def done(self) -> bool:
        return self._future.done()

    def result(self):
        return self._owner._collect(self._future)

log = logging.getLogger(__name__)


def _watch_parent(parent_pid: int) -> None:
    """In the worker: exit as soon as the simulating process is gone (even after SIGKILL).

    Ctrl-C on a terminal reaches the worker too; it is ignored here, since the simulating
    process decides how a run stops (and shuts the worker down).
    """
    import os
    import signal
    import threading
    import time

    signal.signal(signal.SIGINT, signal.SIG_IGN)

    def watch():
        while True:
            time.sleep(0.5)
            if os.getppid() != parent_pid:
                os._exit(0)

    threading.Thread(target=watch, name="knotmm-parent-watch", daemon=True).start()


def _new_pool() -> ProcessPoolExecutor:
    import os

    return ProcessPoolExecutor(
        max_workers=1,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=_watch_parent,
        initargs=(os.getpid(),),
    )


def _identify(positions: np.ndarray, chiral: bool) -> str | None:
    from knotmm.knots.identify import identify_knot

    return identify_knot(positions, chiral=chiral)


class IsolatedKnotIdentifier:
    """Callable ``(positions) -> knot name or None``, evaluated in a worker process.

    Parameters
    ----------
    chiral : bool
        Name chiral knots with their handedness (``"+3_1"``).
    timeout : float
        Seconds to wait for one identification before giving up on it.
    """

    def __init__(self, chiral: bool = True, timeout: float = 300.0):
        self.chiral = chiral
        self.timeout = timeout
        self._pool: ProcessPoolExecutor | None = None
        self._in_process = multiprocessing.current_process().daemon

    def __call__(self, positions) -> str | None:
        return self.submit(positions).result()

    def submit(self, positions):
        """Start an identification and return a handle whose ``result()`` gives the name.

        The worker runs beside the simulation (on another core), so a run does not wait for
        topoly. In-process mode computes at once.
        """
        positions = np.array(positions, dtype=np.float64)
        if not self._in_process:
            try:
                if self._pool is None:
                    self._pool = _new_pool()
                return _Pending(self, self._pool.submit(_identify, positions, self.chiral))
            except BrokenProcessPool:
                log.warning("the knot-identification worker crashed; this check is skipped")
                self.close()
                return _Done(None)
            except (OSError, AssertionError) as exc:  # cannot start a child process here
                log.info("knot checks run in-process (%s)", exc)
                self._in_process = True
        return _Done(_identify(positions, self.chiral))

    def close(self) -> None:
        """Stop the worker process (it is started again when needed)."""
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None

    def _collect(self, future) -> str | None:
        try:
            return future.result(self.timeout)
        except BrokenProcessPool:
            log.warning("the knot-identification worker crashed; this check is skipped")
        except FutureTimeout:
            log.warning("knot identification took over %g s; this check is skipped",
                        self.timeout)
        self.close()
        return None

    def __del__(self):  # pragma: no cover - best effort at interpreter exit
        try:
            self.close()
        except Exception:  # noqa: BLE001
            pass
