"""What ``knotmm run`` says about its knot checks (knotmm.cli.run.knot_lines, _report): every
change of knot type in order on a line before the summary, and the checks not made (the
knot worker had not started topoly when the run ended) at the end of the summary line."""

from __future__ import annotations

from types import SimpleNamespace

import pytest
import tomli_w

from knotmm.cli.main import main
from knotmm.cli.run import _report, knot_lines

NOT_STARTED = "(topoly had not started when the run ended): knotmm analyze makes"
TEMPLATE_NOTE = ("template knot type not checked: the run ended before topoly had started in "
                 "the knot worker")


@pytest.mark.parametrize("facts", [{}, {"knot_type_changes": []},
                                   {"knot_type_checks_dropped": 0, "notes": ["other"]},
                                   {"template_knot_type": "+3_1", "notes": [TEMPLATE_NOTE]}])
def test_nothing_to_say(facts):
    assert knot_lines(facts) == ["", ""]


def test_changes_in_the_order_they_happened():
    facts = {"knot_type_changes": [{"time": 30.0, "from": "+5_2", "to": "-8_20"},
                                   {"time": 100.5, "from": "-8_20", "to": "+9_24"}]}
    changes, not_made = knot_lines(facts)
    assert changes == ("knot type changed: +5_2 -> -8_20 at t = 30, "
                       "-8_20 -> +9_24 at t = 100.5 tau_d")
    assert not_made == ""
    one = {"knot_type_changes": [{"time": 2.25, "from": "+3_1", "to": "0_1"}]}
    assert knot_lines(one)[0] == "knot type changed: +3_1 -> 0_1 at t = 2.25 tau_d"


@pytest.mark.parametrize("facts, expected", [
    ({"knot_type_checks_dropped": 1}, f"1 knot-type check not made {NOT_STARTED} it"),
    ({"knot_type_checks_dropped": 3}, f"3 knot-type checks not made {NOT_STARTED} them"),
    ({"notes": [TEMPLATE_NOTE]}, f"the template's knot-type check not made {NOT_STARTED} it"),
    ({"knot_type_checks_dropped": 2, "notes": ["x", TEMPLATE_NOTE]},
     f"2 knot-type checks and the template's knot-type check not made {NOT_STARTED} them"),
    ({"knot_type_checks_dropped": 1, "notes": [TEMPLATE_NOTE]},
     f"1 knot-type check and the template's knot-type check not made {NOT_STARTED} them"),
])
def test_checks_not_made_singular_and_plural(facts, expected):
    assert knot_lines(facts) == ["", expected]


def _result(directory, facts):
    (directory / "run.toml").write_text(tomli_w.dumps({"knotmm": facts}))
    return SimpleNamespace(directory=directory, summary=lambda: "simulated 4 tau_d, in DIR")


def test_report_prints_the_changes_then_the_summary_with_the_checks_not_made(tmp_path, capsys):
    facts = {"knot_type_changes": [{"time": 3.0, "from": "+3_1", "to": "0_1"}],
             "knot_type_checks_dropped": 2}
    _report(_result(tmp_path, facts))
    out = capsys.readouterr().out.splitlines()
    assert out == ["knot type changed: +3_1 -> 0_1 at t = 3 tau_d",
                   f"simulated 4 tau_d, in DIR; 2 knot-type checks not made {NOT_STARTED} them"]


def test_report_is_the_summary_alone_without_anything_to_say_or_a_readable_run_file(tmp_path,
                                                                                    capsys):
    _report(_result(tmp_path, {"status": "finished"}))
    assert capsys.readouterr().out.splitlines() == ["simulated 4 tau_d, in DIR"]
    (tmp_path / "run.toml").write_text("[knotmm\n")  # cut short
    _report(SimpleNamespace(directory=tmp_path, summary=lambda: "simulated 4 tau_d, in DIR"))
    assert capsys.readouterr().out.splitlines() == ["simulated 4 tau_d, in DIR"]


def test_a_run_without_checks_prints_its_summary_alone(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["run", "--beads", "30", "--duration", "2", "--out", str(out), "--no-progress",
                 "--set", "run.topology_check_interval=0"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 1 and lines[0].startswith("simulated 2 tau_d"), lines
    assert "not made" not in lines[0] and str(out) in lines[0]


def test_a_stop_while_reporting_a_finished_run_is_one_line_and_no_interruption(tmp_path,
                                                                               capsys):
    def stopped():
        raise KeyboardInterrupt  # Ctrl-C after the run finished, while the summary is made

    _report(SimpleNamespace(directory=tmp_path, summary=stopped))  # returns: exit code 0
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.splitlines() == [
        f"knotmm: interrupted after the run finished: {tmp_path} is complete"]
