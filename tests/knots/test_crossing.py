"""Average crossing number (and open-chain writhe) against independent references.

* The ACN is the number of crossings of a projection averaged over directions: checked with a
  naive Monte Carlo quadrature over random directions written here (project, count the
  crossing segment pairs of the 2-D polygon, average).
* The ACN is the Gauss double integral of ``|integrand|``: checked with a naive fine double
  Riemann sum written here.
"""

from __future__ import annotations

import numpy as np
import pytest

from knotmm.knots.writhe import average_crossing_number, writhe


def random_ring(rng, n=30, modes=3):
    """A smooth random closed curve (few Fourier modes) sampled at n points."""
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    x = np.zeros((n, 3))
    for k in range(1, modes + 1):
        a, b = rng.normal(size=3), rng.normal(size=3)
        x += np.outer(np.cos(k * t), a) + np.outer(np.sin(k * t), b)
    return x


def flat_trefoil(n=240, h=0.05):
    """T(2,3) drawn on a thin torus of height h: 3 crossings seen from above."""
    a = 2 * np.pi * 2 * np.arange(n) / n
    rho = 4.0 + 0.8 * np.sin(1.5 * a)
    return np.c_[rho * np.cos(a), rho * np.sin(a), h * np.cos(1.5 * a)]


def segments(x, closed):
    return (x, np.roll(x, -1, axis=0)) if closed else (x[:-1], x[1:])


def projected_crossings(x, closed, directions):
    """Crossings of the projection of the polygon along each direction (naive 2-D test).

    Two segments of the projected polygon that share no bead cross when the ends of each lie
    strictly on both sides of the other's line (orientation signs differ).
    """
    a, b = segments(x, closed)
    m = len(a)
    i, j = np.triu_indices(m, k=2)
    if closed:
        keep = ~((i == 0) & (j == m - 1))
        i, j = i[keep], j[keep]
    counts = np.zeros(len(directions))
    for k, d in enumerate(directions):
        e1 = np.cross(d, [1.0, 0.0, 0.0] if abs(d[0]) < 0.9 else [0.0, 1.0, 0.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(d, e1)
        basis = np.stack([e1, e2], axis=1)  # (3, 2)
        pa, pb = a @ basis, b @ basis

        def orient(p, q, r):
            return np.sign((q[:, 0] - p[:, 0]) * (r[:, 1] - p[:, 1])
                           - (q[:, 1] - p[:, 1]) * (r[:, 0] - p[:, 0]))

        p1, p2, p3, p4 = pa[i], pb[i], pa[j], pb[j]
        crossed = (orient(p1, p2, p3) * orient(p1, p2, p4) < 0) & (
            orient(p3, p4, p1) * orient(p3, p4, p2) < 0)
        counts[k] = crossed.sum()
    return counts


def uniform_directions(n, seed):
    v = np.random.default_rng(seed).normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def naive_gauss(x, closed, absolute, m=16):
    """(1/4pi) sum over ordered pairs of pieces of (|)(dl_i x dl_j) . r_ij(|) / |r_ij|^3.

    Each segment is cut into ``m`` pieces, midpoint rule. Pieces of one segment and of
    adjacent segments give zero (parallel or coplanar with r), so nothing is singular.
    """
    a, b = segments(x, closed)
    seg = b - a
    t = (np.arange(m) + 0.5) / m
    pts = (a[:, None, :] + t[None, :, None] * seg[:, None, :]).reshape(-1, 3)
    dl = np.repeat(seg / m, m, axis=0)
    total = 0.0
    for k in range(len(pts)):
        r = pts[k] - pts
        dist = np.linalg.norm(r, axis=1)
        dist[k] = np.inf
        f = np.einsum("k,jk->j", dl[k], np.cross(dl, r)) / dist**3
        total += np.sum(np.abs(f) if absolute else f)
    return total / (4.0 * np.pi)


# -- closed forms and limits ----------------------------------------------------------------
def test_circle_and_planar_convex_polygons_have_zero_acn():
    t = np.linspace(0.0, 2.0 * np.pi, 64, endpoint=False)
    circle = np.c_[np.cos(t), np.sin(t), np.zeros_like(t)]
    assert average_crossing_number(circle) == pytest.approx(0.0, abs=1e-12)
    ellipse = np.c_[5 * np.cos(t), np.sin(t), np.zeros_like(t)] + [1.0, 2.0, 3.0]
    assert average_crossing_number(ellipse) == pytest.approx(0.0, abs=1e-12)
    # a circle tilted in space is still planar and convex; rounding leaves ~1e-8 per
    # segment pair (arcsin of dot products next to 1), which |.| does not cancel
    rot = np.linalg.qr(np.random.default_rng(0).normal(size=(3, 3)))[0]
    assert average_crossing_number(circle @ rot.T) == pytest.approx(0.0, abs=1e-5)
    assert average_crossing_number(circle[:40], closed=False) == pytest.approx(0.0, abs=1e-12)


def test_flat_curve_with_three_crossings_tends_to_three():
    """A thin T(2,3) seen from above has 3 crossings; as it flattens its ACN tends to 3 (every
    oblique projection of a planar diagram is an affine image: 3 crossings too)."""
    values = [average_crossing_number(flat_trefoil(h=h)) for h in (0.2, 0.05, 0.01)]
    gaps = [v - 3.0 for v in values]
    assert all(g > 0 for g in gaps) and gaps[0] > gaps[1] > gaps[2]
    assert values[-1] == pytest.approx(3.0, abs=0.03)
    # crossings seen from above: exactly 3
    assert projected_crossings(flat_trefoil(h=0.01), True, np.array([[0.0, 0.0, 1.0]]))[0] == 3


@pytest.mark.parametrize("closed", [True, False])
def test_acn_is_the_mean_crossing_number_over_directions(closed):
    """ACN against a naive quadrature: random projection directions, crossings counted."""
    rng = np.random.default_rng(7)
    for x in (random_ring(rng, 30), flat_trefoil(n=60, h=0.6)):
        counts = projected_crossings(x, closed, uniform_directions(6000, seed=1))
        mean, err = counts.mean(), counts.std() / np.sqrt(len(counts))
        acn = average_crossing_number(x, closed=closed)
        assert acn == pytest.approx(mean, abs=4 * err + 1e-9)
        assert counts.std() > 0  # a real test: the count varies with the direction


@pytest.mark.parametrize("closed", [True, False])
def test_acn_and_writhe_against_a_fine_riemann_sum(closed):
    x = random_ring(np.random.default_rng(3), n=14, modes=2)
    ref_acn = naive_gauss(x, closed, absolute=True)
    ref_wr = naive_gauss(x, closed, absolute=False)
    assert average_crossing_number(x, closed=closed) == pytest.approx(ref_acn, rel=5e-3)
    assert writhe(x, closed=closed) == pytest.approx(ref_wr, abs=5e-3 * ref_acn)


def test_invariants_and_batches():
    rng = np.random.default_rng(11)
    frames = np.stack([random_ring(rng, 25) for _ in range(4)])
    acn = average_crossing_number(frames)
    wr = writhe(frames)
    assert acn.shape == (4,)
    assert np.all(acn >= np.abs(wr) - 1e-12)
    for k in range(4):
        assert acn[k] == average_crossing_number(frames[k])
    # rigid motions, scaling and mirror images leave the ACN unchanged
    rot = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    moved = frames[0] @ rot.T * 3.0 + [1.0, -2.0, 5.0]
    assert average_crossing_number(moved) == pytest.approx(acn[0], rel=1e-10)
    assert average_crossing_number(frames[0] * [1, 1, -1]) == pytest.approx(acn[0], rel=1e-10)
    # open chains: the batch of two-bead chains has no segment pairs
    pairs = np.zeros((3, 2, 3)) + [0, 0, 1]
    assert average_crossing_number(pairs, closed=False).tolist() == [0, 0, 0]
    with pytest.raises(ValueError, match="closed chain needs at least 3"):
        average_crossing_number(np.zeros((2, 3)))
