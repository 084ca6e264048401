"""A plain numba program of knotmm's model: the yardstick of the speed targets of issue 12.

What a researcher would write by hand for the model of ``docs/model.md`` (model units: d = 1,
F0 = 1, mu0 = 1): a closed chain of N beads with harmonic bonds ``B/2 (l - l0)^2``, harmonic
bending ``A/2 (phi - pi)^2`` at every bead, the published truncated Lennard-Jones
``eps ((sigma/r)^12 - (sigma/r)^6)`` for ``r < 2^(1/6) sigma`` (no factor 4) between every
pair that is not bonded, gravity ``g`` along -z, and the overlap-corrected Rotne-Prager-Yamakawa
mobility; ``dr/dt = mu F`` advanced by fixed-step Heun (explicit trapezoid). It imports
nothing from knotmm, computes every force in O(N^2) pair loops without a neighbour list, and
writes nothing but a final summary.

The starting shape is read from a file: ``.npy`` (shape (N, 3), in d) or ``.pdb`` (in
Angstrom, 1 d = 10 A, as ``knotmm template torus:2,3 --out t.pdb`` writes it)::

    python benchmarks/numba_chain.py --start t.pdb --duration 400 --dt 0.02

Compiled functions are cached by numba (``cache=True``; ``NUMBA_CACHE_DIR`` moves the
cache). The summary says how long the first call (compilation or cache load) took.
``tests/e2e/test_numba_reference.py`` holds this program to knotmm's Python engine.
"""

from __future__ import annotations

import argparse
import math
import time

import numba
import numpy as np

#: The study's parameters, in the order of the parameter vector ``p`` the kernels take:
#: bond length l0 [d], bond stiffness B [F0/d], bending stiffness A [F0 d],
#: sigma [d], eps [F0 d], gravity g [F0].
STUDY = {"bond_length": 0.6, "bond_stiffness": 50.0, "bending_stiffness": 5.0,
         "lj_sigma": 0.5, "lj_epsilon": 0.25, "gravity": 1.0}


def parameters(**overrides) -> np.ndarray:
    """The parameter vector ``p``, shape (6,), of the kernels (study's values + overrides)."""
    values = dict(STUDY)
    for key, value in overrides.items():
        if key not in values:
            raise KeyError(f"unknown parameter {key!r}; expected one of {', '.join(values)}")
        values[key] = float(value)
    return np.array([values[k] for k in STUDY], dtype=np.float64)


@numba.njit(cache=True)
def bonded_forces(x, p, f):
    """Bonds, bending and gravity: overwrite ``f`` (N, 3) with their forces at ``x`` (N, 3)."""
    n = x.shape[0]
    l0, kb, ka, g = p[0], p[1], p[2], p[5]
    for i in range(n):
        f[i, 0] = 0.0
        f[i, 1] = 0.0
        f[i, 2] = -g
    for i in range(n):  # bond i -- i+1
        j = (i + 1) % n
        dx = x[j, 0] - x[i, 0]
        dy = x[j, 1] - x[i, 1]
        dz = x[j, 2] - x[i, 2]
        r = math.sqrt(dx * dx + dy * dy + dz * dz)
        c = kb * (r - l0) / r  # pulls i towards j when stretched
        f[i, 0] += c * dx
        f[i, 1] += c * dy
        f[i, 2] += c * dz
        f[j, 0] -= c * dx
        f[j, 1] -= c * dy
        f[j, 2] -= c * dz
    for i in range(n):  # angle at bead i between its bonds to a = i-1 and c = i+1
        a = (i - 1) % n
        c = (i + 1) % n
        ux = x[a, 0] - x[i, 0]
        uy = x[a, 1] - x[i, 1]
        uz = x[a, 2] - x[i, 2]
        wx = x[c, 0] - x[i, 0]
        wy = x[c, 1] - x[i, 1]
        wz = x[c, 2] - x[i, 2]
        lu = math.sqrt(ux * ux + uy * uy + uz * uz)
        lw = math.sqrt(wx * wx + wy * wy + wz * wz)
        cx = uy * wz - uz * wy
        cy = uz * wx - ux * wz
        cz = ux * wy - uy * wx
        cross = math.sqrt(cx * cx + cy * cy + cz * cz)
        dot = ux * wx + uy * wy + uz * wz
        theta = math.atan2(cross, dot)
        sin_t = cross / (lu * lw)
        cos_t = dot / (lu * lw)
        # dE/dtheta / sin(theta); (theta - pi) / sin(theta) -> -1 as theta -> pi
        gs = ka * (theta - math.pi) / sin_t if sin_t > 1e-12 else -ka
        # dtheta/dx_a = (cos u^ - w^) / (|u| sin), dtheta/dx_c = (cos w^ - u^) / (|w| sin)
        fax = -gs * (cos_t * ux / lu - wx / lw) / lu
        fay = -gs * (cos_t * uy / lu - wy / lw) / lu
        faz = -gs * (cos_t * uz / lu - wz / lw) / lu
        fcx = -gs * (cos_t * wx / lw - ux / lu) / lw
        fcy = -gs * (cos_t * wy / lw - uy / lu) / lw
        fcz = -gs * (cos_t * wz / lw - uz / lu) / lw
        f[a, 0] += fax
        f[a, 1] += fay
        f[a, 2] += faz
        f[c, 0] += fcx
        f[c, 1] += fcy
        f[c, 2] += fcz
        f[i, 0] -= fax + fcx
        f[i, 1] -= fay + fcy
        f[i, 2] -= faz + fcz


@numba.njit(cache=True)
def steric_forces(x, p, f):
    """Add the truncated LJ forces of every non-bonded pair (O(N^2) half loop) to ``f``."""
    n = x.shape[0]
    s2 = p[3] * p[3]
    eps = p[4]
    rc2 = 2.0 ** (1.0 / 3.0) * s2
    for i in range(n - 1):
        xi = x[i, 0]
        yi = x[i, 1]
        zi = x[i, 2]
        for j in range(i + 2, n):
            if i == 0 and j == n - 1:
                continue  # the ring's closing bond
            dx = xi - x[j, 0]
            dy = yi - x[j, 1]
            dz = zi - x[j, 2]
            r2 = dx * dx + dy * dy + dz * dz
            if r2 < rc2:
                sr6 = (s2 / r2) ** 3
                c = eps * (12.0 * sr6 * sr6 - 6.0 * sr6) / r2  # |F| / r
                f[i, 0] += c * dx
                f[i, 1] += c * dy
                f[i, 2] += c * dz
                f[j, 0] -= c * dx
                f[j, 1] -= c * dy
                f[j, 2] -= c * dz


@numba.njit(cache=True)
def forces(x, p, f):
    """Total force on every bead: overwrite ``f`` (N, 3) (in F0) at positions ``x`` (in d)."""
    bonded_forces(x, p, f)
    steric_forces(x, p, f)


@numba.njit(cache=True)
def mobility(x, f, v):
    """RPY velocities ``v_i = sum_j mu_ij f_j`` (overwrite ``v``; O(N^2) half loop).

    ``mu_ii = I``; ``r >= 1``: ``3/(8r) [(1 + 1/(6r^2)) I + (1 - 1/(2r^2)) rhat rhat]``;
    ``r < 1``: ``(1 - 9r/16) I + (3r/16) rhat rhat`` (d = mu0 = 1).
    """
    n = x.shape[0]
    for i in range(n):
        v[i, 0] = f[i, 0]
        v[i, 1] = f[i, 1]
        v[i, 2] = f[i, 2]
    for i in range(n - 1):
        for j in range(i + 1, n):
            dx = x[i, 0] - x[j, 0]
            dy = x[i, 1] - x[j, 1]
            dz = x[i, 2] - x[j, 2]
            r2 = dx * dx + dy * dy + dz * dz
            r = math.sqrt(r2)
            inv = 1.0 / r  # one division per pair
            inv2 = inv * inv
            if r >= 1.0:
                a = 0.375 * inv * (1.0 + inv2 / 6.0)
                b = 0.375 * inv * (1.0 - 0.5 * inv2) * inv2  # times the unnormalised dx dx^T
            else:
                a = 1.0 - 0.5625 * r
                b = 0.1875 * inv
            dfj = b * (dx * f[j, 0] + dy * f[j, 1] + dz * f[j, 2])
            dfi = b * (dx * f[i, 0] + dy * f[i, 1] + dz * f[i, 2])
            v[i, 0] += a * f[j, 0] + dfj * dx
            v[i, 1] += a * f[j, 1] + dfj * dy
            v[i, 2] += a * f[j, 2] + dfj * dz
            v[j, 0] += a * f[i, 0] + dfi * dx
            v[j, 1] += a * f[i, 1] + dfi * dy
            v[j, 2] += a * f[i, 2] + dfi * dz


@numba.njit(cache=True)
def velocity(x, p, f, v):
    """``v = mu(x) F(x)`` (in d/tau_d); ``f`` and ``v`` are (N, 3) work arrays."""
    forces(x, p, f)
    mobility(x, f, v)


@numba.njit(cache=True)
def heun(x, p, dt, steps):
    """``steps`` Heun steps of length ``dt`` (tau_d) from ``x`` (N, 3); returns the new x."""
    n = x.shape[0]
    y = x.copy()
    y1 = np.empty_like(y)
    f = np.empty_like(y)
    k1 = np.empty_like(y)
    k2 = np.empty_like(y)
    for _ in range(steps):
        velocity(y, p, f, k1)
        for i in range(n):
            for k in range(3):
                y1[i, k] = y[i, k] + dt * k1[i, k]
        velocity(y1, p, f, k2)
        for i in range(n):
            for k in range(3):
                y[i, k] += 0.5 * dt * (k1[i, k] + k2[i, k])
    return y


def read_start(path: str) -> np.ndarray:
    """Positions (N, 3) in d from ``.npy`` (in d) or ``.pdb`` (ATOM/HETATM lines, in Angstrom)."""
    if path.endswith(".npy"):
        return np.ascontiguousarray(np.load(path), dtype=np.float64)
    rows = []
    with open(path) as fh:
        for line in fh:
            if line.startswith(("ATOM", "HETATM")):
                rows.append([float(line[30:38]), float(line[38:46]), float(line[46:54])])
    return np.array(rows, dtype=np.float64) / 10.0


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--start", required=True, help="starting positions (.npy in d, .pdb)")
    parser.add_argument("--duration", type=float, default=400.0, help="tau_d")
    parser.add_argument("--dt", type=float, default=0.02, help="Heun step, tau_d")
    for key, value in STUDY.items():
        parser.add_argument("--" + key.replace("_", "-"), type=float, default=value)
    args = parser.parse_args(argv)
    x0 = read_start(args.start)
    p = parameters(**{k: getattr(args, k) for k in STUDY})
    steps = int(round(args.duration / args.dt))
    t0 = time.perf_counter()
    heun(x0, p, args.dt, 0)  # compiles, or loads the cache
    t1 = time.perf_counter()
    x = heun(x0, p, args.dt, steps)
    t2 = time.perf_counter()
    com0 = x0.mean(axis=0)
    com = x.mean(axis=0)
    bonds = np.linalg.norm(np.roll(x, -1, axis=0) - x, axis=1)
    speed = (com0[2] - com[2]) / (steps * args.dt) if steps else float("nan")
    print(f"numba_chain: N={len(x)} heun dt={args.dt:g} steps={steps} evaluations={2 * steps} "
          f"t={steps * args.dt:g} tau_d; final centre of mass {com[0]:.6f} {com[1]:.6f} "
          f"{com[2]:.6f} d, mean sinking speed {speed:.6f} d/tau_d, bonds {bonds.min():.4f}-"
          f"{bonds.max():.4f} d; wall: first call {t1 - t0:.3f} s, "
          f"loop {t2 - t1:.3f} s ({(t2 - t1) / max(2 * steps, 1) * 1e6:.1f} us/evaluation)")


if __name__ == "__main__":
    main()
