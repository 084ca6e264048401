"""Tests of knotmm.knots.writhe: the compiled kernel against a brute-force Gauss integral."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from knotmm.knots import writhe as writhe_module
from knotmm.knots.writhe import writhe


def naive_gauss_writhe(x, m=12):
    """Writhe as a brute-force double sum of the Gauss integrand over a refined polygon.

    Every segment is cut into ``m`` pieces; the integrand (t_i x t_j) . r_ij / |r_ij|^3
    is summed over all pairs of pieces with the midpoint rule. Pieces of one segment are
    parallel (zero integrand), pieces of adjacent segments are coplanar with r (zero too),
    so no singular term appears.
    """
    seg = np.roll(x, -1, axis=0) - x
    t = (np.arange(m) + 0.5) / m
    pts = (x[:, None, :] + t[None, :, None] * seg[:, None, :]).reshape(-1, 3)
    dl = np.repeat(seg / m, m, axis=0)
    total = 0.0
    for i in range(len(pts)):
        r = pts[i] - pts
        dist = np.linalg.norm(r, axis=1)
        dist[i] = np.inf
        total += np.sum(np.einsum("k,jk->j", dl[i], np.cross(dl, r)) / dist**3)
    # (t_i x t_j) . (r_i - r_j) = t_i . (t_j x r_ij); sum over ordered pairs / 4 pi
    return total / (4.0 * np.pi)


def random_ring(rng, n=40):
    """A smooth random closed curve (few Fourier modes) sampled at n points."""
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    x = np.zeros((n, 3))
    for k in range(1, 4):
        a = rng.normal(size=3)
        b = rng.normal(size=3)
        x += np.outer(np.cos(k * t), a) + np.outer(np.sin(k * t), b)
    return x


# -- writhe --------------------------------------------------------------------------------
def test_planar_polygon_has_zero_writhe():
    t = np.linspace(0.0, 2.0 * np.pi, 50, endpoint=False)
    circle = np.c_[np.cos(t), np.sin(t), np.zeros_like(t)]
    assert writhe(circle) == pytest.approx(0.0, abs=1e-12)
    star = np.c_[(1 + 0.5 * np.cos(5 * t)) * np.cos(t), (1 + 0.5 * np.cos(5 * t)) * np.sin(t)]
    star = np.c_[star, np.zeros(len(t))]
    assert writhe(star) == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_writhe_matches_brute_force_gauss_integral(seed, torus_curve):
    # a trefoil with a random smooth distortion: strands stay well apart, so the midpoint
    # rule of the brute-force sum converges
    rng = np.random.default_rng(seed)
    x = torus_curve(2, 3, 36) + 0.25 * random_ring(rng, 36)
    assert writhe(x) == pytest.approx(naive_gauss_writhe(x, m=10), abs=2e-3)


def test_trefoil_writhe_matches_brute_force_and_is_positive(torus_curve):
    x = torus_curve(2, 3, 60)
    w = writhe(x)
    assert w > 3.0
    assert w == pytest.approx(naive_gauss_writhe(x, m=8), abs=2e-3)


def test_numba_kernel_matches_numpy_reference_and_leaves_input_alone():
    rng = np.random.default_rng(3)
    frames = np.stack([random_ring(rng, 25) + 0.1 * rng.normal(size=(25, 3)) for _ in range(6)])
    frames.setflags(write=False)
    before = frames.copy()
    fast = np.zeros(6)
    writhe_module._numba_kernel()(np.ascontiguousarray(frames), fast)
    ref = writhe_module._writhe_numpy(frames)
    np.testing.assert_allclose(fast, ref, rtol=0, atol=1e-8)
    np.testing.assert_array_equal(frames, before)
    np.testing.assert_allclose([writhe(f) for f in frames], fast, rtol=0, atol=1e-8)


def test_writhe_takes_the_compiled_kernel_for_large_problems(monkeypatch):
    rng = np.random.default_rng(4)
    frames = np.stack([random_ring(rng, 30) for _ in range(4)])
    small = writhe(frames)  # numpy
    monkeypatch.setattr(writhe_module, "_PAIR_CHUNK", 10)  # now "large": numba
    calls = []
    kernel = writhe_module._numba_kernel()
    monkeypatch.setattr(writhe_module, "_numba_kernel",
                        lambda: lambda f, o: calls.append(1) or kernel(f, o))
    large = writhe(frames)
    assert calls == [1] and large.shape == (4,)
    np.testing.assert_allclose(large, small, rtol=0, atol=1e-8)


def test_writhe_invariances():
    rng = np.random.default_rng(7)
    x = random_ring(rng, 40)
    w = writhe(x)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    if np.linalg.det(q) < 0:
        q[:, 0] *= -1
    assert writhe(x @ q.T + rng.normal(size=3)) == pytest.approx(w, abs=1e-9)
    assert writhe(3.7 * x) == pytest.approx(w, abs=1e-9)
    assert writhe(np.roll(x, 11, axis=0)) == pytest.approx(w, abs=1e-9)
    assert writhe(x[::-1]) == pytest.approx(w, abs=1e-9)
    mirrored = x * np.array([1.0, 1.0, -1.0])
    assert writhe(mirrored) == pytest.approx(-w, abs=1e-9)


@settings(max_examples=25, deadline=None)
@given(st.integers(min_value=0, max_value=2**32 - 1), st.integers(min_value=5, max_value=30))
def test_writhe_of_random_polygons_is_odd_under_mirroring(seed, n):
    x = np.random.default_rng(seed).normal(size=(n, 3))
    w = writhe(x)
    assert np.isfinite(w)
    assert writhe(x * np.array([-1.0, 1.0, 1.0])) == pytest.approx(-w, abs=1e-9)


def test_writhe_rejects_bad_input(torus_curve):
    with pytest.raises(ValueError, match="shape"):
        writhe(np.zeros((10, 2)))
    with pytest.raises(ValueError, match="at least 3"):
        writhe(np.zeros((2, 3)))
    bad = torus_curve(2, 3, 20)
    bad[3, 1] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        writhe(bad)


# -- knot identification -------------------------------------------------------------------
