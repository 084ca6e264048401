"""Probe (issue 33): a Brownian try that reuses the last accepted velocity, and what it costs.

``ito_heun_adaptive`` takes Heun's step and estimates its error as ``h/2 (v(yE) - v(y0))``,
``yE = y0 + h v(y0) + W`` the Euler-Maruyama point: two evaluations a step, the second at
``yE`` and the next step's first at the Heun point. Taking ``yE`` itself as the step
(adaptive Euler-Maruyama with the same error estimate, as Lamba, Mattingly and Stuart's
adaptive scheme) makes ``v(yE)`` the next step's first velocity: one evaluation a step. This
program runs both, in numba, with the plugin's control (PI, error order 1.5, the maximum
bead norm against the tolerance, a rejected try's Wiener increment kept and split by
Brownian bridges), on T(2,3), N = 90, the study's parameters, gravity 0, Cholesky noise, and
prints the accepted steps, rejections, evaluations and the bond-length variance over the
Boltzmann value of the stretching energy (frames every 0.05 tau_d, the first 10 % dropped,
standard error from 10 blocks)::

    python benchmarks/probe_fsal_brownian.py PE TOLERANCE FSAL DURATION SEED
    python benchmarks/probe_fsal_brownian.py 2 0.02 1 80 1   # FSAL Euler-Maruyama, Pe = 2

Results: ``benchmarks/README.md`` (``adaptive``). Units: d, tau_d, F0.
"""
import math
import sys
import time
from pathlib import Path

import numba
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the numba yardsticks sit here
from numba_brownian import cholesky, rpy_matrix, velocity  # noqa: E402
from numba_chain import parameters  # noqa: E402

from knotmm.shapes import torus_knot  # noqa: E402


@numba.njit(cache=True)
def take_increment(need, dw, pend_span, pend_dw, npend):
    """``dw`` (3N,) = the Wiener increment over ``need`` tau_d: the kept increments of
    rejected tries first (a Brownian bridge splits one that spans more), then fresh normals.
    Returns the number of kept increments left."""
    dw[:] = 0.0
    while need > 0.0:
        if npend == 0:
            for i in range(dw.shape[0]):
                dw[i] += math.sqrt(need) * np.random.standard_normal()
            return npend
        span = pend_span[npend - 1]
        if span <= need * (1 + 1e-12):  # the whole kept interval fits
            dw += pend_dw[npend - 1]
            need = 0.0 if span >= need * (1 - 1e-12) else need - span
            npend -= 1
            continue
        for i in range(dw.shape[0]):  # the bridge's value at `need`
            part = (need / span * pend_dw[npend - 1, i]
                    + math.sqrt(need * (span - need) / span) * np.random.standard_normal())
            pend_dw[npend - 1, i] -= part
            dw[i] += part
        pend_span[npend - 1] = span - need
        return npend
    return npend


@numba.njit(cache=True)
def run(x, p, kt, tol, t_end, fsal, seed, frame_dt, out_bonds):
    """Integrate from ``x`` (N, 3) to ``t_end``, writing the ring's bond lengths every
    ``frame_dt`` into ``out_bonds`` (frames, N); ``fsal``: Euler-Maruyama steps (one
    evaluation), else Heun's (two). Returns (accepted steps, rejected tries, evaluations)."""
    np.random.seed(seed)
    n = x.shape[0]
    y = x.copy()
    f = np.empty_like(y)
    v0 = np.empty_like(y)
    v1 = np.empty_like(y)
    y_euler = np.empty_like(y)
    w = np.empty_like(y)
    m = np.empty((3 * n, 3 * n))
    pend_span = np.zeros(64)
    pend_dw = np.zeros((64, 3 * n))
    npend = 0
    dw = np.empty(3 * n)
    h, err_old, t = 1e-3, 1.0, 0.0
    velocity(y, p, f, v0)
    steps, rejected, evals, frame, next_frame = 0, 0, 1, 0, frame_dt
    while t < t_end - 1e-12 and frame < out_bonds.shape[0]:
        rpy_matrix(y, m)
        lower = cholesky(m)  # B(y) once for every try from y
        while True:
            hh = min(h, next_frame - t)
            npend = take_increment(hh, dw, pend_span, pend_dw, npend)
            ww = math.sqrt(2.0 * kt) * (lower @ dw)
            for i in range(n):
                for k in range(3):
                    w[i, k] = ww[3 * i + k]
                    y_euler[i, k] = y[i, k] + hh * v0[i, k] + w[i, k]
            velocity(y_euler, p, f, v1)
            evals += 1
            e = 0.0
            for i in range(n):
                s = 0.0
                for k in range(3):
                    d = 0.5 * hh * (v1[i, k] - v0[i, k])
                    s += d * d
                e = max(e, math.sqrt(s))
            e /= tol
            if e <= 1.0:
                fac = 5.0
                if e != 0.0:
                    fac = min(5.0, max(0.2, 0.9 * e ** (-0.7 / 1.5) * err_old ** (0.4 / 1.5)))
                if hh >= h or fac < 1.0:  # a step clipped to land on a frame keeps its size
                    h = min(1.0, hh * fac)
                err_old = max(e, 1e-4)
                break
            pend_span[npend] = hh  # a rejected try's increment is kept
            pend_dw[npend] = dw
            npend += 1
            rejected += 1
            h = hh * max(0.1, 0.9 * e ** (-1.0 / 1.5))
        t += hh
        steps += 1
        if fsal:
            y[:] = y_euler
            v0[:] = v1
        else:
            for i in range(n):
                for k in range(3):
                    y[i, k] += 0.5 * hh * (v0[i, k] + v1[i, k]) + w[i, k]
            velocity(y, p, f, v0)
            evals += 1
        if t >= next_frame - 1e-12:
            for i in range(n):
                j = (i + 1) % n
                out_bonds[frame, i] = math.sqrt((y[j, 0] - y[i, 0]) ** 2 + (y[j, 1] - y[i, 1]) ** 2
                                                + (y[j, 2] - y[i, 2]) ** 2)
            frame += 1
            next_frame += frame_dt
    return steps, rejected, evals


def boltzmann_variance(stiffness, rest, kt):
    """Variance of a bond length under ``p(l) ~ l^2 exp(-B (l - l0)^2 / (2 kT))`` (d^2)."""
    sd = math.sqrt(kt / stiffness)
    grid = np.linspace(rest - 12 * sd, rest + 12 * sd, 200_001)
    weight = grid * grid * np.exp(-stiffness * (grid - rest) ** 2 / (2 * kt))
    mean = (weight * grid).sum() / weight.sum()
    return float((weight * (grid - mean) ** 2).sum() / weight.sum())


def main(argv):
    """Run one case; print and return (variance ratio, its s.e., steps, evaluations)."""
    pe, tol, fsal, duration, seed = (float(argv[0]), float(argv[1]), int(argv[2]),
                                     float(argv[3]), int(argv[4]))
    p = parameters(gravity=0.0)
    kt = 1.0 / pe
    x = torus_knot(2, 3, 90)
    frame_dt = 0.05
    bonds = np.zeros((int(round(duration / frame_dt)), 90))
    run(x, p, kt, tol, 0.01, fsal, seed, 0.01, np.zeros((1, 90)))  # compiles
    t0 = time.perf_counter()
    steps, rejected, evals = run(x, p, kt, tol, duration, fsal, seed, frame_dt, bonds)
    wall = time.perf_counter() - t0
    kept = bonds[len(bonds) // 10:]
    ref = boltzmann_variance(p[1], p[0], kt)
    blocks = [block.var() / ref for block in np.array_split(kept, 10)]
    ratio, se = float(np.mean(blocks)), float(np.std(blocks, ddof=1) / math.sqrt(10))
    print(f"Pe={pe:g} tol={tol:g} {'fsal_em' if fsal else 'heun'} seed={seed}: steps {steps} "
          f"rejected {rejected} evaluations {evals} wall {wall:.2f} s; bond variance / "
          f"Boltzmann {ratio:.4f} +- {se:.4f}")
    return ratio, se, steps, evals


if __name__ == "__main__":
    main(sys.argv[1:])
