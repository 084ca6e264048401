"""The one line of an interrupted command says how that command goes on; a sweep that could
not write its files exits 3, as knotmm run does (issue 23)."""

from __future__ import annotations

import types

import pytest

import knotmm.sweep
from knotmm.cli.main import main


@pytest.mark.parametrize(("command", "argv", "says"), [
    ("sweep", ["sweep", "x.toml"], "the same knotmm sweep command continues"),
    ("analyze", ["analyze", "somewhere"], "run knotmm analyze again"),
    ("run", ["run"], "knotmm run --resume DIR"),
])
def test_an_interrupted_command_says_how_it_goes_on(monkeypatch, capsys, command, argv, says):
    module = __import__(f"knotmm.cli.{command}", fromlist=["execute"])

    def stopped(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(module, "execute", stopped)
    assert main(argv) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and says in err[0], err


def test_a_sweep_point_that_could_not_write_its_files_exits_3(monkeypatch, tmp_path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text("[sweep]\nseeds = 2\n[run]\nduration = 1.0\n"
                    f"[output]\ndirectory = {str(tmp_path / 'sw')!r}\n")
    rows = [{"point": "replica=0", "status": "finished", "error": None},
            {"point": "replica=1", "status": "error",
             "error": "OutputError: cannot write 'sw/replica=1/trajectory.dcd': no space left"}]
    result = types.SimpleNamespace(failed=rows[1:], report=lambda: "sweep: 2 points")
    monkeypatch.setattr(knotmm.sweep, "run_sweep", lambda *a, **k: result)
    assert main(["sweep", str(spec), "--no-progress"]) == 3
    rows[1]["error"] = "SimulationFault: the step is too large"
    assert main(["sweep", str(spec), "--no-progress"]) == 1
