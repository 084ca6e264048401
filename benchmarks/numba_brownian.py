"""A plain numba + LAPACK program of knotmm's Brownian dynamics: the yardstick of issue 12.

The Brownian counterpart of ``numba_chain.py`` (whose force and mobility kernels it imports:
the same model, model units d = F0 = mu0 = 1) at a finite Peclet number ``Pe``, ``kT = 1/Pe``
in F0 d. The noise is exact: ``B xi`` with ``B = L`` the lower Cholesky factor of the dense
3N x 3N Rotne-Prager-Yamakawa mobility (``np.linalg.cholesky`` inside numba, which calls
LAPACK's ``dpotrf`` through scipy), ``xi`` standard normal drawn by numba. Three schemes, those
of ``knotmm.dynamics.brownian`` (``v = mu F``)::

    euler_maruyama       y1 = y + h v(y) + sqrt(2 kT h) L(y) xi         (default h = 0.002)
    ito_heun             W = sqrt(2 kT h) L(y) xi;  y* = y + h v(y) + W;
                         y1 = y + h/2 (v(y) + v(y*)) + W                 (default h = 0.002)
    leimkuhler_matthews  p = y + h v(y) + k;  k <- sqrt(kT h / 2) L(p) xi;  y1 = p + k
                         (the first held kick k is drawn at the start)   (default h = 0.01)

It imports nothing from knotmm. Start from ``.npy`` (in d) or ``.pdb`` (Angstrom)::

    knotmm template torus:2,3 --beads 90 --out t.pdb
    python benchmarks/numba_brownian.py --start t.pdb --peclet 2 --gravity 0 --duration 4

and it prints one summary line: the time of the first call (compilation or numba's cache),
the loop's wall time per step (compilation excluded), the bond-length spread. ``--profile``
adds where a step's time goes (forces, RPY matrix, Cholesky, rest), from the kernels timed
one by one at the final positions. ``tests/e2e/test_numba_brownian.py`` holds it to knotmm.
LAPACK runs on ``--blas-threads`` threads (default 1, as knotmm's run loop: OpenBLAS's
threads on a busy 2-core machine made one factorisation 20-200 ms instead of 0.5 ms).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numba
import numpy as np
from threadpoolctl import threadpool_limits

sys.path.insert(0, str(Path(__file__).resolve().parent))  # numba_chain.py sits next to this
from numba_chain import STUDY, forces, mobility, parameters, read_start  # noqa: E402

#: Scheme name -> default step (tau_d), as knotmm's registry.
SCHEMES = {"euler_maruyama": 0.002, "ito_heun": 0.002, "leimkuhler_matthews": 0.01}


@numba.njit(cache=True)
def rpy_matrix(x, m):
    """Overwrite ``m`` (3N, 3N) with the RPY mobility at ``x`` (N, 3); bead-major order.

    ``mu_ii = I``; ``r >= 1``: ``3/(8r) [(1 + 1/(6r^2)) I + (1 - 1/(2r^2)) rhat rhat]``;
    ``r < 1``: ``(1 - 9r/16) I + (3r/16) rhat rhat``.
    """
    n = x.shape[0]
    for i in range(n):
        for k in range(3):
            for q in range(3):
                m[3 * i + k, 3 * i + q] = 1.0 if k == q else 0.0
        for j in range(i + 1, n):
            ux = x[j, 0] - x[i, 0]
            uy = x[j, 1] - x[i, 1]
            uz = x[j, 2] - x[i, 2]
            r = math.sqrt(ux * ux + uy * uy + uz * uz)
            ux /= r
            uy /= r
            uz /= r
            if r >= 1.0:
                a = 3.0 / (8.0 * r) * (1.0 + 1.0 / (6.0 * r * r))
                b = 3.0 / (8.0 * r) * (1.0 - 1.0 / (2.0 * r * r))
            else:
                a = 1.0 - 9.0 * r / 16.0
                b = 3.0 * r / 16.0
            u = (ux, uy, uz)
            for k in range(3):
                for q in range(3):
                    val = b * u[k] * u[q] + (a if k == q else 0.0)
                    m[3 * i + k, 3 * j + q] = val  # mu_ij, and mu_ji = mu_ij^T
                    m[3 * j + q, 3 * i + k] = val


@numba.njit(cache=True)
def cholesky(m):
    """Lower Cholesky factor of ``m`` (LAPACK ``dpotrf``, a new array)."""
    return np.linalg.cholesky(m)


@numba.njit(cache=True)
def draw(xi, k, z):
    """Fill ``z`` (3N,) with row ``k`` of ``xi`` if ``xi`` has rows, else with fresh normals."""
    if xi.shape[0] > 0:
        z[:] = xi[k]
    else:
        for i in range(z.shape[0]):
            z[i] = np.random.standard_normal()


@numba.njit(cache=True)
def noise(x, z, scale, m, out):
    """``out = scale L(x) z`` (N, 3) with ``L L^T = mu(x)``; ``m`` is a (3N, 3N) work array."""
    rpy_matrix(x, m)
    w = cholesky(m) @ z
    for i in range(x.shape[0]):
        for k in range(3):
            out[i, k] = scale * w[3 * i + k]


@numba.njit(cache=True)
def velocity(y, p, f, v):
    """``v = mu(y) F(y)`` (N, 3); ``f`` (N, 3) a work array for the forces."""
    forces(y, p, f)
    mobility(y, f, v)


@numba.njit(cache=True)
def euler_maruyama(x, p, kt, dt, steps, seed, xi):
    """``steps`` Euler-Maruyama steps of ``dt`` from ``x`` (N, 3): one force evaluation and
    one Cholesky factorisation a step; returns the new positions (``xi``: as :func:`ito_heun`).
    """
    np.random.seed(seed)
    n = x.shape[0]
    y = x.copy()
    f = np.empty_like(y)
    v = np.empty_like(y)
    w = np.empty_like(y)
    z = np.empty(3 * n)
    m = np.empty((3 * n, 3 * n))
    scale = math.sqrt(2.0 * kt * dt)
    for s in range(steps):
        draw(xi, s, z)
        noise(y, z, scale, m, w)
        velocity(y, p, f, v)
        for i in range(n):
            for k in range(3):
                y[i, k] += dt * v[i, k] + w[i, k]
    return y


@numba.njit(cache=True)
def ito_heun(x, p, kt, dt, steps, seed, xi):
    """``steps`` ito_heun steps of ``dt`` from ``x`` (N, 3); returns the new positions.

    ``xi`` (steps, 3N): the standard normals to use, or shape (0, 3N): draw them (numba's
    generator, seeded with ``seed``).
    """
    np.random.seed(seed)
    n = x.shape[0]
    y = x.copy()
    ys = np.empty_like(y)
    f = np.empty_like(y)
    v0 = np.empty_like(y)
    v1 = np.empty_like(y)
    w = np.empty_like(y)
    z = np.empty(3 * n)
    m = np.empty((3 * n, 3 * n))
    scale = math.sqrt(2.0 * kt * dt)
    for s in range(steps):
        draw(xi, s, z)
        noise(y, z, scale, m, w)
        velocity(y, p, f, v0)
        for i in range(n):
            for k in range(3):
                ys[i, k] = y[i, k] + dt * v0[i, k] + w[i, k]
        velocity(ys, p, f, v1)
        for i in range(n):
            for k in range(3):
                y[i, k] += 0.5 * dt * (v0[i, k] + v1[i, k]) + w[i, k]
    return y


@numba.njit(cache=True)
def leimkuhler_matthews(x, p, kt, dt, steps, seed, xi):
    """``steps`` Leimkuhler-Matthews steps of ``dt`` from ``x``; returns the new positions.

    ``xi`` (steps + 1, 3N): row 0 makes the first held kick at ``x``, row ``s + 1`` the kick of
    step ``s``; shape (0, 3N): draw them (seeded with ``seed``).
    """
    np.random.seed(seed)
    n = x.shape[0]
    y = x.copy()
    f = np.empty_like(y)
    v = np.empty_like(y)
    kick = np.empty_like(y)
    z = np.empty(3 * n)
    m = np.empty((3 * n, 3 * n))
    scale = math.sqrt(0.5 * kt * dt)
    draw(xi, 0, z)
    noise(y, z, scale, m, kick)
    for s in range(steps):
        velocity(y, p, f, v)
        for i in range(n):
            for k in range(3):
                y[i, k] += dt * v[i, k] + kick[i, k]  # y is now p
        draw(xi, s + 1, z)
        noise(y, z, scale, m, kick)
        for i in range(n):
            for k in range(3):
                y[i, k] += kick[i, k]
    return y


def run(scheme, x, p, kt, dt, steps, seed=0, xi=None):
    """Dispatch to :func:`euler_maruyama`, :func:`ito_heun` or :func:`leimkuhler_matthews`
    (``xi`` None: draw)."""
    if xi is None:
        xi = np.empty((0, 3 * x.shape[0]))
    fn = {"euler_maruyama": euler_maruyama, "ito_heun": ito_heun,
          "leimkuhler_matthews": leimkuhler_matthews}[scheme]
    return fn(np.ascontiguousarray(x, dtype=np.float64), p, float(kt), float(dt), int(steps),
              int(seed), np.ascontiguousarray(xi, dtype=np.float64))


def per_call(fn, budget=0.5, batches=5, clock=time.perf_counter):
    """Microseconds per call of ``fn`` on ``clock`` (wall; ``time.process_time``: CPU time),
    the median of ``batches`` batches of ``budget / batches`` s each."""
    fn()
    out = []
    for _ in range(batches):
        calls, t0 = 0, clock()
        while calls == 0 or clock() - t0 < budget / batches:  # at least one call
            fn()
            calls += 1
        out.append((clock() - t0) / calls)
    return 1e6 * float(np.median(out))


def profile(x, p, budget=0.5, clock=time.perf_counter) -> dict:
    """Microseconds per call of each kernel at positions ``x`` (one at a time, warm)."""
    n = x.shape[0]
    f = np.empty_like(x)
    v = np.empty_like(x)
    m = np.empty((3 * n, 3 * n))
    rpy_matrix(x, m)
    lower = cholesky(m)
    z = np.random.default_rng(0).standard_normal(3 * n)
    out = {
        "forces": per_call(lambda: forces(x, p, f), budget, clock=clock),
        "mobility": per_call(lambda: mobility(x, f, v), budget, clock=clock),
        "matrix": per_call(lambda: rpy_matrix(x, m), budget, clock=clock),
        "cholesky": per_call(lambda: cholesky(m), budget, clock=clock),
        "L xi": per_call(lambda: lower @ z, budget, clock=clock),
    }
    return out


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--start", required=True, help="starting positions (.npy in d, .pdb)")
    parser.add_argument("--scheme", choices=list(SCHEMES), default="ito_heun")
    parser.add_argument("--peclet", type=float, default=2.0, help="Pe = F0 d / kT")
    parser.add_argument("--duration", type=float, default=4.0, help="tau_d")
    parser.add_argument("--dt", type=float, default=None, help="tau_d (default: per scheme)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--profile", action="store_true", help="also time each kernel")
    parser.add_argument("--blas-threads", type=int, default=1, help="LAPACK threads")
    for key, value in STUDY.items():
        parser.add_argument("--" + key.replace("_", "-"), type=float, default=value)
    args = parser.parse_args(argv)
    import scipy.linalg.cython_lapack  # noqa: F401 - numba's LAPACK: loaded before the limit

    with threadpool_limits(limits=args.blas_threads, user_api="blas"):
        _main(args)


def _main(args) -> None:
    dt = SCHEMES[args.scheme] if args.dt is None else args.dt
    x0 = read_start(args.start)
    p = parameters(**{k: getattr(args, k) for k in STUDY})
    kt = 1.0 / args.peclet
    steps = int(round(args.duration / dt))
    t0 = time.perf_counter()
    run(args.scheme, x0, p, kt, dt, 1, args.seed)  # compiles, or loads the cache
    t1 = time.perf_counter()
    x = run(args.scheme, x0, p, kt, dt, steps, args.seed)
    t2 = time.perf_counter()
    bonds = np.linalg.norm(np.roll(x, -1, axis=0) - x, axis=1)
    print(f"numba_brownian: N={len(x)} {args.scheme} dt={dt:g} Pe={args.peclet:g} "
          f"steps={steps} t={steps * dt:g} tau_d; bonds mean {bonds.mean():.4f} sd "
          f"{bonds.std():.4f} d (sqrt(kT/B) = {math.sqrt(kt / p[1]):.4f}); wall: first call "
          f"{t1 - t0:.3f} s, loop {t2 - t1:.3f} s ({(t2 - t1) / max(steps, 1) * 1e6:.1f} "
          f"us/step)")
    if args.profile:
        split = profile(x, p)
        print("  per call [us]: " + ", ".join(f"{k} {t:.1f}" for k, t in split.items()))


if __name__ == "__main__":
    main()
