"""A sweep's ``seeds = K`` replicas of a point run as one replicated run (issue 33).

Where ``knotmm run`` with ``[run] replicas = K`` steps its replicas as copies of one Context,
a sweep steps the replicas of each point the same way (``knotmm.sweep.together``): each
replica is still a point of its own (directory, seed, row), and its trajectory is that of
replica k of ``knotmm run`` with the same file. The runs are tiny: 30 beads, Pe 10.
"""

from __future__ import annotations

import numpy as np
import pytest

from knotmm.config import RunConfig, read_toml
from knotmm.replicas import run_replicas
from knotmm.sweep import Sweep, run_sweep
from knotmm.sweep import together as together_module
from knotmm.sweep.together import group_tasks, point_results


def sweep_file(directory, seeds=3, **run) -> dict:
    return {
        "knot": {"beads": 30},
        "run": {"duration": 4.0, "peclet": 10.0, "seed": 7, "topology_check_interval": 0.0,
                **run},
        "output": {"directory": str(directory), "frame_interval": 0.25},
        "sweep": {"model.bending_stiffness": [3.0, 6.0], "seeds": seeds, "knot_samples": 0,
                  "plots": False},
    }


def _frames(directory):
    return np.loadtxt(directory / "observables.csv", delimiter=",", skiprows=1)


def _stepping(directory) -> str:
    return read_toml(directory / "run.toml")["knotmm"].get("replica_stepping", "")


@pytest.mark.parametrize("workers", [0, 2])
def test_a_points_replicas_are_knotmm_runs_replicas(tmp_path, workers):
    data = sweep_file(tmp_path / "sweep")
    result = run_sweep(Sweep.from_dict(data), workers=workers, progress=False)
    assert [r["status"] for r in result.rows] == ["finished"] * 6, result.report()
    # the same file as `knotmm run` with replicas = 3 (stepped together, as copies)
    cfg = RunConfig.from_dict({k: v for k, v in data.items() if k != "sweep"}).replace(
        {"model.bending_stiffness": 6.0, "run.replicas": 3})
    run_replicas(cfg, directory=tmp_path / "set", progress=False)
    for k in range(3):
        point = result.directory / f"model.bending_stiffness=6.0,replica={k}"
        assert _stepping(point) == f"together: copy {k} of 3 in one Context"
        here, there = _frames(point), _frames(tmp_path / "set" / f"replica_{k}")
        assert here.shape[0] == 17
        # the same copies, seeds and steps: the same numbers, bit for bit
        np.testing.assert_array_equal(here, there)
    assert not np.array_equal(_frames(point), _frames(point.parent / point.name.replace(
        "replica=2", "replica=1")))  # the replicas differ


def test_one_after_another_keeps_one_run_per_replica(tmp_path):
    data = sweep_file(tmp_path / "sweep", seeds=2, replica_stepping="one_after_another")
    result = run_sweep(Sweep.from_dict(data), workers=0, progress=False)
    assert [r["status"] for r in result.rows] == ["finished"] * 4, result.report()
    for row in result.rows:  # each replica's run.toml says how it ran, and why
        assert _stepping(result.directory / row["directory"]) == (
            'one after another: run.replica_stepping = "one_after_another" (each equals its '
            'single run bit for bit)')


def test_the_python_engine_runs_each_replica_alone(tmp_path):
    data = sweep_file(tmp_path / "sweep", seeds=2, engine="python")
    result = run_sweep(Sweep.from_dict(data), workers=0, progress=False)
    assert [r["status"] for r in result.rows] == ["finished"] * 4, result.report()
    for row in result.rows:
        assert _stepping(result.directory / row["directory"]) == (
            "one after another: the Python engine steps one system at a time")


def _tasks(points: int, seeds: int, action="run"):
    tasks, keys = [], {}
    for p in range(points):
        for k in range(seeds):
            name = f"p={p},replica={k}"
            tasks.append({"name": name, "action": action, "config": {}})
            keys[name] = (p,)
    return tasks, keys


@pytest.mark.parametrize(("points", "seeds", "workers", "sizes"), [
    (1, 8, 2, [4, 4]),          # one point still fills both workers
    (1, 8, 4, [2, 2, 2, 2]),
    (1, 3, 4, [3]),             # groups of two replicas or more
    (2, 3, 2, [3, 3]),
    (3, 4, None, [4, 4, 4]),    # Dask or this process: a point's replicas stay one group
    (1, 5, 3, [2, 3]),
])
def test_groups_share_the_workers_out(monkeypatch, points, seeds, workers, sizes):
    monkeypatch.setattr(together_module, "stepping_refusal", lambda cfg, count: None)
    monkeypatch.setattr(together_module.RunConfig, "from_dict", staticmethod(lambda d: d))
    tasks, keys = _tasks(points, seeds)
    grouped = group_tasks(tasks, keys, workers)
    assert all("members" in t for t in grouped)
    assert sorted(len(t["members"]) for t in grouped) == sorted(sizes)
    # every task exactly once, each group of one point only
    names = [m["name"] for t in grouped for m in t.get("members", [t])]
    assert sorted(names) == sorted(t["name"] for t in tasks)
    for t in grouped:
        assert len({keys[m["name"]] for m in t.get("members", [t])}) == 1


def test_only_runs_and_resumes_are_grouped_and_refusals_are_kept(monkeypatch):
    monkeypatch.setattr(together_module.RunConfig, "from_dict", staticmethod(lambda d: d))
    monkeypatch.setattr(together_module, "stepping_refusal", lambda cfg, count: "no")
    tasks, keys = _tasks(2, 3)
    assert group_tasks(tasks, keys, 2) == tasks  # refused: as they were
    monkeypatch.setattr(together_module, "stepping_refusal", lambda cfg, count: None)
    analyse, keys2 = _tasks(1, 3, action="analyze")
    assert group_tasks(analyse, keys2, 2) == analyse


def test_a_lost_group_gives_every_replica_its_error():
    lost = {"name": "group:a", "status": "error", "error": "the worker died", "values": {}}
    got = point_results(lost, {"group:a": ["a", "b"]})
    assert [(r["name"], r["status"], r["error"]) for r in got] == [
        ("a", "error", "the worker died"), ("b", "error", "the worker died")]
    one = {"name": "c", "status": "finished", "error": None, "values": {"x": 1}}
    assert point_results(one, {"group:a": ["a", "b"]}) == [one]
    both = {"name": "group:a", "status": "finished", "group": [one, one]}
    assert point_results(both, {}) == [one, one]


def test_a_point_resumed_keeps_its_finished_replicas_as_copies(monkeypatch):
    """One replica left to resume is still a copy among its point's others (they stay put),
    as when the point was first run: it resumes bit for bit."""
    monkeypatch.setattr(together_module.RunConfig, "from_dict", staticmethod(lambda d: d))
    asked = []
    monkeypatch.setattr(together_module, "stepping_refusal",
                        lambda cfg, count: asked.append(count))
    tasks, keys = _tasks(2, 3)
    resume = [dict(tasks[1], action="resume")]  # point 0: replica 1 to resume
    idle = [{"name": t["name"], "action": "skip"} for t in (tasks[0], tasks[2])]
    grouped = group_tasks(resume + tasks[3:], keys, 4, idle)
    groups = [t for t in grouped if "members" in t]
    assert [[m["name"] for m in g["members"]] for g in groups if "p=0" in g["name"]] == [
        ["p=0,replica=0", "p=0,replica=1", "p=0,replica=2"]]  # one group, replica order
    assert sorted(asked) == [3, 3]  # the policy asked for the point's three replicas
    fresh = [g for g in groups if "p=1" in g["name"]]  # a fresh point still shares workers
    assert sum(len(g["members"]) for g in fresh) == 3 and len(fresh) == 1  # 3 // 2 = 1 part
    names = [m["name"] for t in grouped for m in t.get("members", [t])]
    assert sorted(names) == sorted(t["name"] for t in tasks)


def test_a_stopped_sweep_resumes_to_the_uninterrupted_one_bit_for_bit(tmp_path):
    import shutil
    import threading
    import time

    from knotmm.engine.interrupt import request_stop, take_stop_request

    data = sweep_file(tmp_path / "whole", seeds=2)
    data["run"]["duration"] = 8.0
    whole = run_sweep(Sweep.from_dict(data), workers=0, progress=False)
    assert [r["status"] for r in whole.rows] == ["finished"] * 4, whole.report()

    data["output"]["directory"] = str(tmp_path / "stopped")
    sweep = Sweep.from_dict(data)
    first = tmp_path / "stopped" / "model.bending_stiffness=3.0,replica=1" / "observables.csv"

    def stop_midway():  # once the first point's replicas have written a few frames
        end = time.monotonic() + 60
        while time.monotonic() < end:
            if first.exists() and first.read_text().count("\n") > 6:
                request_stop()
                return
            time.sleep(0.005)

    stopper = threading.Thread(target=stop_midway, daemon=True)
    stopper.start()
    with pytest.raises(KeyboardInterrupt):
        run_sweep(sweep, workers=0, progress=False)
    stopper.join()
    take_stop_request()
    statuses = [read_toml(tmp_path / "stopped" / r["directory"] / "run.toml")["knotmm"]["status"]
                for r in whole.rows[:2]]
    assert statuses == ["interrupted", "interrupted"]
    # replica 0 of that point finished meanwhile (as the uninterrupted sweep's): replica 1
    # resumes as a copy beside it, which stays put
    done = whole.rows[0]["directory"]
    shutil.rmtree(tmp_path / "stopped" / done)
    shutil.copytree(tmp_path / "whole" / done, tmp_path / "stopped" / done)
    again = run_sweep(sweep, workers=0, progress=False)
    assert [r["status"] for r in again.rows] == ["finished"] * 4, again.report()
    assert (again.resumed, again.skipped) == (1, 1)
    assert _stepping(tmp_path / "stopped" / whole.rows[1]["directory"]).startswith("together")
    for row in whole.rows:
        here = _frames(tmp_path / "stopped" / row["directory"])
        there = _frames(tmp_path / "whole" / row["directory"])
        np.testing.assert_array_equal(here, there)
