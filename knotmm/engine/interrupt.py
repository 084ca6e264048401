"""Stop a run between two steps on Ctrl-C or SIGTERM, so that its exact state can be saved.

Python raises ``KeyboardInterrupt`` wherever the program happens to be, which may be half
way through a step or a frame being written; a run stopped that way can only resume from its
last periodic checkpoint. Inside :func:`stop_between_steps` the first SIGINT or SIGTERM only
asks for a stop: :class:`~knotmm.engine.simulation.Simulation` finishes the step it is taking,
reports what is due, and raises :class:`StopRequested` at the next step boundary, where the
runner writes a checkpoint of that exact state. A second signal stops at once (a plain
``KeyboardInterrupt``), for a step that would take too long.

``knotmm run`` uses it; from Python::

    from knotmm.engine.interrupt import stop_between_steps
    from knotmm.workflow import run

    with stop_between_steps():
        run(config)
"""

from __future__ import annotations

import signal
import sys
import threading
from contextlib import contextmanager

__all__ = [
    "StopRequested",
    "raise_if_requested",
    "request_stop",
    "stop_between_steps",
    "stop_requested",
]

_requested = threading.Event()


class StopRequested(KeyboardInterrupt):
    """A stop asked for by a signal, raised between two steps: the simulation state is whole.

    A subclass of ``KeyboardInterrupt``, so code that handles Ctrl-C handles it too.
    """


def stop_requested() -> bool:
    """Whether a signal has asked the running simulation to stop at its next step boundary."""
    return _requested.is_set()


def request_stop() -> None:
    """Ask the running simulation to stop at its next step boundary (for signal handlers)."""
    _requested.set()


def raise_if_requested() -> None:
    """Raise :class:`StopRequested` (once) if a stop has been asked for."""
    if _requested.is_set():
        _requested.clear()
        raise StopRequested


@contextmanager
def stop_between_steps(stream=None):
    """Within the block, SIGINT and SIGTERM ask for a stop at the next step boundary.

    The first signal prints one line to ``stream`` (default: stderr) and sets the request;
    a second one raises ``KeyboardInterrupt`` at once. Outside the main thread, where Python
    cannot install signal handlers, the block runs with the handlers it has.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    out = sys.stderr if stream is None else stream

    def ask(signum, frame):
        if _requested.is_set():
            raise KeyboardInterrupt
        _requested.set()
        print(
            "knotmm: stopping after the current step (interrupt again to stop at once)",
            file=out,
            flush=True,
        )

    signals = [signal.SIGINT, signal.SIGTERM]
    previous = {sig: signal.getsignal(sig) for sig in signals}
    _requested.clear()
    for sig in signals:
        signal.signal(sig, ask)
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)
        _requested.clear()
