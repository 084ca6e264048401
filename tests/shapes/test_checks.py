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
        return resources.RunResources.of(cfg).need(6000)[0]

    assert need(_brownian(6000, "cholesky")) == 2 * 18000**2 * 8
    assert need(_brownian(6000, "lanczos")) == 0
    assert need(_brownian(6000, "auto")) == 0  # lanczos above 300
    assert need(RunConfig.from_dict({"knot": {"beads": 6000}})) == 0
