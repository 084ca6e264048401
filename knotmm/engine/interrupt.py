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
    "describe_signal",
    "raise_if_requested",
    "request_stop",
    "stop_between_steps",
    "stop_requested",
    "stop_signal",
    "take_stop_request",
]

_requested = threading.Event()
_received: list[str] = []  # names of the signals received inside stop_between_steps


class StopRequested(KeyboardInterrupt):
    """A stop asked for by a signal, raised between two steps: the simulation state is whole.

    A subclass of ``KeyboardInterrupt``, so code that handles Ctrl-C handles it too. Its
    ``signal`` attribute names the signal (``"SIGTERM"``), or is None for
    :func:`request_stop`.
    """

    def __init__(self, signal_name: str | None = None):
        super().__init__(signal_name or "stop requested")
        self.signal = signal_name


def describe_signal(name: str | None) -> str:
    """``"SIGINT (Ctrl-C)"``, ``"SIGTERM"``; ``"a stop request"`` for None."""
    if name is None:
        return "a stop request"
    return f"{name} (Ctrl-C)" if name == "SIGINT" else name


def stop_signal() -> str | None:
    """Name of the first signal received in the current (or last) :func:`stop_between_steps`."""
    return _received[0] if _received else None


def request_stop() -> None:
    """Ask the running simulation to stop at its next step boundary (for signal handlers)."""
    _requested.set()


def stop_requested() -> bool:
    """Whether a stop has been asked for and not yet taken (the request stays)."""
    return _requested.is_set()


def take_stop_request() -> bool:
    """Whether a stop has been asked for; the request is taken (as :func:`raise_if_requested`
    takes it), for a caller that stops several runs at once (:mod:`knotmm.engine.copies`)."""
    if _requested.is_set():
        _requested.clear()
        return True
    return False


def raise_if_requested() -> None:
    """Raise :class:`StopRequested` (once) if a stop has been asked for."""
    if _requested.is_set():
        _requested.clear()
        raise StopRequested(stop_signal())


@contextmanager
def stop_between_steps(stream=None):
    """Within the block, SIGINT and SIGTERM ask for a stop at the next step boundary.

    The first signal prints one line naming it to ``stream`` (default: stderr) and sets the
    request; any later one raises ``KeyboardInterrupt`` at once, also while the run is
    already ending (closing its files and helper processes). Outside the main thread, where
    Python cannot install signal handlers, the block runs with the handlers it has.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    out = sys.stderr if stream is None else stream

    def ask(signum, frame):
        name = signal.Signals(signum).name
        _received.append(name)
        if len(_received) > 1:
            raise KeyboardInterrupt(name)
        _requested.set()
        print(
            f"knotmm: {describe_signal(name)} received: stopping after the current step "
            f"(interrupt again to stop at once)",
            file=out,
            flush=True,
        )

    signals = [signal.SIGINT, signal.SIGTERM]
    previous = {sig: signal.getsignal(sig) for sig in signals}
    _requested.clear()
    _received.clear()
    for sig in signals:
        signal.signal(sig, ask)
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)
        _requested.clear()
