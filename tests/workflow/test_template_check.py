"""A run does not wait for topoly: the template's knot type is judged beside the run."""

from __future__ import annotations

import pytest

from knotmm.config import RunConfig, read_toml
from knotmm.errors import TemplateError
from knotmm.shapes import builder


class _Handle:
    """A knot identification under way: ``answer`` once ``ready`` is set."""

    def __init__(self, answer, ready=False):
        self.answer = answer
        self.ready = ready
        self.waited = False

    def done(self):
        return self.ready

    def result(self):
        self.waited = not self.ready
        return self.answer


def _deferred(monkeypatch, handle):
    monkeypatch.setattr(builder, "topoly_available", lambda: True)
    monkeypatch.setattr(builder, "submit_knot_check", lambda x: handle)


CFG = {"knot": {"beads": 40}, "run": {"duration": 1.0, "topology_check_interval": 0.0}}


def test_a_deferred_check_is_judged_once_the_answer_is_back(monkeypatch):
    handle = _Handle("+3_1|10_132")
    _deferred(monkeypatch, handle)
    template = builder.build_template(RunConfig.from_dict(CFG), identify="later")
    assert template.knot_type_pending and template.knot_type is None
    assert template.settle_knot_type(wait=False) == [] and template.knot_type_pending
    handle.ready = True
    template.settle_knot_type(wait=False)
    assert not template.knot_type_pending
    assert template.knot_type == "+3_1"  # the expected one of the two the polynomial allows
    assert template.facts["template_knot_type"] == "+3_1"
    assert template.description == "T(2,3), +3_1"


def test_a_deferred_check_of_the_wrong_knot_raises_the_builders_message(monkeypatch):
    _deferred(monkeypatch, _Handle("4_1", ready=True))
    template = builder.build_template(RunConfig.from_dict(CFG), identify="later")
    with pytest.raises(TemplateError, match="the template is the knot 4_1, not 3_1; use more"):
        template.settle_knot_type()


def test_a_run_stops_when_the_template_is_the_wrong_knot(monkeypatch, tmp_path):
    from knotmm.workflow import run

    handle = _Handle("4_1")
    _deferred(monkeypatch, handle)
    cfg = RunConfig.from_dict(CFG)
    handle.ready = True  # back before the first frame after t = 0
    with pytest.raises(TemplateError, match="not 3_1"):
        run(cfg, tmp_path / "r", progress=False)
    facts = read_toml(tmp_path / "r" / "run.toml")["knotmm"]
    assert facts["status"] == "fault" and "not 3_1" in facts["message"]
    assert (tmp_path / "r" / "trajectory.dcd").exists()  # what was written is kept


@pytest.mark.parametrize("worker_up", [False, True])
def test_the_end_of_a_run_waits_only_for_a_worker_that_is_up(monkeypatch, tmp_path, worker_up):
    import knotmm.engine.knot_checks
    from knotmm.workflow import run

    handle = _Handle("+3_1")
    _deferred(monkeypatch, handle)
    monkeypatch.setattr(knotmm.engine.knot_checks, "worker_ready", lambda: worker_up)
    run(RunConfig.from_dict(CFG), tmp_path / "r", progress=False)
    facts = read_toml(tmp_path / "r" / "run.toml")["knotmm"]
    assert facts["status"] == "finished"
    assert handle.waited == worker_up
    if worker_up:
        assert facts["template_knot_type"] == "+3_1"
        assert not any("not checked" in n for n in facts.get("notes", []))
    else:
        assert "template_knot_type" not in facts  # not measured: not a number
        assert any("ended before topoly had started" in n for n in facts["notes"])


def test_the_knot_watch_does_not_wait_for_a_worker_still_starting():
    from concurrent.futures import Future

    from knotmm.engine.reporters import KnotTypeWatch

    class Worker:
        ready = False

        def __init__(self):
            self.futures = []

        def submit(self, positions):
            self.futures.append(Future())  # never answered: result() would block
            return self.futures[-1]

    class Sim:
        positions = None
        time = 1.0
        currentStep = 10

    worker = Worker()
    watch = KnotTypeWatch(1.0, expected="+3_1", identify=worker, first_index=1)
    watch.report(Sim(), None)
    watch.finish()  # returns at once
    watch.close()
    assert (watch.checks, watch.dropped) == (0, 1)


def test_a_run_asked_to_stop_at_a_change_waits_for_its_checks(monkeypatch, tmp_path):
    import knotmm.engine.knot_checks
    from knotmm.workflow import run

    handle = _Handle("+3_1")
    _deferred(monkeypatch, handle)
    monkeypatch.setattr(knotmm.engine.knot_checks, "worker_ready", lambda: False)
    cfg = RunConfig.from_dict({**CFG, "run": {**CFG["run"], "on_topology_change": "stop"}})
    run(cfg, tmp_path / "r", progress=False)
    assert handle.waited  # not dropped: the user asked for the checks to be enforced
    assert read_toml(tmp_path / "r" / "run.toml")["knotmm"]["template_knot_type"] == "+3_1"
