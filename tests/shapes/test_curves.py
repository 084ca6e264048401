"""Equal-chord placement on a tube curve: the radius for a length and the Newton systems."""

from __future__ import annotations

import numpy as np
import pytest

from knotmm.shapes import curves


@pytest.mark.parametrize("p, q", [(2, 3), (2, 5), (3, 4)])
def test_radius_for_length_matches_bisection(p, q):
    curve = curves.torus_curve(p, q, 1.0)
    target = 90 * 0.6
    lo, hi = -curve.rho_min + 1e-9, 100.0
    for _ in range(200):  # plain bisection on the monotone length, written here
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if curve.length(mid) < target else (lo, mid)
    r = curve.radius_for_length(target, 100.0)
    assert r == pytest.approx(0.5 * (lo + hi), abs=1e-11)
    assert curve.length(r) == pytest.approx(target, rel=1e-13)


def test_length_slope_is_the_derivative_of_the_length():
    curve = curves.torus_curve(2, 3, 1.0)
    for r in (3.0, 8.0):
        h = 1e-5
        numeric = (curve.length(r + h) - curve.length(r - h)) / (2 * h)
        assert curve.length_slope(r) == pytest.approx(numeric, rel=1e-8)


@pytest.mark.parametrize("radius", [None, 9.0])
def test_dense_and_sparse_newton_systems_place_the_same_beads(radius, monkeypatch):
    curve = curves.torus_curve(2, 3, 1.0)
    dense = curves.equal_chord(curve, 120, radius, 0.6)
    monkeypatch.setattr(curves, "_DENSE_BEADS", 0)  # scipy.sparse's solver
    sparse = curves.equal_chord(curve, 120, radius, 0.6)
    np.testing.assert_allclose(dense[0], sparse[0], rtol=0, atol=1e-12)
    assert dense[1:] == pytest.approx(sparse[1:], rel=1e-12)
    x = curve.points(dense[0], dense[1])
    chords = np.linalg.norm(np.roll(x, -1, axis=0) - x, axis=1)
    np.testing.assert_allclose(chords, dense[2], rtol=1e-9)
    if radius is None:
        assert dense[2] == 0.6
