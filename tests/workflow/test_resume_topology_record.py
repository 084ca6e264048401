"""A resumed run's topology record equals the uninterrupted run's (issue 30, BUG-4).

run.toml's ``[knotmm]`` record of the knot-type and linking-number checks
(``knot_type_start``, ``knot_type_changes``, ``knot_type_checks``, ``template_knot_type``,
``linking_numbers``, ``linking_checks``, ``linking_number_changes``, ...) must come out the
same whether the run went through in one go or was stopped and resumed with ``--resume``:
after a kill (SIGKILL: run.toml is the one written at the start, the files run past the last
checkpoint) and after a stop asked for by a signal (SIGTERM, SIGINT: the state at the stop is
checkpointed). The record is kept in the checkpoint with the state it belongs to.

The knot case is a 30-bead trefoil at Pe = 1 (seed 3) that unties at t = 5 tau_d with the
plugin engine; the linking case is a trefoil beside a hopf link at Pe = 10 (seed 7), whose
rings B and C pass through each other at t = 20 and 30 tau_d (slow).
"""

from __future__ import annotations

import logging

import pytest

from knotmm.config import RunConfig, read_toml
from knotmm.engine.interrupt import request_stop
from knotmm.knots.identify import topoly_available
from knotmm.workflow import resume, run

#: run.toml's record of the checks, which a resumed run must share with the uninterrupted one.
RECORD = (
    "knot_type_start",
    "knot_type",
    "knot_type_changes",
    "knot_type_checks",
    "knot_type_checks_dropped",
    "template_knot_type",
    "linking_numbers",
    "linking_numbers_now",
    "linking_checks",
    "linking_number_changes",
)

#: The audit's cfg/kchange.toml, shortened, another seed: the trefoil unties at t = 4 tau_d
#: (plugin; seed 18 since the defaults of 2026-12-06, under which seed 11 did not untie).
KCHANGE = {
    "knot": {"beads": 30},
    "run": {"duration": 8.0, "peclet": 1.0, "seed": 18, "topology_check_interval": 1.0},
    "output": {"frame_interval": 0.5, "checkpoint_interval": 1.0},
}

#: The audit's cfg/bro2.toml, to t = 30, at Pe = 3, seed 19 (its Pe = 10 with the noise of
#: stepper layout 6 gave no pass before t = 30; Pe = 4, seed 14 until the Brownian defaults of
#: 2026-12-06, under which no seed of 14-75 at Pe = 4 passed as needed): a trefoil and a hopf
#: link (chains A, B-C), whose rings pass through each other (a change of a linking number
#: seen at t = 20, another at t = 30).
BRO2 = {
    "chains": [
        {"kind": "torus", "beads": 40, "offset": [-4.0, 0.0, 0.0]},
        {"kind": "knotinfo", "name": "hopf", "beads": 40, "offset": [5.0, 0.0, 0.0],
         "rotation": [0.0, 1.0, 0.0, 45.0]},
    ],
    "run": {"duration": 30.0, "peclet": 3.0, "seed": 19},
    "output": {"frame_interval": 0.25, "checkpoint_interval": 1.0},
}

#: A hopf link of 48 beads (two rings) (chains A-B, Lk 1), checked every tau_d: a fast case.
HOPF = {
    "knot": {"kind": "knotinfo", "name": "hopf", "beads": 48},
    "run": {"duration": 3.0, "peclet": 10.0, "seed": 7, "topology_check_interval": 1.0},
    "output": {"frame_interval": 0.5, "checkpoint_interval": 1.0},
}

needs_topoly = pytest.mark.skipif(not topoly_available(), reason="knot checks need topoly")


def _config(settings: dict, duration: float) -> RunConfig:
    run_table = {**settings["run"], "duration": duration}
    return RunConfig.from_dict({**settings, "run": run_table})


def _record(directory) -> dict:
    facts = read_toml(directory / "run.toml")["knotmm"]
    return {key: facts.get(key) for key in RECORD}


def _run(settings: dict, duration: float, directory) -> None:
    run(_config(settings, duration), directory=directory, progress=False, wait_for_checks=True)


def _killed(settings: dict, duration: float, directory, monkeypatch) -> None:
    """A run as SIGKILL leaves it after ``duration``: its run.toml the one written at the start
    (``status = "running"``, no record of the checks), the frames and observables past the
    last checkpoint, the checkpoint before them."""
    import knotmm.workflow as workflow

    written = []
    real = workflow.write_run_toml

    def only_first(*args, **kwargs):  # the end of the run never comes
        if not written:
            written.append(True)
            real(*args, **kwargs)

    with monkeypatch.context() as patch:
        patch.setattr(workflow, "write_run_toml", only_first)
        _run(settings, duration, directory)
    assert read_toml(directory / "run.toml")["knotmm"]["status"] == "running"


def _stopped(settings: dict, after: float, directory, monkeypatch) -> float:
    """A run stopped by a signal (SIGTERM, SIGINT) at its first frame from ``after`` on: it
    stops there, between two checkpoints, and checkpoints that state; return its time."""
    import knotmm.workflow as workflow

    class StopAfter(workflow.DCDReporter):
        def report(self, simulation, state):
            super().report(simulation, state)
            if simulation.time >= after:
                request_stop()  # what the handler of SIGINT and SIGTERM does

    with monkeypatch.context() as patch:
        patch.setattr(workflow, "DCDReporter", StopAfter)
        with pytest.raises(KeyboardInterrupt):
            _run(settings, 1e3, directory)
    facts = read_toml(directory / "run.toml")["knotmm"]
    assert facts["status"] == "interrupted"
    stopped = float(facts["time_reached"])
    assert stopped % settings["output"]["checkpoint_interval"] != 0  # not a checkpoint's time
    return stopped


class _Slow:
    """A knot identification that is not done before its result is asked for: a knot worker
    still starting (topoly's import takes seconds), so that checks are under way when a run
    is stopped (and dropped by the stopping run) or checkpointed."""

    def __init__(self, handle):
        self._handle = handle

    def done(self) -> bool:
        return False

    def result(self):
        return self._handle.result()


@pytest.fixture
def slow_worker(monkeypatch):
    """Every knot identification of the run (the template's too) is still under way until
    the run waits for it at its end."""
    import knotmm.shapes.builder as builder
    from knotmm.knots.worker import IsolatedKnotIdentifier

    submit = IsolatedKnotIdentifier.submit
    monkeypatch.setattr(IsolatedKnotIdentifier, "submit",
                        lambda self, positions: _Slow(submit(self, positions)))
    template = builder.submit_knot_check
    monkeypatch.setattr(builder, "submit_knot_check", lambda x: _Slow(template(x)))


@pytest.fixture(scope="module")
def kchange_reference(tmp_path_factory):
    directory = tmp_path_factory.mktemp("kchange") / "ref"
    _run(KCHANGE, KCHANGE["run"]["duration"], directory)
    record = _record(directory)
    # the run this test is about: the type changes before the interruptions below
    assert record["knot_type_start"] == "+3_1"
    assert [c["to"] for c in record["knot_type_changes"]] == ["0_1"]
    assert record["knot_type_changes"][0]["time"] < 6.0
    assert record["knot_type_checks"] == 8
    return record


@needs_topoly
def test_resume_after_a_kill_keeps_the_knot_type_record(tmp_path, kchange_reference,
                                                         monkeypatch, caplog):
    """SIGKILL at t = 6.5 (checkpoint at 6, after the change at 4), then --resume."""
    directory = tmp_path / "run"
    _killed(KCHANGE, 6.5, directory, monkeypatch)
    with caplog.at_level(logging.WARNING):
        resume(directory, progress=False, duration=8.0, wait_for_checks=True)
    assert "holds no record" not in caplog.text
    assert _record(directory) == kchange_reference


@needs_topoly
def test_resume_after_a_stop_keeps_the_knot_type_record(tmp_path, kchange_reference,
                                                         monkeypatch, slow_worker):
    """SIGTERM or SIGINT at t = 6.5 (after the change at 4) while every check, the start's
    included, is still under way in the knot worker; then --resume."""
    from knotmm.engine.checkpoint import read_checkpoint

    directory = tmp_path / "run"
    assert _stopped(KCHANGE, 6.5, directory, monkeypatch) == 6.5
    kept = read_checkpoint(directory / "checkpoint.npz")
    resume(directory, progress=False, duration=8.0, wait_for_checks=True)
    assert _record(directory) == kchange_reference
    # what the stop left under way was kept in its checkpoint: the start's check, the six
    # periodic ones and the template's
    record = kept["counters"].get("topology", {})
    assert record["knot"]["start_at"] == 0 and len(record["knot"]["pending"]) == 6
    assert kept["arrays"]["knot_check_positions"].shape == (7, 30, 3)
    assert record["template"]["pending"] is True  # built again and checked by the resume


@needs_topoly
def test_a_template_not_built_again_is_noted(tmp_path, monkeypatch, slow_worker, caplog):
    """The template's check was under way at the stop and the template built again is
    another shape (its file changed, ...): no knot type is made up, a note says so."""
    from knotmm.engine.checkpoint import read_checkpoint, write_checkpoint

    directory = tmp_path / "run"
    _stopped(KCHANGE, 1.5, directory, monkeypatch)
    path = directory / "checkpoint.npz"
    state = read_checkpoint(path)
    state["counters"]["topology"]["template"]["sha256"] = "another shape"
    write_checkpoint(path, state)
    with caplog.at_level(logging.WARNING):
        resume(directory, progress=False, duration=2.0, wait_for_checks=True)
    facts = read_toml(directory / "run.toml")["knotmm"]
    assert "template_knot_type" not in facts
    assert any("template knot type not checked" in note for note in facts["notes"])
    assert "cannot be built again" in caplog.text
    assert facts["knot_type_start"] == "+3_1"  # the watch's own check of the start


@needs_topoly
def test_resume_before_the_change_records_it_once(tmp_path, kchange_reference, monkeypatch,
                                                  slow_worker):
    """Killed at t = 2.5, before the change, with checks under way; resumed, stopped at
    4.5, resumed again: the record is the uninterrupted run's."""
    directory = tmp_path / "run"
    _killed(KCHANGE, 2.5, directory, monkeypatch)
    assert _record(directory)["knot_type_changes"] is None  # run.toml as at the start
    resume(directory, progress=False, duration=4.5, wait_for_checks=True)
    resume(directory, progress=False, duration=8.0, wait_for_checks=True)
    assert _record(directory) == kchange_reference


def test_an_old_checkpoint_without_the_record_resumes_from_run_toml(tmp_path, monkeypatch,
                                                                     caplog):
    """A checkpoint written before knotmm kept the record: resumed from run.toml's, with a
    warning; the linking record goes on from the numbers at the stop, not the start's."""
    from knotmm.config import load_run_file
    from knotmm.engine.checkpoint import read_checkpoint, write_checkpoint
    from knotmm.io.rundir import write_run_toml

    directory = tmp_path / "run"
    assert _stopped(HOPF, 1.5, directory, monkeypatch) == 1.5
    path = directory / "checkpoint.npz"
    state = read_checkpoint(path)
    state["counters"].pop("topology", None)  # as an older knotmm wrote it
    write_checkpoint(path, state)
    # run.toml as an older knotmm left it at the stop, after a change
    facts = read_toml(directory / "run.toml")["knotmm"]
    assert facts["linking_numbers"] == {"A-B": 1}
    facts.update(linking_numbers={"A-B": 2}, linking_numbers_now={"A-B": 1}, linking_checks=1,
                 linking_number_changes=[{"time": 1.0, "chains": "A-B", "from": 2, "to": 1}])
    write_run_toml(directory, load_run_file(directory / "run.toml"), facts)
    with caplog.at_level(logging.WARNING):
        resume(directory, progress=False, duration=3.0, wait_for_checks=True)
    record = _record(directory)
    assert record["linking_numbers"] == {"A-B": 2}
    assert record["linking_numbers_now"] == {"A-B": 1}
    # the numbers did not change since the stop: the old change is not recorded again
    assert record["linking_number_changes"] == [
        {"time": 1.0, "chains": "A-B", "from": 2, "to": 1}]
    assert record["linking_checks"] == 1 + 2  # at t = 2 and 3
    assert "holds no record of the knot-type and linking checks" in caplog.text


@pytest.fixture(scope="module")
def bro2_reference(tmp_path_factory):
    directory = tmp_path_factory.mktemp("bro2") / "ref"
    _run(BRO2, BRO2["run"]["duration"], directory)
    record = _record(directory)
    # the run this test is about: the rings pass through each other before the
    # interruptions below (at t = 20 tau_d), and again after them (at t = 30)
    times = [c["time"] for c in record["linking_number_changes"]]
    assert any(t <= 21.0 for t in times) and any(t > 26.0 for t in times), times
    return record


@pytest.mark.slow
@needs_topoly
def test_resume_after_a_kill_keeps_the_linking_record(tmp_path, bro2_reference, monkeypatch):
    """bro2 killed at t = 25.5 (checkpoint at 25, after a change), then --resume."""
    directory = tmp_path / "run"
    _killed(BRO2, 25.5, directory, monkeypatch)
    resume(directory, progress=False, duration=BRO2["run"]["duration"], wait_for_checks=True)
    assert _record(directory) == bro2_reference


@pytest.mark.slow
@needs_topoly
def test_resume_after_a_stop_keeps_the_linking_record(tmp_path, bro2_reference, monkeypatch):
    """bro2 stopped at t = 21.5, after a change: recorded once, not again after resume."""
    directory = tmp_path / "run"
    assert _stopped(BRO2, 21.5, directory, monkeypatch) == 21.5
    resume(directory, progress=False, duration=BRO2["run"]["duration"], wait_for_checks=True)
    assert _record(directory) == bro2_reference
