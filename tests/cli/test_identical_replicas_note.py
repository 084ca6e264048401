"""``knotmm run`` with ``run.replicas = K > 1`` at Pe = inf and no perturbation: one note
that the replicas are identical, in the wording ``knotmm sweep`` uses for its ensembles."""

from __future__ import annotations

import pytest

import knotmm.replicas as replicas
from knotmm.cli.main import main
from knotmm.config import RunConfig


class _Done:
    def __init__(self, directory):
        self.directory = directory
        self.errors = {}

    def summary(self):
        return "done"


@pytest.fixture
def ran(tmp_path, monkeypatch, capsys):
    """``knotmm run --set ...`` with the running stubbed out; returns stderr lines."""
    calls = []

    def fake_run(cfg, overwrite=False, progress=None):
        import sys

        print("RUNNING", file=sys.stderr)
        calls.append(cfg)
        return _Done(tmp_path / "nowhere")

    monkeypatch.setattr(replicas, "run_replicas", fake_run)

    def go(*sets):
        args = ["run", "--out", str(tmp_path / "r"), "--duration", "1", "--no-progress"]
        for s in sets:
            args += ["--set", s]
        assert main(args) == 0
        assert calls
        return capsys.readouterr().err.splitlines()

    return go


def test_identical_replicas_noted_before_running(ran):
    err = ran("run.replicas=3", "run.peclet=inf", "knot.perturbation=0")
    notes = [ln for ln in err if ln.startswith("knotmm: note:")]
    assert len(notes) == 1
    assert "run.replicas = 3" in notes[0] and "the replicas will be identical" in notes[0]
    assert err.index(notes[0]) < err.index("RUNNING")


@pytest.mark.parametrize("sets", [
    ("run.replicas=1", "run.peclet=inf", "knot.perturbation=0"),
    ("run.replicas=3", "run.peclet=inf", "knot.perturbation=0.01"),
    ("run.replicas=3", "run.peclet=10", "knot.perturbation=0"),
])
def test_no_note_when_replicas_differ(ran, sets):
    assert not [ln for ln in ran(*sets) if "identical" in ln]


def test_sweep_and_run_share_the_wording(tmp_path):
    """The sweep's note comes from the same function (one owner)."""
    from knotmm.sweep.spec import Sweep

    data = {"knot": {"beads": 40}, "run": {"duration": 10.0},
            "output": {"directory": str(tmp_path / "sweep")},
            "sweep": {"seeds": 2, "knot.beads": [40]}}
    sweep = Sweep.from_dict(data)
    note = replicas.identical_replicas_note(RunConfig.from_dict({}), 2, "seeds")
    assert note is not None and note in sweep.notes
