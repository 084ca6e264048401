"""The RPY mobility kernels against docs/model.md's tensor, written as a naive loop in the test."""

from __future__ import annotations

import numpy as np
import pytest
import reference_model as rm
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from knotmm.dynamics.mobility import pair_coefficients, rpy_matrix, rpy_velocities


def _cloud(rng, n, box):
    """n beads uniform in a cube of side ``box`` d (small box: most pairs overlap, r < d)."""
    return rng.uniform(-box / 2, box / 2, size=(n, 3))


def _readonly(a):
    a = np.array(a, dtype=np.float64)
    a.setflags(write=False)
    return a


@pytest.mark.parametrize("n,box", [(2, 0.5), (7, 1.0), (30, 1.5), (40, 6.0), (64, 20.0)])
def test_velocities_match_naive_loop(rng, n, box):
    x = _cloud(rng, n, box)
    f = rng.normal(size=(n, 3))
    r = np.linalg.norm(x[:, None] - x[None], axis=-1)[np.triu_indices(n, 1)]
    want = rm.rpy_velocities(x, f)
    got = rpy_velocities(x, f)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12 * np.abs(want).max())
    if box <= 1.5:
        assert (r < 1).mean() > 0.4  # the overlap branch is exercised
    if box >= 6:
        assert (r >= 1).mean() > 0.8


def test_both_branches_through_a_pair_scan():
    """Two beads, random force directions, r through both branches and across r = d."""
    rng = np.random.default_rng(3)
    for r in np.concatenate([np.linspace(1e-6, 3.0, 301), [1 - 1e-12, 1.0, 1 + 1e-12]]):
        rhat = rng.normal(size=3)
        rhat /= np.linalg.norm(rhat)
        x = np.array([[0.1, -0.2, 0.3], [0.1, -0.2, 0.3] + r * rhat])
        f = rng.normal(size=(2, 3))
        np.testing.assert_allclose(
            rpy_velocities(x, f), rm.rpy_velocities(x, f), rtol=1e-12, atol=1e-12, err_msg=f"r={r}"
        )
        np.testing.assert_allclose(rpy_matrix(x), rm.rpy_dense(x), rtol=1e-12, atol=1e-14)


def test_coincident_beads_take_the_r_to_zero_limit():
    x = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    f = np.array([[1.0, 2.0, 3.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    v = rpy_velocities(x, f)
    np.testing.assert_allclose(v[1], f[0])  # mu_01 = I at r = 0
    np.testing.assert_allclose(v, rm.rpy_velocities(x, f), atol=1e-15)
    assert np.all(np.isfinite(rpy_matrix(x)))


@pytest.mark.parametrize("n,box", [(5, 0.8), (25, 2.0), (50, 8.0)])
def test_velocities_equal_dense_matrix_product(rng, n, box):
    x = _cloud(rng, n, box)
    f = rng.normal(size=(n, 3))
    m = rpy_matrix(x)
    np.testing.assert_allclose(m, rm.rpy_dense(x), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(
        rpy_velocities(x, f), (m @ f.reshape(-1)).reshape(n, 3), rtol=1e-11, atol=1e-12
    )


@settings(max_examples=80, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(2, 48),
    box=st.floats(0.2, 8.0),
    squash=st.floats(0.05, 1.0),
)
def test_matrix_symmetric_positive_definite(seed, n, box, squash):
    """Random clouds, most of them with many overlapping beads (r < d), some flattened to
    near-planar sheets: the tensor is symmetric with every eigenvalue > 0."""
    rng = np.random.default_rng(seed)
    x = _cloud(rng, n, box) * np.array([1.0, 1.0, squash])
    r = np.linalg.norm(x[:, None] - x[None], axis=-1)[np.triu_indices(n, 1)]
    # coincident beads make the tensor only semi-definite (F_i = -F_j gives v = 0)
    assume(r.min() > 1e-3)
    m = rpy_matrix(x)
    np.testing.assert_array_equal(m, m.T)
    lam = np.linalg.eigvalsh(m)
    assert lam.min() > 1e-8, (lam.min(), r.min())


def test_positive_definite_for_dense_overlapping_clusters(rng):
    """Many beads packed at 0.05-0.3 d from each other: still positive definite."""
    for n, box in [(60, 0.7), (120, 1.2), (200, 3.0)]:
        x = _cloud(rng, n, box)
        lam = np.linalg.eigvalsh(rpy_matrix(x))
        assert lam.min() > 0, (n, box, lam.min())


def _parallel_perpendicular(r):
    """mu_parallel and mu_perpendicular of the pair tensor at distance r (code under test)."""
    x = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, r]])
    m = rpy_matrix(x)[0:3, 3:6]
    return m[2, 2], m[0, 0]


def test_pair_tensor_continuous_with_continuous_slope_at_contact():
    # closed forms from docs/model.md at r = d: both branches give 5/8 along rhat, 7/16 across,
    # with slopes -3/8 and -9/16 (outside: d/dr of 3/(4r) - 1/(8r^3), 3/(8r) + 1/(16r^3)).
    par, perp = _parallel_perpendicular(1.0)
    assert par == pytest.approx(5 / 8, rel=1e-15) and perp == pytest.approx(7 / 16, rel=1e-15)
    d = 1e-6
    below = np.array(_parallel_perpendicular(1 - d))
    above = np.array(_parallel_perpendicular(1 + d))
    np.testing.assert_allclose(below, [5 / 8, 7 / 16], atol=1e-6)
    np.testing.assert_allclose(above, [5 / 8, 7 / 16], atol=1e-6)
    h = 1e-4
    slope_in = (np.array(_parallel_perpendicular(1 - h)) - _parallel_perpendicular(1 - 2 * h)) / h
    slope_out = (np.array(_parallel_perpendicular(1 + 2 * h)) - _parallel_perpendicular(1 + h)) / h
    np.testing.assert_allclose(slope_in, [-3 / 8, -9 / 16], atol=1e-9)  # linear inside
    np.testing.assert_allclose(slope_out, [-3 / 8, -9 / 16], atol=5e-4)
    # and the exposed scalar coefficients agree with the tensor
    for r in (0.3, 1 - 1e-9, 1.0, 1.7):
        a, b = pair_coefficients(r)
        par, perp = _parallel_perpendicular(r)
        assert a == pytest.approx(perp, rel=1e-14)
        assert a + b * r * r == pytest.approx(par, rel=1e-14)


def test_inputs_are_not_mutated_and_readonly_inputs_work(rng):
    x = _readonly(_cloud(rng, 20, 2.0))
    f = _readonly(rng.normal(size=(20, 3)))
    x0, f0 = x.copy(), f.copy()
    v = rpy_velocities(x, f)
    m = rpy_matrix(x)
    np.testing.assert_array_equal(x, x0)
    np.testing.assert_array_equal(f, f0)
    np.testing.assert_allclose(v, rm.rpy_velocities(x0, f0), rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(m, rm.rpy_dense(x0), rtol=1e-12, atol=1e-14)
    # non-contiguous views and float32 inputs
    big = rng.normal(size=(20, 6)) * 2
    xv, fv = big[:, ::2], big[:, 1::2]
    np.testing.assert_allclose(
        rpy_velocities(xv, fv), rm.rpy_velocities(xv, fv), rtol=1e-12, atol=1e-13
    )
    x32 = x0.astype(np.float32)
    np.testing.assert_allclose(
        rpy_velocities(x32, f0), rm.rpy_velocities(x32, f0), rtol=1e-12, atol=1e-13
    )


def test_out_argument_is_filled_and_returned(rng):
    x = _cloud(rng, 10, 3.0)
    f = rng.normal(size=(10, 3))
    out = np.full((10, 3), np.nan)
    ret = rpy_velocities(x, f, out=out)
    assert ret is out
    np.testing.assert_allclose(out, rm.rpy_velocities(x, f), rtol=1e-12, atol=1e-13)


def test_shape_errors_name_the_arguments():
    with pytest.raises(ValueError, match="positions and forces"):
        rpy_velocities(np.zeros((4, 3)), np.zeros((5, 3)))
    with pytest.raises(ValueError, match="positions"):
        rpy_matrix(np.zeros((4, 2)))


# -- two beads falling together ---------------------------------------------------------------
# Two beads under the same force F = -F0 z. With mu_ij = a(r) I + b(r) rhat rhat, both move
# with U = mu0 F0 (1 + a) when side by side (rhat perpendicular to gravity) and with
# U = mu0 F0 (1 + a + b) when one is above the other (rhat along gravity). From docs/model.md:
#   r >= d, side by side:  1 + 3/(8r) + 1/(16 r^3)       (= 1 + 3a/(4r) + a^3/(2r^3), a = d/2)
#   r >= d, one above:     1 + 3/(4r) - 1/(8 r^3)        (= 1 + 3a/(2r) - a^3/r^3)
#   r <  d, side by side:  2 - 9r/16
#   r <  d, one above:     2 - 3r/8
def _side_by_side(r):
    return 1 + 3 / (8 * r) + 1 / (16 * r**3) if r >= 1 else 2 - 9 * r / 16


def _one_above(r):
    return 1 + 3 / (4 * r) - 1 / (8 * r**3) if r >= 1 else 2 - 3 * r / 8


@pytest.mark.parametrize("r", [0.05, 0.3, 0.6, 0.999, 1.0, 1.2, 2.0, 5.0, 50.0])
@pytest.mark.parametrize("orientation", ["side_by_side", "one_above"])
def test_two_beads_fall_with_the_closed_form_speed(r, orientation):
    direction = (
        np.array([1.0, 0.0, 0.0]) if orientation == "side_by_side" else np.array([0.0, 0.0, 1.0])
    )
    x = np.array([[0.3, 0.2, -7.0], [0.3, 0.2, -7.0] + r * direction])
    f = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, -1.0]])
    v = rpy_velocities(x, f)
    want = _side_by_side(r) if orientation == "side_by_side" else _one_above(r)
    np.testing.assert_allclose(v[:, 2], -want, rtol=1e-13)
    np.testing.assert_allclose(v[:, :2], 0.0, atol=1e-15)
    # a pair falls faster than a lone bead, and faster one above the other when apart
    assert want > 1
    if r > 1:
        assert _one_above(r) > _side_by_side(r)


def test_two_beads_far_apart_fall_like_one():
    x = np.array([[0.0, 0.0, 0.0], [1e6, 0.0, 0.0]])
    v = rpy_velocities(x, np.array([[0.0, 0.0, -1.0]] * 2))
    np.testing.assert_allclose(v[:, 2], -1.0, rtol=1e-6)


def test_one_bead_pulled_drags_its_neighbour():
    """Only bead 0 pulled along the line of centres: bead 1 moves with mu_par(r) of the tensor."""
    for r in (0.5, 1.0, 3.0):
        x = np.array([[0.0, 0.0, 0.0], [r, 0.0, 0.0]])
        v = rpy_velocities(x, np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]))
        want = 3 / (4 * r) - 1 / (8 * r**3) if r >= 1 else 1 - 3 * r / 8
        assert v[1, 0] == pytest.approx(want, rel=1e-13)
        assert v[0, 0] == pytest.approx(1.0, rel=1e-15)


@pytest.mark.parametrize("n", [7, 150])
def test_threaded_pair_loop_gives_the_same_velocities_bit_for_bit(rng, n):
    x = rng.uniform(0, 6.0, size=(n, 3))
    f = rng.normal(size=(n, 3))
    import numba

    from knotmm.dynamics.mobility import _threads_for

    assert _threads_for(2) == min(2, numba.config.NUMBA_NUM_THREADS)  # main thread: used
    serial = rpy_velocities(x, f)
    np.testing.assert_array_equal(rpy_velocities(x, f, threads=2), serial)
    np.testing.assert_array_equal(rpy_velocities(x, f, threads=64), serial)  # capped
    want = rm.rpy_velocities(x, f)
    np.testing.assert_allclose(serial, want, rtol=1e-12, atol=1e-12 * np.abs(want).max())


def test_threaded_pair_loop_falls_back_to_one_thread_off_the_main_thread(rng):
    """numba's default threading layer may not be entered from two threads at once."""
    import threading

    from knotmm.dynamics.mobility import _threads_for

    x = rng.uniform(0, 6.0, size=(50, 3))
    f = rng.normal(size=(50, 3))
    seen = {}

    def work():
        seen["threads"] = _threads_for(2)
        seen["v"] = rpy_velocities(x, f, threads=2)

    worker = threading.Thread(target=work)
    worker.start()
    worker.join()
    assert seen["threads"] == 1
    np.testing.assert_array_equal(seen["v"], rpy_velocities(x, f))
