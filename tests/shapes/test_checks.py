"""Template checks at any size (issue 11, item 5): O(N) memory, a refusal with the estimate."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from knotmm.config import RunConfig
from knotmm.errors import ConfigError
from knotmm.shapes import build_template, checks, resources, torus_knot
from knotmm.shapes.checks import closest_nonbonded


def _naive_closest(x):
    """Every pair, in (i, j) order; the first of equal distances wins."""
    n = len(x)
    best, pair = np.inf, None
    for i in range(n):
        for j in range(i + 1, n):
            if j - i == 1 or (i == 0 and j == n - 1):
                continue
            d = np.sqrt(np.sum((x[i] - x[j]) ** 2))
            if d < best:
                best, pair = d, (i, j)
    return float(best), pair


@pytest.mark.parametrize("way", ["blocks", "row-by-row", "kd-tree"])
@pytest.mark.parametrize("n", [4, 5, 7, 30, 120])
def test_closest_pair_matches_all_pairs(n, way, rng, monkeypatch):
    if way == "kd-tree":  # the k-d tree that large chains use, on small ones
        monkeypatch.setattr(checks, "_ALL_PAIRS_BEADS", 0)
    elif way == "row-by-row":  # one row per block: ties across blocks
        monkeypatch.setattr(checks, "_BLOCK_PAIRS", 1)
    for trial in range(5):
        x = rng.normal(size=(n, 3))
        if trial % 2:
            x = np.round(x, 1)  # exact ties
        x.setflags(write=False)
        assert closest_nonbonded(x) == _naive_closest(x)


def test_closest_pair_of_coincident_beads():
    assert closest_nonbonded(np.zeros((6, 3))) == (0.0, (0, 2))


def test_closest_pair_of_a_huge_chain_in_linear_memory():
    x = torus_knot(2, 3, 20000)
    tracemalloc.start()
    try:
        d, (i, j) = closest_nonbonded(x)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    # all pairs would take 20000^2 / 2 doubles = 1.6 GB
    assert peak < 50e6
    assert j - i == 2 and d == pytest.approx(np.linalg.norm(x[i] - x[j]))


def _brownian(beads, noise):
    return RunConfig.from_dict(
        {"knot": {"beads": beads}, "run": {"peclet": 2.0, "noise": noise, "duration": 1.0}}
    )


def test_dense_noise_that_cannot_fit_is_refused_with_the_estimate(monkeypatch):
    monkeypatch.setattr(resources, "available_memory", lambda: 2_000_000_000)
    need = 2 * (3 * 6000) ** 2 * 8  # the RPY matrix and its Cholesky factor, float64
    with pytest.raises(ConfigError, match=rf"knot\.beads=6000 .*about {need / 1e9:.3g} GB") as e:
        build_template(_brownian(6000, "cholesky"))
    assert "\n" not in str(e.value) and "lanczos" in str(e.value)


def test_only_the_dense_noise_counts():
    def need(cfg):
        return resources.RunResources.of(cfg).need(6000).host  # run.engine "auto": the larger

    assert need(_brownian(6000, "cholesky")) == 2 * 18000**2 * 8
    assert need(_brownian(6000, "lanczos")) == 0
    assert need(_brownian(6000, "auto")) == 0  # lanczos above 300
    assert need(RunConfig.from_dict({"knot": {"beads": 6000}})) == 0


@pytest.mark.parametrize(("engine", "device", "host", "on_device"), [
    # the Python engine: scipy's factor beside the RPY matrix, both (3N)^2 float64 on the host
    ("python", False, 2 * 18000**2 * 8, 0),
    ("python", True, 2 * 18000**2 * 8, 0),  # a device computes its forces; its state: the host
    # the plugin: one matrix, factored in place; on a device, host too (CommonRPYBackend's mat)
    ("plugin", False, 18000**2 * 8, 0),
    # on the device: the backend's 5 vectors (forces, noiseAt, lanczosIn, lanczosOut,
    # energyPosition) and the stepper's StepWork 5, FixedSteps 6, RK23 5, RKC2 11, adaptive
    # Brownian 8, each 3N float64
    ("plugin", True, 18000**2 * 8, (5 + 5 + 6 + 5 + 11 + 8) * 18000 * 8),
])
def test_the_memory_need_knows_where_the_arrays_live(engine, device, host, on_device):
    need = resources.RunResources(brownian=True, noise="cholesky", engine=engine).need(
        6000, device=device)
    assert (need.host, need.device) == (host, on_device)
    lanczos = resources.RunResources(brownian=True, noise="lanczos", engine=engine).need(
        6000, device=device)
    assert (lanczos.host, lanczos.device) == (0, on_device)  # matrix-free: nothing dense


def test_the_plan_records_its_memory_need_for_its_engine():
    from knotmm.plan import make_plan

    for engine, matrices in (("python", 2), ("plugin", 1)):
        cfg = RunConfig.from_dict({"knot": {"beads": 40}, "run": {
            "peclet": 2.0, "noise": "cholesky", "engine": engine, "duration": 1.0,
            "platform": "Reference"}})
        plan = make_plan(cfg)
        if plan.placement.engine != engine:
            pytest.skip(f"the {engine} engine is not available here")
        assert plan.memory.host == matrices * 120**2 * 8 and plan.memory.device == 0
