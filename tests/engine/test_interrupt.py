"""A stop asked for by a signal ends a run between two steps, with a whole state."""

import os
import signal
import time

import numpy as np
import pytest

from knotmm.engine import interrupt
from knotmm.engine.interrupt import (
    StopRequested,
    describe_signal,
    raise_if_requested,
    stop_between_steps,
)
from knotmm.engine.simulation import Simulation


def stop_requested() -> bool:
    """Whether a stop is asked for and not yet taken (the module's own flag)."""
    return interrupt._requested.is_set()


def _signal_self(sig, until=stop_requested):
    """Send ``sig`` to this process and give its Python handler time to run (it runs in the
    main thread at the next check, not necessarily inside ``os.kill``)."""
    os.kill(os.getpid(), sig)
    for _ in range(200):
        if until():
            return
        time.sleep(0.005)


def test_first_signal_asks_second_stops_at_once_and_handlers_come_back(capsys):
    before = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
    with stop_between_steps():
        _signal_self(signal.SIGTERM)
        assert stop_requested()
        with pytest.raises(KeyboardInterrupt) as info:
            _signal_self(signal.SIGINT, until=lambda: False)
        assert not isinstance(info.value, StopRequested)  # a plain, immediate interrupt
    assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) == before
    assert not stop_requested()
    assert "stopping after the current step" in capsys.readouterr().err


def test_raise_if_requested_raises_once():
    raise_if_requested()  # nothing asked: nothing raised
    with stop_between_steps():
        _signal_self(signal.SIGINT)
        with pytest.raises(StopRequested):
            raise_if_requested()
        raise_if_requested()  # the request is used up


class _Frames:
    """A time-scheduled reporter keeping a copy of every frame."""

    def __init__(self, interval):
        self.interval = interval
        self.times, self.frames = [], []

    def next_report_time(self, simulation):
        return len(self.times) * self.interval

    def report(self, simulation, state):
        self.times.append(simulation.time)
        self.frames.append(simulation.positions.copy())


def test_a_stopped_simulation_goes_on_exactly_as_an_uninterrupted_one(trefoil40):
    """Stop half way between two frames; then run on: same frames, same final state."""
    reference = Simulation(trefoil40)
    ref_frames = _Frames(0.5)
    reference.reporters.append(ref_frames)
    reference.run(5.0)

    sim = Simulation(trefoil40)
    frames = _Frames(0.5)
    sim.reporters.append(frames)
    velocity = sim.velocity
    calls = []

    def velocity_that_signals(x):
        calls.append(1)
        if len(calls) == 100:  # inside a step, wherever that falls
            os.kill(os.getpid(), signal.SIGINT)
        return velocity(x)

    sim.velocity = velocity_that_signals
    with stop_between_steps(), pytest.raises(StopRequested):
        sim.run(5.0)
    stopped_at = sim.time
    assert 0.0 < stopped_at < 5.0
    assert len(frames.times) == int(stopped_at / 0.5) + 1  # every frame due so far, no more
    sim.run(5.0 - stopped_at, write_at_start=False)
    assert frames.times == ref_frames.times
    np.testing.assert_array_equal(np.array(frames.frames), np.array(ref_frames.frames))
    np.testing.assert_array_equal(sim.positions, reference.positions)
    assert sim.currentStep == reference.currentStep


def test_the_stop_names_its_signal(capsys):
    with stop_between_steps():
        _signal_self(signal.SIGTERM)
        with pytest.raises(StopRequested) as info:
            raise_if_requested()
    assert info.value.signal == "SIGTERM"
    assert "SIGTERM received: stopping after the current step" in capsys.readouterr().err
    assert describe_signal("SIGINT") == "SIGINT (Ctrl-C)"


def test_a_second_signal_stops_at_once_while_the_run_is_ending(capsys):
    """Issue 11, item 11: after the first stop was taken (StopRequested raised, the run now
    closing its files and workers), a second Ctrl-C raises at once instead of asking again."""
    with stop_between_steps():
        _signal_self(signal.SIGINT)
        with pytest.raises(StopRequested):
            raise_if_requested()
        assert not stop_requested()  # the request is used up ...
        with pytest.raises(KeyboardInterrupt) as info:
            _signal_self(signal.SIGINT, until=lambda: False)  # ... the signal still counts
        assert not isinstance(info.value, StopRequested)
    assert capsys.readouterr().err.count("stopping after the current step") == 1
