"""Replicas of a run in one process: each equals the single run with its recorded seed, a
breakdown of one leaves the others, an interrupted set resumes, the set is analysed."""

from __future__ import annotations

import json

import mdtraj
import numpy as np
import pytest

import knotmm.plugin as kp
import knotmm.replicas as replicas
from knotmm.analysis.replicas import analyze_sweep
from knotmm.cli.main import main
from knotmm.config import RunConfig
from knotmm.engine.engines import DEVICE_PLATFORMS, plugin_platforms
from knotmm.errors import SimulationFault
from knotmm.io.replica_set import read_replica_set
from knotmm.io.rundir import read_facts
from knotmm.replicas import replica_seeds, resume_replicas, run_replicas
from knotmm.workflow import run

_PLATFORMS = plugin_platforms() if kp.available() else ()

BROWNIAN = {
    "knot": {"beads": 30, "minor_radius": 0.6},
    "model": {"gravity": 1.0},
    "run": {"duration": 1.0, "peclet": 10.0, "integrator": "ito_heun", "timestep": 0.002,
            "topology_check_interval": 0.0, "replicas": 3, "seed": 11},
    "output": {"frame_interval": 0.05},
}


def _xyz(directory):
    return mdtraj.load(str(directory / "trajectory.dcd"), top=str(directory / "topology.pdb")).xyz


def test_seeds_are_spawned_from_run_seed_and_keep_when_replicas_are_added():
    want = [int(np.random.SeedSequence(11, spawn_key=(k,)).generate_state(1, np.uint32)[0])
            for k in range(5)]
    assert replica_seeds(11, 5) == want
    assert replica_seeds(11, 3) == want[:3]
    assert len(set(want)) == 5


@pytest.fixture(scope="module")
def brownian_set(tmp_path_factory):
    root = tmp_path_factory.mktemp("set") / "set"
    result = run_replicas(RunConfig.from_dict(BROWNIAN), directory=root, progress=False)
    return root, result


def test_fixed_step_brownian_replicas_equal_single_runs_with_their_seeds(brownian_set,
                                                                          tmp_path):
    # Stepped together (copies of one Context) the replicas equal the single runs within
    # rounding: a copy's forces are evaluated at its place in the shared Context, in the CPU
    # platform's single-precision positions; 500 noisy steps carry that to about 1e-7 d.
    root, result = brownian_set
    assert result.count == 3 and not result.errors
    record = read_replica_set(root)
    assert record["replicas"]["stepping"] == "together"
    seeds = record["replicas"]["seeds"]
    assert seeds == replica_seeds(11, 3)
    frames = []
    for k, seed in enumerate(seeds):
        facts = read_facts(root / f"replica_{k}")
        assert facts["status"] == "finished"
        single = tmp_path / f"single_{k}"
        cfg = RunConfig.from_dict({**BROWNIAN, "run": {**BROWNIAN["run"], "replicas": 1,
                                                       "seed": seed}})
        run(cfg, directory=single, progress=False)
        assert facts["replica_stepping"] == f"together: copy {k} of 3 in one Context"
        np.testing.assert_allclose(_xyz(root / f"replica_{k}"), _xyz(single), rtol=0, atol=1e-5)
        frames.append(_xyz(single))
    # the noise differs between replicas, far beyond that tolerance
    assert np.abs(frames[0] - frames[1]).max() > 0.1
    assert "+-" in result.summary() and "3 replicas" in result.summary()


def test_one_after_another_replicas_equal_single_runs_bit_for_bit(tmp_path):
    # one after another (asked for), each replica is a single run of its own, bit for bit,
    # and the set's record says why
    cfg = RunConfig.from_dict({**BROWNIAN, "run": {**BROWNIAN["run"], "duration": 0.2,
                                                   "replicas": 2,
                                                   "replica_stepping": "one_after_another"}})
    run_replicas(cfg, directory=tmp_path / "set", progress=False)
    record = read_replica_set(tmp_path / "set")["replicas"]
    assert record["stepping"] == "one after another"
    assert "run.replica_stepping" in record["stepping_reason"]
    seed = record["seeds"][1]
    single = tmp_path / "single"
    run(RunConfig.from_dict({**BROWNIAN, "run": {**BROWNIAN["run"], "duration": 0.2,
                                                 "replicas": 1, "seed": seed,
                                                 "replica_stepping": "one_after_another"}}),
        directory=single, progress=False)
    np.testing.assert_array_equal(_xyz(tmp_path / "set" / "replica_1"), _xyz(single))
    stepping = read_facts(tmp_path / "set" / "replica_1")["replica_stepping"]
    assert stepping == f"one after another: {record['stepping_reason']}"
    assert "replica_stepping" not in read_facts(single)  # a run alone says nothing


@pytest.mark.parametrize("platform", [p for p in DEVICE_PLATFORMS if p in _PLATFORMS] or [
    pytest.param("OpenCL", marks=pytest.mark.skip(reason="no device platform with the plugin"))])
def test_replicas_on_a_device_platform_equal_single_runs_with_their_seeds(tmp_path, platform):
    # the device backend's copies (CommonRPYBatch): each replica follows its single run on
    # that platform, in double precision, to the trajectory file's float32 rounding
    run_keys = {**BROWNIAN["run"], "duration": 0.4, "platform": platform,
                "precision": "double"}
    root = tmp_path / "set"
    result = run_replicas(RunConfig.from_dict({**BROWNIAN, "run": run_keys}), directory=root,
                          progress=False)
    assert not result.errors
    record = read_replica_set(root)["replicas"]
    assert record["stepping"] == "together"
    for k, seed in enumerate(record["seeds"]):
        single = tmp_path / f"single_{k}"
        run(RunConfig.from_dict({**BROWNIAN, "run": {**run_keys, "replicas": 1, "seed": seed}}),
            directory=single, progress=False)
        assert read_facts(root / f"replica_{k}")["replica_stepping"] == (
            f"together: copy {k} of 3 in one Context")
        np.testing.assert_allclose(_xyz(root / f"replica_{k}"), _xyz(single), rtol=0,
                                   atol=2e-6)


def test_auto_steps_together_on_a_device_at_every_size():
    from knotmm.engine.copies import copies_refusal

    # the host's measured limits (79 Brownian beads) do not apply on a device platform
    assert "79 beads" in copies_refusal("plugin", "CPU", 8, "auto", 90, brownian=True)
    for platform in ("OpenCL", "CUDA"):
        assert copies_refusal("plugin", platform, 8, "auto", 5000, brownian=True) is None
        assert "one_after_another" in copies_refusal("plugin", platform, 8, "one_after_another",
                                                     90)
    assert "HIP" in copies_refusal("plugin", "HIP", 8, "auto", 30)


@pytest.mark.parametrize(("stepping", "together"), [("auto", False), ("together", True)])
def test_auto_steps_together_only_where_measured_faster(tmp_path, stepping, together):
    # Brownian replicas of 90 beads: one after another was measured faster (auto), unless
    # asked for
    cfg = RunConfig.from_dict({**BROWNIAN, "knot": {"beads": 90},
                               "run": {**BROWNIAN["run"], "duration": 0.05, "replicas": 2,
                                       "replica_stepping": stepping}})
    run_replicas(cfg, directory=tmp_path / "set", progress=False)
    record = read_replica_set(tmp_path / "set")["replicas"]
    assert (record["stepping"] == "together") == together
    if not together:
        assert "measured faster one after another" in record["stepping_reason"]
        assert "79 beads" in record["stepping_reason"]
        for k in range(2):  # and each replica's run.toml says so
            facts = read_facts(tmp_path / "set" / f"replica_{k}")
            assert facts["replica_stepping"].startswith("one after another: measured faster")


def test_a_large_set_steps_in_groups_one_after_another(tmp_path, monkeypatch, brownian_set):
    # at most MAX_TOGETHER replicas share a Context; the replicas are the same runs
    monkeypatch.setattr(replicas, "MAX_TOGETHER", 2)
    root = tmp_path / "set"
    cfg = RunConfig.from_dict({**BROWNIAN, "run": {**BROWNIAN["run"], "replicas": 4}})
    result = run_replicas(cfg, directory=root, progress=False)
    assert not result.errors
    stepping = [read_facts(root / f"replica_{k}")["replica_stepping"] for k in range(4)]
    assert stepping == [f"together: copy {k % 2} of 2 in one Context" for k in range(4)]
    # a copy's forces are its own: replica k (k < 3, the same seed in a set of 3 or 4) takes
    # the same trajectory in a group of 2 as in the set of 3
    for k in range(3):
        np.testing.assert_array_equal(_xyz(root / f"replica_{k}"),
                                      _xyz(brownian_set[0] / f"replica_{k}"))


def test_the_set_is_analysed_as_one_point(brownian_set):
    root, _ = brownian_set
    out = analyze_sweep(root, plots=False, knot_samples=0)
    stats = out["points"]["all"]["statistics"]["sedimentation_velocity"]
    assert stats["n"] == 3 and stats["std_error"] > 0
    values = [json.loads((root / f"replica_{k}" / "analysis.json").read_text())
              ["sedimentation_velocity"] for k in range(3)]
    assert stats["mean"] == pytest.approx(np.mean(values), rel=1e-12)
    assert stats["std_error"] == pytest.approx(np.std(values, ddof=1) / np.sqrt(3), rel=1e-9)


@pytest.mark.parametrize("stepping", [
    {}, {"replica_stepping": "one_after_another", "replicas_at_once": 1},
    {"replica_stepping": "one_after_another", "replicas_at_once": 2}])
def test_a_breakdown_of_one_replica_is_recorded_and_the_others_go_on(tmp_path, monkeypatch,
                                                                      stepping):
    real = replicas.run

    def flaky(cfg, directory, **kwargs):
        if directory.name == "replica_1":
            raise SimulationFault("the step is too large for the forces (a test fault)")
        return real(cfg, directory=directory, **kwargs)

    monkeypatch.setattr(replicas, "run", flaky)
    cfg = RunConfig.from_dict({**BROWNIAN, "run": {**BROWNIAN["run"], "duration": 0.5,
                                                   **stepping}})
    result = run_replicas(cfg, directory=tmp_path / "s", progress=False)
    assert list(result.errors) == [1] and "a test fault" in result.errors[1]
    assert result.results[1] is None and result.results[0] and result.results[2]
    assert "1 broke down (1)" in result.summary()


def test_a_copy_that_fails_takes_its_stretch_alone_and_the_others_are_untouched(
        tmp_path, monkeypatch, brownian_set, caplog):
    # the third stretch of replica 1 is handed to its copy with two beads on one point: the
    # copy's step fails (no Cholesky factor there), the replica takes that stretch again
    # alone from its own good state, and no other copy notices
    import knotmm.plugin as plugin

    real = plugin.RPYIntegrator.setCopyPositions
    calls = {"n": 0}

    def broken_once(self, copy, positions):
        if copy == 1:
            calls["n"] += 1
            if calls["n"] == 3:
                positions = list(positions)
                positions[3:6] = positions[0:3]
        return real(self, copy, positions)

    monkeypatch.setattr(plugin.RPYIntegrator, "setCopyPositions", broken_once)
    root = tmp_path / "set"
    with caplog.at_level("INFO", logger="knotmm.engine.copies"):
        result = run_replicas(RunConfig.from_dict(BROWNIAN), directory=root, progress=False)
    assert not result.errors and calls["n"] > 3
    assert any("replica 1: its copy stopped" in r.getMessage() and "alone" in r.getMessage()
               for r in caplog.records)
    reference = brownian_set[0]
    for k in (0, 2):
        np.testing.assert_array_equal(_xyz(root / f"replica_{k}"),
                                      _xyz(reference / f"replica_{k}"))
    # replica 1 took one stretch on its own Context (NonbondedForce): equal to rounding
    np.testing.assert_allclose(_xyz(root / "replica_1"), _xyz(reference / "replica_1"),
                               rtol=0, atol=1e-5)


def test_a_copy_whose_bonds_run_away_takes_its_stretch_alone(tmp_path, monkeypatch,
                                                             brownian_set):
    # the checks of a run alone (finite positions, bonds within run.max_bond_length) hold
    # for what a copy reached: here copy 2 hands back, once, a bond stretched to 10 d
    import knotmm.plugin as plugin

    real = plugin.RPYIntegrator.getCopyPositions
    calls = {"n": 0}

    def stretched_once(self, copy):
        positions = real(self, copy)
        if copy == 2:
            calls["n"] += 1
            if calls["n"] == 4:
                positions = list(positions)
                positions[0] += 10.0
        return positions

    monkeypatch.setattr(plugin.RPYIntegrator, "getCopyPositions", stretched_once)
    from knotmm.engine.plugin_engine import PluginEngine

    alone = []
    real_alone = PluginEngine._advance_within

    def counted(self, sim, target):
        alone.append(self.copy_index)
        return real_alone(self, sim, target)

    monkeypatch.setattr(PluginEngine, "_advance_within", counted)
    root = tmp_path / "set"
    result = run_replicas(RunConfig.from_dict(BROWNIAN), directory=root, progress=False)
    assert not result.errors and calls["n"] > 4
    assert alone and set(alone) == {2}  # that stretch, and no other, was taken alone
    assert read_facts(root / "replica_2")["final_max_bond"] < 3.0
    ours, theirs = _xyz(root / "replica_2"), _xyz(brownian_set[0] / "replica_2")
    np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-5)


def test_copies_that_cannot_be_built_leave_every_replica_to_run_alone(tmp_path, monkeypatch,
                                                                     brownian_set):
    import knotmm.model.system as system

    def no_room(*args, **kwargs):
        raise MemoryError("no room for the copies (a test)")

    monkeypatch.setattr(system, "copies_system", no_room)
    root = tmp_path / "set"
    result = run_replicas(RunConfig.from_dict(BROWNIAN), directory=root, progress=False)
    assert not result.errors
    for k in range(3):
        facts = read_facts(root / f"replica_{k}")
        assert facts["status"] == "finished"
        assert facts["replica_stepping"].startswith("alone: the copies could not be stepped")
        assert "no room for the copies" in facts["replica_stepping"]
        # alone, each is its single run: equal to the copies' trajectories to rounding
        np.testing.assert_allclose(_xyz(root / f"replica_{k}"),
                                   _xyz(brownian_set[0] / f"replica_{k}"), rtol=0, atol=1e-5)


def test_an_interrupted_set_resumes_to_the_same_trajectories(tmp_path, monkeypatch,
                                                             brownian_set):
    root_ref, _ = brownian_set
    real = replicas.run

    def interrupted(cfg, directory, **kwargs):
        if directory.name == "replica_2":
            raise KeyboardInterrupt
        return real(cfg, directory=directory, **kwargs)

    monkeypatch.setattr(replicas, "run", interrupted)
    root = tmp_path / "s"
    with pytest.raises(KeyboardInterrupt):
        run_replicas(RunConfig.from_dict(BROWNIAN), directory=root, progress=False)
    monkeypatch.setattr(replicas, "run", real)
    result = resume_replicas(root, progress=False)
    assert not result.errors and all(r is not None for r in result.results)
    # replicas 0 and 1 ran beside each other, replica 2 later beside copies that no longer
    # moved: on the CPU platform a copy's forces round with where the other copies are
    # (single-precision positions, one neighbour list), so the set agrees to rounding
    for k in range(3):
        np.testing.assert_allclose(_xyz(root / f"replica_{k}"),
                                   _xyz(root_ref / f"replica_{k}"), rtol=0, atol=1e-5)
    # extending the set extends every replica
    longer = resume_replicas(root, progress=False, duration=1.5)
    assert all(r.time == pytest.approx(1.5) for r in longer.results)


def test_bad_replica_counts_and_occupied_directories_are_one_line(tmp_path, capsys,
                                                                  brownian_set):
    path = tmp_path / "r.toml"
    path.write_text(f"[run]\nreplicas = 0\n[output]\ndirectory = {str(tmp_path / 'o')!r}\n")
    assert main(["run", str(path), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "run.replicas" in err[0], err
    root, _ = brownian_set
    with pytest.raises(Exception, match="already holds a replica set"):
        run_replicas(RunConfig.from_dict(BROWNIAN), directory=root, progress=False)


def test_the_command_line_runs_and_resumes_a_set(tmp_path, capsys):
    out = tmp_path / "cli"
    argv = ["run", "--out", str(out), "--beads", "30", "--duration", "0.5", "--no-progress",
            "--set", "run.replicas=2", "--set", "run.topology_check_interval=0",
            "--set", "run.replicas_at_once=2"]
    assert main(argv) == 0
    line = capsys.readouterr().out.strip().splitlines()[-1]
    # deterministic, two at once: one after another, side by side (measured faster)
    assert line.startswith("2 replicas (one after another, 2 replicas at once): 2 simulated "
                           "0.5 tau_d"), line
    assert main(["run", "--resume", str(out)]) == 2
    assert "every replica already finished" in capsys.readouterr().err
    # a shorter --duration: the line says where the replicas are, not what was asked
    assert main(["run", "--resume", str(out), "--duration", "0.5"]) == 2
    err = capsys.readouterr().err
    assert "at t = 0.5 tau_d or later" in err and "T > 0.5" in err, err
    assert main(["run", "--resume", str(out), "--duration", "1"]) == 0
    assert read_facts(out / "replica_1")["time_reached"] == pytest.approx(1.0)


_LARGE_SET = """
[knot]
beads = 80
[run]
duration = {duration}
peclet = 2.0
seed = 5
replicas = 2
replica_stepping = "together"
topology_check_interval = 0.0
[output]
directory = "{directory}"
frame_interval = 0.25
checkpoint_interval = 0.5
"""


@pytest.mark.skipif(not kp.available(), reason="the copies are the plugin's")
def test_a_set_resumed_in_a_new_process_equals_the_uninterrupted_set(tmp_path):
    # Each command in a process of its own, as a user runs them: the set extended from
    # 0.5 to 1 tau_d by `--resume --duration` takes the uninterrupted set's steps, to the
    # last bit of the state. Before, a resumed process loaded LAPACK's library after the set
    # had limited the BLAS threads: the 240 x 240 noise factors were made on every core
    # (rounding otherwise, and slower).
    import subprocess
    import sys

    def knotmm(*args):
        done = subprocess.run([sys.executable, "-m", "knotmm.cli", *map(str, args),
                               "--no-progress"], capture_output=True, text=True, timeout=300)
        assert done.returncode == 0, done.stderr

    for name, duration in (("whole", 1.0), ("resumed", 0.5)):
        path = tmp_path / f"{name}.toml"
        path.write_text(_LARGE_SET.format(duration=duration, directory=tmp_path / name))
        knotmm("run", path)
    knotmm("run", "--resume", tmp_path / "resumed", "--duration", 1.0)
    for k in range(2):
        whole = np.load(tmp_path / "whole" / f"replica_{k}" / "checkpoint.npz")
        resumed = np.load(tmp_path / "resumed" / f"replica_{k}" / "checkpoint.npz")
        assert float(whole["time"]) == float(resumed["time"]) == 1.0
        np.testing.assert_array_equal(resumed["positions"], whole["positions"])
        assert read_facts(tmp_path / "resumed" / f"replica_{k}")["replica_stepping"] == (
            f"together: copy {k} of 2 in one Context")
