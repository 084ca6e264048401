"""Rotne-Prager-Yamakawa (RPY) mobility of equal beads, with the overlap correction.

Model units: bead diameter ``d = 1``, single-bead mobility ``mu0 = 1``. For beads ``i != j``
at separation ``r = |r_i - r_j|`` with unit vector ``rhat``:

* ``r >= d``: ``mu_ij = 3 d / (8 r) [(1 + d^2/(6 r^2)) I + (1 - d^2/(2 r^2)) rhat rhat]``
* ``r <  d``: ``mu_ij = (1 - 9 r / (16 d)) I + (3 r / (16 d)) rhat rhat``

and ``mu_ii = I``. Both branches meet continuously at ``r = d`` (value and slope), the
3N x 3N tensor is symmetric and positive definite for every configuration, and its
divergence vanishes, so Brownian dynamics with it needs no drift term.

The velocity ``v_i = sum_j mu_ij F_j`` is computed matrix-free by :func:`rpy_velocities`,
an O(N^2) pair loop compiled with numba (each bead sums over all others; rows can run on
several threads). :func:`rpy_matrix`
assembles the dense tensor (for the noise and for tests).
"""

from __future__ import annotations

import threading

import numba
import numpy as np

__all__ = ["rpy_velocities", "rpy_matrix", "pair_coefficients"]


@numba.njit(cache=True, inline="always")
def _pair_coefficients(r):
    """Coefficients ``(a, b)`` with ``mu_ij = a I + b rvec rvec^T`` (``rvec`` unnormalised).

    Written without an early exit so that the pair loop that inlines it vectorises; at
    ``r = 0`` (a bead with itself, or an exact overlap) it gives the limit ``mu = I``.
    """
    inv = 1.0 / max(r, 1e-300)
    inv2 = inv * inv
    if r >= 1.0:
        a = 0.375 * inv * (1.0 + inv2 / 6.0)
        b = 0.375 * inv * (1.0 - 0.5 * inv2) * inv2
    else:
        a = 1.0 - 0.5625 * r
        b = 0.1875 * inv
    if r == 0.0:
        a = 1.0
        b = 0.0
    return a, b


@numba.njit(cache=True)
def pair_coefficients(r):
    """Scalar coefficients of the RPY pair tensor at distance ``r`` (in d).

    Returns ``(a, b)`` such that ``mu_ij / mu0 = a I + b * rvec rvec^T`` with ``rvec`` the
    (unnormalised) separation vector. Exposed for tests and diagnostics.
    """
    return _pair_coefficients(r)


@numba.njit(cache=True, fastmath=True, boundscheck=False, inline="always")
def _row_velocity(xt, ft, i):
    """``sum_j mu_ij F_j`` for bead ``i``; coordinates stored as rows (``xt[k, i]``).

    Every bead visits all others (N^2 pairs instead of N^2/2) because a loop that only
    reads memory and accumulates in registers vectorises; it is about 3x faster than the
    half loop that scatters into ``v[j]``, and the rows are independent, so they can be
    shared out among threads.
    """
    n = xt.shape[1]
    xs = xt[0]
    ys = xt[1]
    zs = xt[2]
    fx = ft[0]
    fy = ft[1]
    fz = ft[2]
    xi = xs[i]
    yi = ys[i]
    zi = zs[i]
    ax = 0.0
    ay = 0.0
    az = 0.0
    for j in range(n):
        r0 = xs[j] - xi
        r1 = ys[j] - yi
        r2 = zs[j] - zi
        a, b = _pair_coefficients(np.sqrt(r0 * r0 + r1 * r1 + r2 * r2))
        rf = b * (r0 * fx[j] + r1 * fy[j] + r2 * fz[j])
        ax += a * fx[j] + rf * r0
        ay += a * fy[j] + rf * r1
        az += a * fz[j] + rf * r2
    return ax, ay, az


@numba.njit(cache=True, fastmath=True, boundscheck=False)
def _velocities_kernel(xt, ft, vt):
    """``vt = mu ft``, one thread."""
    for i in range(xt.shape[1]):
        vt[0, i], vt[1, i], vt[2, i] = _row_velocity(xt, ft, i)


@numba.njit(cache=True, fastmath=True, boundscheck=False, parallel=True)
def _velocities_kernel_threaded(xt, ft, vt):
    """``vt = mu ft``, rows shared out among numba's threads (the same sums, bit for bit)."""
    for i in numba.prange(xt.shape[1]):
        vt[0, i], vt[1, i], vt[2, i] = _row_velocity(xt, ft, i)


def _threads_for(threads: int) -> int:
    """How many threads the pair loop may use here: at most numba's pool, and one outside
    the main thread (numba's default threading layer may not be entered from two threads
    at once, as in a Dask worker running several points)."""
    if threads <= 1 or threading.current_thread() is not threading.main_thread():
        return 1
    return min(int(threads), numba.config.NUMBA_NUM_THREADS)


def rpy_velocities(positions, forces, out=None, threads: int = 1):
    """Velocities ``v = mu F`` under the RPY mobility, matrix-free.

    Parameters
    ----------
    positions : ndarray, shape (n_beads, 3), float64, in d
    forces : ndarray, shape (n_beads, 3), float64, in F0
    out : ndarray, shape (n_beads, 3), float64, optional
        Filled in place and returned when given.
    threads : int, optional
        Threads for the pair loop (numba); the result is the same bit for bit. Two threads
        on two free cores halve the loop's time from N of about 100 up. Capped at numba's
        thread pool; one thread outside the main thread.

    Returns
    -------
    ndarray, shape (n_beads, 3), in d / tau_d
    """
    x = np.asarray(positions, dtype=np.float64)
    f = np.asarray(forces, dtype=np.float64)
    if x.shape != f.shape or x.ndim != 2 or x.shape[1] != 3:
        raise ValueError(
            f"positions and forces: expected equal shapes (n_beads, 3), got {x.shape} and "
            f"{f.shape}"
        )
    vt = np.empty((3, x.shape[0]))
    xt, ft = np.ascontiguousarray(x.T), np.ascontiguousarray(f.T)
    nthreads = _threads_for(threads)
    if nthreads > 1:
        if numba.get_num_threads() != nthreads:  # a per-thread setting of numba's
            numba.set_num_threads(nthreads)
        _velocities_kernel_threaded(xt, ft, vt)
    else:
        _velocities_kernel(xt, ft, vt)
    if out is None:
        return np.ascontiguousarray(vt.T)
    out[...] = vt.T
    return out


@numba.njit(cache=True)
def _matrix_kernel(x, m):
    n = x.shape[0]
    for i in range(n):
        for k in range(3):
            m[3 * i + k, 3 * i + k] = 1.0
        for j in range(i + 1, n):
            r0 = x[j, 0] - x[i, 0]
            r1 = x[j, 1] - x[i, 1]
            r2 = x[j, 2] - x[i, 2]
            r = np.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
            a, b = _pair_coefficients(r)
            rv = (r0, r1, r2)
            for k in range(3):
                for m_ in range(3):
                    val = b * rv[k] * rv[m_]
                    if k == m_:
                        val += a
                    m[3 * i + k, 3 * j + m_] = val
                    m[3 * j + m_, 3 * i + k] = val


def rpy_matrix(positions):
    """The dense 3N x 3N RPY mobility tensor.

    Parameters
    ----------
    positions : ndarray, shape (n_beads, 3), in d

    Returns
    -------
    ndarray, shape (3 n_beads, 3 n_beads), in units of mu0
        Block ``(i, j)`` is ``mu_ij``; rows and columns are ordered bead-major
        (``x0, y0, z0, x1, ...``), matching ``forces.reshape(-1)``.
    """
    x = np.ascontiguousarray(positions, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 3:
        raise ValueError(f"positions: expected shape (n_beads, 3), got {x.shape}")
    m = np.zeros((3 * x.shape[0], 3 * x.shape[0]))
    _matrix_kernel(x, m)
    return m
