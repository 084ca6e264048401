"""Replicas that step at the same time in threads of one process (``run.replicas_at_once``):
each still equals its single run, they do overlap, a stop of one stops the others, and the
automatic choice follows the cores (a breakdown: tests/workflow/test_replica_runs.py)."""

from __future__ import annotations

import threading

import mdtraj
import numpy as np
import pytest

import knotmm.engine.copies as copies
import knotmm.plugin as kp
import knotmm.replicas as replicas
from knotmm.config import RunConfig
from knotmm.engine import affinity
from knotmm.io.replica_set import read_replica_set
from knotmm.io.rundir import read_facts
from knotmm.replicas import resume_replicas, run_replicas
from knotmm.workflow import run

pytestmark = pytest.mark.skipif(not kp.available(), reason="the plugin steps without the GIL")

BROWNIAN = {
    "knot": {"beads": 30, "minor_radius": 0.6},
    "model": {"gravity": 1.0},
    "run": {"duration": 0.3, "peclet": 10.0, "integrator": "ito_heun", "timestep": 0.002,
            "topology_check_interval": 0.0, "replicas": 3, "seed": 11,
            "replica_stepping": "one_after_another", "replicas_at_once": 2},
    "output": {"frame_interval": 0.05},
}


def _cfg(**run_keys):
    return RunConfig.from_dict({**BROWNIAN, "run": {**BROWNIAN["run"], **run_keys}})


def _xyz(directory):
    return mdtraj.load(str(directory / "trajectory.dcd"), top=str(directory / "topology.pdb")).xyz


def _single(tmp_path, seed, **run_keys):
    where = tmp_path / f"single_{seed}"
    run(_cfg(replicas=1, seed=seed, **run_keys), directory=where, progress=False)
    return _xyz(where)


class _Overlap:
    """Wraps :func:`knotmm.replicas.run`: the most replicas that were running at once."""

    def __init__(self, real):
        self.real, self.now, self.most = real, 0, 0
        self.lock = threading.Lock()

    def __call__(self, cfg, directory, **kwargs):
        with self.lock:
            self.now += 1
            self.most = max(self.most, self.now)
        try:
            return self.real(cfg, directory=directory, **kwargs)
        finally:
            with self.lock:
                self.now -= 1


def test_the_automatic_choice_follows_the_cores_and_the_threads_a_replica_takes(monkeypatch):
    monkeypatch.setattr(copies, "usable_cores", lambda: 4)
    assert copies.replicas_at_once(0, 8, "plugin", "CPU", 1)[0] == 4
    assert copies.replicas_at_once(0, 8, "plugin", "CPU", 2)[0] == 2
    assert copies.replicas_at_once(0, 3, "plugin", "Reference", 1)[0] == 3  # no more than K
    assert copies.replicas_at_once(0, 8, "plugin", "CPU", 8)[0] == 1
    assert copies.replicas_at_once(0, 8, "python", "CPU", 1)[0] == 1
    at_once, why = copies.replicas_at_once(0, 8, "plugin", "OpenCL", 1)
    assert at_once == 1 and "OpenCL" in why
    assert copies.replicas_at_once(3, 8, "python", "CUDA", 1) == (3, "run.replicas_at_once = 3")
    assert copies.replicas_at_once(5, 2, "plugin", "CPU", 1)[0] == 2


def test_replicas_side_by_side_overlap_and_equal_single_runs_bit_for_bit(tmp_path, monkeypatch):
    overlap = _Overlap(replicas.run)
    monkeypatch.setattr(replicas, "run", overlap)
    result = run_replicas(_cfg(), directory=tmp_path / "set", progress=False)
    assert not result.errors and all(r is not None for r in result.results)
    assert overlap.most == 2  # two at a time, never three
    record = read_replica_set(tmp_path / "set")["replicas"]
    assert (record["stepping"], record["at_once"]) == ("one after another", 2)
    assert record["at_once_reason"] == "run.replicas_at_once = 2"
    for k, seed in enumerate(record["seeds"]):
        np.testing.assert_array_equal(_xyz(tmp_path / "set" / f"replica_{k}"),
                                      _single(tmp_path, seed))


def test_groups_of_copies_step_at_the_same_time_and_equal_single_runs(tmp_path):
    """Four replicas stepped together, two groups at once: each group of two is one Context,
    and each replica equals its single run to the rounding of a copies Context (see
    tests/workflow/test_replica_runs.py)."""
    root = tmp_path / "set"
    run_replicas(_cfg(replicas=4, replica_stepping="together"), directory=root, progress=False)
    record = read_replica_set(root)["replicas"]
    assert (record["stepping"], record["at_once"]) == ("together", 2)
    stepping = [read_facts(root / f"replica_{k}")["replica_stepping"] for k in range(4)]
    assert stepping == [f"together: copy {k % 2} of 2 in one Context" for k in range(4)]
    for k in (0, 3):
        np.testing.assert_allclose(_xyz(root / f"replica_{k}"),
                                   _single(tmp_path, record["seeds"][k]), rtol=0, atol=1e-5)


def test_a_stop_of_one_replica_stops_the_one_beside_it_and_the_set_resumes_bit_for_bit(
        tmp_path, monkeypatch):
    real = replicas.run
    started = threading.Event()

    def stopping(cfg, directory, **kwargs):
        if directory.name == "replica_1":
            started.wait(30)  # replica 0 is under way
            raise KeyboardInterrupt
        started.set()
        return real(cfg, directory=directory, **kwargs)

    monkeypatch.setattr(replicas, "run", stopping)
    root = tmp_path / "set"
    cfg = _cfg(duration=2.0)
    with pytest.raises(KeyboardInterrupt):
        run_replicas(cfg, directory=root, progress=False)
    facts = read_facts(root / "replica_0")
    assert facts["status"] == "interrupted" and facts["time_reached"] < 2.0
    assert not (root / "replica_2" / "run.toml").exists()  # not started after the stop
    monkeypatch.setattr(replicas, "run", real)
    result = resume_replicas(root, progress=False)
    assert not result.errors and all(r.time == pytest.approx(2.0) for r in result.results)
    seeds = read_replica_set(root)["replicas"]["seeds"]
    for k in (0, 2):
        np.testing.assert_array_equal(_xyz(root / f"replica_{k}"),
                                      _single(tmp_path, seeds[k], duration=2.0))


def test_stretches_stepping_at_the_same_time_take_different_cores():
    try:
        allowed = affinity.os.sched_getaffinity(0)
    except (AttributeError, OSError):
        pytest.skip("no CPU affinity here")
    if len(allowed) < 2 or affinity._sched_getcpu is None:
        pytest.skip("needs two cores")
    first = affinity._take_core(allowed)
    try:
        second = affinity._take_core(allowed)  # this thread's core is held: another one
        try:
            assert first != second and {first, second} <= allowed
        finally:
            affinity._give_core(second)
    finally:
        affinity._give_core(first)
    assert not any(affinity._held.values())


def test_contexts_created_at_the_same_time_each_pin_only_their_own_pool():
    """Two replicas starting together in threads: each CorePin remembers the pool threads of
    its own Context, never the other's (or each stretch would pull the other's pool)."""
    import openmm

    from knotmm.model.system import ChainModel, chain_system
    from knotmm.shapes.geometry import torus_knot

    if not affinity._supported():
        pytest.skip("no thread affinity here")
    system = chain_system(torus_knot(2, 3, 30), ChainModel())
    platform = openmm.Platform.getPlatformByName("CPU")
    start = threading.Barrier(2)
    pins, contexts = [], []

    def create():
        pin = affinity.CorePin(True)
        start.wait(10)
        with pin.creating():
            contexts.append(openmm.Context(system, openmm.VerletIntegrator(0.001), platform,
                                           {"Threads": "1"}))
        pins.append(pin)

    threads = [threading.Thread(target=create) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(pins) == 2 and pins[0].pool and pins[1].pool
    assert not pins[0].pool & pins[1].pool


def test_the_replicas_of_one_lane_show_the_progress_one_after_another(tmp_path, monkeypatch):
    """Side by side, the replicas that the first thread runs show their progress in turn
    (never two bars at once), and the others none; replica 0 is one of them."""
    real, seen = replicas.run, []

    def recording(cfg, directory, **kwargs):
        seen.append((directory.name, kwargs["progress"], threading.current_thread().name))
        return real(cfg, directory=directory, **{**kwargs, "progress": False})

    monkeypatch.setattr(replicas, "run", recording)
    run_replicas(_cfg(replicas=4), directory=tmp_path / "set", progress=True)
    shown = {name for name, progress, _ in seen if progress}
    first_lane = {name for name, _, thread in seen if thread == "knotmm-replicas-0"}
    assert len(seen) == 4 and "replica_0" in shown and shown == first_lane
