"""-v/--verbose and -q/--quiet: on every sub-command, before or after its name."""

from __future__ import annotations

import logging
import os
import subprocess
import sys

import pytest

from knotmm.cli.main import COMMANDS, build_parser, main


def _knotmm(*argv, cwd):
    """Run the knotmm command in a fresh interpreter (real stdout, stderr and logging)."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST")}
    return subprocess.run(
        [sys.executable, "-m", "knotmm.cli", *argv],
        cwd=cwd, env=env, capture_output=True, text=True, timeout=120,
    )


@pytest.mark.parametrize("command", COMMANDS)
def test_every_sub_command_lists_verbose_and_quiet(command, capsys):
    with pytest.raises(SystemExit) as info:
        main([command, "--help"])
    assert info.value.code == 0
    text = capsys.readouterr().out
    assert "-v, --verbose" in text and "-q, --quiet" in text


@pytest.mark.parametrize("command", COMMANDS)
@pytest.mark.parametrize("where", ["before", "after"])
@pytest.mark.parametrize("option", ["-v", "--verbose", "-q", "--quiet"])
def test_options_parse_before_or_after_the_sub_command(command, where, option):
    rest = {"run": [], "template": ["3_1"], "analyze": ["runs/x"], "orbit": ["runs/x"],
            "sweep": ["sweep.toml"], "movie": ["runs/x"]}[command]
    argv = [option, command, *rest] if where == "before" else [command, *rest, option]
    args = build_parser().parse_args(argv)
    name = option.lstrip("-")[0]
    assert getattr(args, {"v": "verbose", "q": "quiet"}[name]) is True


def test_a_sub_command_does_not_reset_options_given_before_it():
    args = build_parser().parse_args(["-v", "template", "3_1"])
    assert args.verbose is True and not hasattr(args, "quiet")


def test_verbose_and_quiet_together_is_a_usage_error(capsys):
    with pytest.raises(SystemExit) as info:
        main(["-v", "template", "3_1", "-q"])
    assert info.value.code == 2
    assert "exclude each other" in capsys.readouterr().err


def test_verbose_logs_debug_lines_and_leaves_the_log_level(caplog, capsys):
    before = logging.getLogger("knotmm").level
    with caplog.at_level(logging.DEBUG):
        assert main(["template", "3_1", "--beads", "60", "-v"]) == 0
    debug = [r for r in caplog.records
             if r.levelno == logging.DEBUG and r.name.startswith("knotmm")]
    assert len(debug) >= 3
    assert any("exit code 0" in r.getMessage() for r in debug)
    assert logging.getLogger("knotmm").level == before
    assert "writhe" in capsys.readouterr().out  # the summary is printed as without -v


def test_quiet_prints_no_summary(capsys):
    assert main(["template", "3_1", "--beads", "60", "-q"]) == 0
    assert capsys.readouterr().out == ""


def test_quiet_keeps_errors(capsys):
    assert main(["-q", "template", "torus:2,5", "--beads", "12"]) == 2
    assert capsys.readouterr().err.startswith("knotmm: error: ")


def test_quiet_run_prints_nothing_on_success(tmp_path):
    done = _knotmm("run", "--duration", "1", "--out", "r", "-q", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout == ""
    # a plugin that needs a rebuild is a warning, which -q keeps; nothing else may appear
    assert [x for x in done.stderr.splitlines() if "using the Python engine" not in x] == []
    assert (tmp_path / "r" / "trajectory.dcd").is_file()


def test_verbose_after_the_sub_command_shows_debug_lines(tmp_path):
    done = _knotmm("template", "3_1", "--beads", "60", "--verbose", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    lines = [x for x in done.stderr.splitlines() if x.startswith("knotmm: ")]
    assert len(lines) > 1 and any("exit code 0" in x for x in lines)
    assert "writhe" in done.stdout
