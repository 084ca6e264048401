"""``knotmm.engine.copies.run_together``: runs side by side in threads, stopped as one.

What it promises a replicated run and a sweep: it returns only once every run has ended,
however it is interrupted, so that every run writes its checkpoint and status; a first
interruption of the waiting thread asks the runs to stop at their next step and is waited
out, a second is raised. The runs here are plain loops standing for a simulation: each
takes "steps" of 10 ms and stops at a step boundary when a stop is asked for
(``raise_if_requested``), the first after a last step of 0.5 s (a long C++ step).
"""

from __future__ import annotations

import signal
import threading
import time

import pytest

from knotmm.engine.copies import run_together
from knotmm.engine.interrupt import StopRequested, raise_if_requested, take_stop_request


def _body(ended: dict, started: threading.Event, count: int):
    def body(k, copies):
        group, copy = copies
        assert group.count == count and 0 <= copy < count
        try:
            started.set()
            for _ in range(2000):  # 20 s if nobody stops it
                time.sleep(0.01)
                raise_if_requested()
        except StopRequested:
            if k == 0:
                time.sleep(0.5)  # its step was under way: it ends after the others
            raise
        finally:
            ended[k] = time.monotonic()
    return body


@pytest.fixture
def sigint_raises():
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    take_stop_request()
    yield
    signal.signal(signal.SIGINT, previous)
    take_stop_request()


def _interrupt_after(started: threading.Event, times: int = 1):
    def send():
        started.wait(10)
        time.sleep(0.2)
        for _ in range(times):  # to the main thread itself: its wait is what is interrupted
            signal.pthread_kill(threading.main_thread().ident, signal.SIGINT)
            time.sleep(0.05)
    threading.Thread(target=send, daemon=True).start()


def test_an_interruption_is_waited_out_until_every_run_has_ended(sigint_raises):
    ended: dict[int, float] = {}
    started = threading.Event()
    _interrupt_after(started)
    t0 = time.monotonic()
    failures = run_together(3, _body(ended, started, 3))
    back = time.monotonic()
    assert sorted(ended) == [0, 1, 2]  # every run reached its end ...
    assert all(t <= back for t in ended.values())  # ... before run_together returned
    assert back - t0 < 5.0  # stopped, not run to the end
    assert isinstance(failures[-1], KeyboardInterrupt)  # the waiting thread's interruption
    assert all(isinstance(failures[k], StopRequested) for k in range(3))


def test_a_second_interruption_is_raised(sigint_raises):
    ended: dict[int, float] = {}
    started = threading.Event()
    _interrupt_after(started, times=2)
    with pytest.raises(KeyboardInterrupt):
        run_together(2, _body(ended, started, 2))
    # raised at once, the runs still going: they end at their next step (and ask the others
    # to stop on their way out); only then is the stop request cleared for the next test
    end = time.monotonic() + 10
    while len(ended) < 2 and time.monotonic() < end:
        time.sleep(0.01)
    assert sorted(ended) == [0, 1]
    time.sleep(0.05)


def test_groups_of_at_most_max_together_one_after_another():
    seen: list[tuple[int, int, int]] = []
    lock = threading.Lock()

    def body(k, copies):
        with lock:
            seen.append((k, copies[0].count, copies[1]))

    assert run_together(5, body, max_together=2) == {}
    # three groups of sizes that differ by one at most: {0}, {1, 2}, {3, 4}
    assert sorted(seen) == [(0, 1, 0), (1, 2, 0), (2, 2, 1), (3, 2, 0), (4, 2, 1)]
