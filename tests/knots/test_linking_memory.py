"""The Gauss linking integral of long chains in bounded memory (issue 30, BUG-16): a link
of up to knotmm.limits.MAX_BEADS beads must not ask for memory in proportion to the product
of its components' lengths (two 50000-bead rings once needed over 1 TB)."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from knotmm.knots.linking import gauss_linking_integral


def _hopf(n: int) -> tuple[np.ndarray, np.ndarray]:
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    a = 50.0 * np.stack([np.cos(t), np.sin(t), 0.0 * t], axis=1)
    b = 50.0 * np.stack([1.0 + np.cos(t), 0.0 * t, np.sin(t)], axis=1)
    return a, b


def test_the_linking_integral_of_long_rings_takes_bounded_memory():
    a, b = _hopf(1000)  # 1e6 segment pairs: about 450 MB when held at once
    tracemalloc.start()
    try:
        value = gauss_linking_integral(a, b)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert abs(value) == pytest.approx(1.0, abs=1e-6)
    assert peak < 150e6, f"peak {peak / 1e6:.0f} MB"


def test_blocks_give_the_same_integral_as_one_block(monkeypatch):
    import knotmm.knots.linking as linking

    a, b = _hopf(120)
    whole = gauss_linking_integral(a, b)
    monkeypatch.setattr(linking, "_BLOCK_PAIRS", 1000)  # 8 rows a block, the last one short
    assert gauss_linking_integral(a, b) == pytest.approx(whole, abs=1e-12)
