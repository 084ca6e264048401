"""``[run] replicas = K`` in a sweep file: K replicas of every point (issue 30, BUG-9).

A sweep runs ``run.replicas = K`` as its own ensemble (``seeds = K``): every point runs K
times, in ``<point>,replica=k``, each a run with ``run.replicas = 1`` and the ``run.seed`` of
replica k of ``knotmm run``; a file that also sets ``seeds`` or ``seed`` otherwise is refused
in one line. The runs are tiny: 30 beads, 4 tau_d at Pe 10, no knot-type checks, no plots.
"""

from __future__ import annotations

import numpy as np
import pytest

from knotmm.cli.main import main
from knotmm.config import RunConfig, read_toml
from knotmm.errors import ConfigError
from knotmm.replicas import replica_seeds, run_replicas
from knotmm.sweep import Sweep, read_summary, run_sweep


def replicated(directory, replicas=3, **sweep) -> dict:
    return {
        "knot": {"beads": 30},
        # no knot-type checks during the runs: these tests are about the sweep machinery
        "run": {"duration": 4.0, "peclet": 10.0, "replicas": replicas, "seed": 7,
                "topology_check_interval": 0.0},
        "output": {"directory": str(directory), "frame_interval": 0.25},
        "sweep": {"model.bending_stiffness": [3.0, 6.0], "knot_samples": 0, "plots": False,
                  **sweep},
    }


def test_run_replicas_become_the_sweeps_ensemble(tmp_path):
    sweep = Sweep.from_dict(replicated(tmp_path))
    seeds = replica_seeds(7, 3)
    assert [p.name for p in sweep.points] == [
        f"model.bending_stiffness={b},replica={k}" for b in (3.0, 6.0) for k in range(3)
    ]
    assert [p.config["run.seed"] for p in sweep.points] == seeds * 2
    assert {p.config["run.replicas"] for p in sweep.points} == {1}  # each point: one run
    assert sweep.columns == ("model.bending_stiffness", "replica", "run.seed")
    assert "run.replicas = 3" in sweep.notes[0]
    # the same points as the sweep's own ensemble key
    data = replicated(tmp_path, replicas=1, seeds=3)
    same = Sweep.from_dict(data)
    assert [(p.name, p.config) for p in same.points] == [(p.name, p.config) for p in sweep.points]
    both = Sweep.from_dict(replicated(tmp_path, seeds=3, seed=7))  # consistent: accepted
    assert [p.name for p in both.points] == [p.name for p in sweep.points]


def test_an_ensemble_of_run_replicas_alone(tmp_path):
    data = replicated(tmp_path, replicas=2)
    del data["sweep"]["model.bending_stiffness"]
    assert [p.name for p in Sweep.from_dict(data).points] == ["replica=0", "replica=1"]


@pytest.mark.parametrize(
    ("sweep", "words"),
    [
        ({"seeds": 2}, ["seeds = 2", "run.replicas = 3"]),
        ({"seed": 5}, ["seed = 5", "run.seed = 7"]),
        ({"run.seed": [1, 2]}, ["run.seed", "run.replicas = 3"]),
        ({"run.replicas": [1, 3]}, ["run.replicas", "seeds = K"]),
    ],
    ids=["other_seeds", "other_seed", "swept_seed", "swept_replicas"],
)
def test_inconsistent_ensembles_are_refused(tmp_path, sweep, words):
    with pytest.raises(ConfigError) as info:
        Sweep.from_dict(replicated(tmp_path, **sweep))
    message = str(info.value)
    assert "\n" not in message and all(w in message for w in words), message


def test_cli_refuses_both_in_one_line_and_writes_nothing(tmp_path, capsys):
    path = tmp_path / "s.toml"
    out = tmp_path / "o"
    path.write_text(
        '[knot]\nbeads = 30\n[run]\nduration = 1.0\nreplicas = 3\n[sweep]\n'
        '"model.bending_stiffness" = [3.0]\nseeds = 2\nknot_samples = 0\nplots = false\n'
    )
    assert main(["sweep", str(path), "--out", str(out), "--workers", "0"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "seeds = 2" in err and "Traceback" not in err
    assert not out.exists()


def test_dry_run_describes_the_replicas(tmp_path, capsys):
    path = tmp_path / "s.toml"
    out = tmp_path / "o"
    path.write_text(
        '[knot]\nbeads = 30\n[run]\nduration = 4.0\npeclet = 10.0\nreplicas = 3\n'
        '[sweep]\n"model.bending_stiffness" = [3.0, 6.0]\nknot_samples = 0\nplots = false\n'
    )
    assert main(["sweep", str(path), "--dry-run", "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert "6 points" in captured.out and "2 combinations x 3 replicas" in captured.out
    seed = replica_seeds(1, 3)[2]
    assert f"model.bending_stiffness=6.0,replica=2  (run.seed = {seed})" in captured.out
    assert "note: run.replicas = 3: every point runs 3 times" in captured.err
    assert not out.exists()


def test_every_replica_runs_and_records_what_it_did(tmp_path):
    data = replicated(tmp_path / "sweep", replicas=2)
    data["sweep"]["model.bending_stiffness"] = [3.0]
    sweep = Sweep.from_dict(data)
    result = run_sweep(sweep, workers=0, progress=False)
    assert [r["status"] for r in result.rows] == ["finished"] * 2, result.report()
    rows = read_summary(result.directory)
    seeds = replica_seeds(7, 2)
    assert [(r["replica"], r["run.seed"]) for r in rows] == list(enumerate(seeds))
    for k, seed in enumerate(seeds):
        stored = read_toml(result.directory / f"model.bending_stiffness=3.0,replica={k}"
                           / "run.toml")
        assert stored["run"]["replicas"] == 1 and stored["run"]["seed"] == seed
        assert stored["knotmm"]["status"] == "finished"
    again = run_sweep(sweep, workers=0, progress=False)  # continued: nothing run again
    assert (again.ran, again.skipped) == (0, 2)

    # replica k of the sweep is replica k of `knotmm run` with the same file: the same
    # seed and start; `knotmm run` steps its replicas as copies of one Context, which rounds
    # the forces otherwise (knotmm.engine.copies): equal to rounding at first; later a
    # rounding can tip an accept-or-reject of the adaptive Brownian steps, and the paths part
    cfg = RunConfig.from_dict({k: v for k, v in data.items() if k != "sweep"}).replace(
        {"model.bending_stiffness": 3.0})
    run_replicas(cfg, directory=tmp_path / "set", progress=False)
    for k in range(2):
        point = result.directory / f"model.bending_stiffness=3.0,replica={k}"
        here = np.loadtxt(point / "observables.csv", delimiter=",", skiprows=1)
        there = np.loadtxt(tmp_path / "set" / f"replica_{k}" / "observables.csv",
                           delimiter=",", skiprows=1)
        assert here.shape[0] > 10 and here.shape == there.shape
        np.testing.assert_allclose(here[:4], there[:4], rtol=1e-6, atol=1e-6)
