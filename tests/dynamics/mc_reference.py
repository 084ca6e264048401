"""A Metropolis Monte Carlo of the bead chain's energy: the reference for Brownian equilibrium.

It samples ``exp(-E / kT)`` with ``E`` the model's energy (docs/model.md, the same terms and
parameters as ``tests/reference_model.py``): harmonic bonds ``B/2 (l - l0)^2``, harmonic bending
``A/2 (phi - pi)^2`` at every bead (``phi`` the angle at bead ``i`` between the bonds to its two
neighbours), and the truncated Lennard-Jones term ``eps ((sigma/r)^12 - (sigma/r)^6)`` for
``r < 2^(1/6) sigma`` between every pair that is not bonded (1-3 pairs included); no gravity.
Nothing here knows of mobilities, time steps or knotmm: it imports only numpy and numba, so that
it can judge the dynamics independently. Strands may pass through each other, as they may in
the dynamics (the steric range, 0.56 d, is shorter than a bond): nothing but the energy is used.

Moves: one bead, chosen at random, displaced uniformly in a cube of half-width ``delta``;
accepted with probability ``min(1, exp(-dE / kT))``, ``dE`` from the terms that involve that bead
only (two bonds, three bending angles, its steric pairs: O(N) per move). ``delta`` is tuned
towards an acceptance of about 0.4 during the burn-in only, then kept fixed (a symmetric
proposal with a fixed width: detailed balance holds in the production run).

Observables (``ring_observables``): bond lengths ``l_k = |r_{k+1} - r_k|``, the cosine of the
angle between successive bond vectors ``cos theta_k = e_{k-1} . e_k`` (``theta = pi - phi``,
the angle the bending term penalises), and ``|r_{k+2} - r_k|``. Each sample is reduced to its
averages over the chain (``<l>``, ``<l^2>``, ``<cos>``, ``<|r_{k+2} - r_k|>``); statistical errors
come from a jackknife over contiguous blocks much longer than the autocorrelation time, and
:func:`blocking_error` gives the Flyvbjerg-Petersen blocking curve to check that.

Model units: d = 1, F0 = 1; ``kT = 1 / Pe`` in F0 d.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numba
import numpy as np

#: The study's parameters (docs/model.md); the same values as reference_model.STUDY.
STUDY = dict(
    bond_length=0.6,
    bond_stiffness=50.0,
    bending_stiffness=5.0,
    lj_sigma=0.5,
    lj_epsilon=0.25,
)

#: Names of the per-sample chain averages, in the order of the columns of ``series``.
SERIES = ("bond", "bond_sq", "cos", "d13")


# -- the local energy ---------------------------------------------------------------------------
@numba.njit(cache=True, inline="always")
def _bend(x, a, i, c, A):
    """``A/2 (phi - pi)^2`` with ``phi`` the angle at bead i between x[a] - x[i] and x[c] - x[i]."""
    ux = x[a, 0] - x[i, 0]
    uy = x[a, 1] - x[i, 1]
    uz = x[a, 2] - x[i, 2]
    wx = x[c, 0] - x[i, 0]
    wy = x[c, 1] - x[i, 1]
    wz = x[c, 2] - x[i, 2]
    cx = uy * wz - uz * wy
    cy = uz * wx - ux * wz
    cz = ux * wy - uy * wx
    phi = math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), ux * wx + uy * wy + uz * wz)
    return 0.5 * A * (phi - math.pi) ** 2


@numba.njit(cache=True, inline="always")
def _bond(x, i, j, B, l0):
    dx = x[j, 0] - x[i, 0]
    dy = x[j, 1] - x[i, 1]
    dz = x[j, 2] - x[i, 2]
    return 0.5 * B * (math.sqrt(dx * dx + dy * dy + dz * dz) - l0) ** 2


@numba.njit(cache=True)
def local_energy(x, i, closed, B, l0, A, sigma, eps):
    """Every energy term that involves bead ``i`` (F0 d), for a ring or an open chain."""
    n = x.shape[0]
    rc2 = 2.0 ** (1.0 / 3.0) * sigma * sigma
    s6 = sigma**6
    e = 0.0
    # bonds (i-1, i) and (i, i+1)
    if closed:
        e += _bond(x, (i - 1) % n, i, B, l0) + _bond(x, i, (i + 1) % n, B, l0)
    else:
        if i > 0:
            e += _bond(x, i - 1, i, B, l0)
        if i < n - 1:
            e += _bond(x, i, i + 1, B, l0)
    # bending at beads i-1, i, i+1
    if A != 0.0:
        for k in (i - 1, i, i + 1):
            if closed:
                kk = k % n
                e += _bend(x, (kk - 1) % n, kk, (kk + 1) % n, A)
            elif 1 <= k <= n - 2:
                e += _bend(x, k - 1, k, k + 1, A)
    # steric pairs: every bead that is not bonded to i
    if eps != 0.0:
        for j in range(n):
            dij = abs(j - i)
            if dij <= 1 or (closed and dij == n - 1):
                continue
            dx = x[j, 0] - x[i, 0]
            dy = x[j, 1] - x[i, 1]
            dz = x[j, 2] - x[i, 2]
            r2 = dx * dx + dy * dy + dz * dz
            if r2 < rc2:
                q6 = s6 / (r2 * r2 * r2)
                e += eps * (q6 * q6 - q6)
    return e


@numba.njit(cache=True)
def total_energy(x, closed, B, l0, A, sigma, eps):
    """The whole energy (F0 d), from the same kernels (each bond, bend and pair once)."""
    n = x.shape[0]
    rc2 = 2.0 ** (1.0 / 3.0) * sigma * sigma
    s6 = sigma**6
    e = 0.0
    nb = n if closed else n - 1
    for k in range(nb):
        e += _bond(x, k, (k + 1) % n, B, l0)
    if A != 0.0:
        for k in range(n):
            if closed:
                e += _bend(x, (k - 1) % n, k, (k + 1) % n, A)
            elif 1 <= k <= n - 2:
                e += _bend(x, k - 1, k, k + 1, A)
    if eps != 0.0:
        for i in range(n):
            for j in range(i + 2, n):
                if closed and i == 0 and j == n - 1:
                    continue
                dx = x[j, 0] - x[i, 0]
                dy = x[j, 1] - x[i, 1]
                dz = x[j, 2] - x[i, 2]
                r2 = dx * dx + dy * dy + dz * dz
                if r2 < rc2:
                    q6 = s6 / (r2 * r2 * r2)
                    e += eps * (q6 * q6 - q6)
    return e


# -- observables ----------------------------------------------------------------------------------
@numba.njit(cache=True)
def _observe(x, closed, out):
    """Chain averages of l, l^2, cos theta and |r_{k+2} - r_k| into out[0:4]."""
    n = x.shape[0]
    nb = n if closed else n - 1
    sl = 0.0
    sl2 = 0.0
    sc = 0.0
    sd = 0.0
    # bond vectors
    ex = np.empty(nb)
    ey = np.empty(nb)
    ez = np.empty(nb)
    for k in range(nb):
        j = (k + 1) % n
        dx = x[j, 0] - x[k, 0]
        dy = x[j, 1] - x[k, 1]
        dz = x[j, 2] - x[k, 2]
        ell = math.sqrt(dx * dx + dy * dy + dz * dz)
        sl += ell
        sl2 += ell * ell
        ex[k] = dx / ell
        ey[k] = dy / ell
        ez[k] = dz / ell
    m = n if closed else n - 2
    for k in range(m):
        k1 = (k + 1) % nb
        sc += ex[k] * ex[k1] + ey[k] * ey[k1] + ez[k] * ez[k1]
        j = (k + 2) % n
        dx = x[j, 0] - x[k, 0]
        dy = x[j, 1] - x[k, 1]
        dz = x[j, 2] - x[k, 2]
        sd += math.sqrt(dx * dx + dy * dy + dz * dz)
    out[0] = sl / nb
    out[1] = sl2 / nb
    out[2] = sc / m if m > 0 else np.nan  # a dimer has no angle
    out[3] = sd / m if m > 0 else np.nan


def ring_observables(x, closed: bool = True) -> np.ndarray:
    """``[<l>, <l^2>, <cos theta>, <|r_{k+2} - r_k|>]`` of one configuration (chain averages)."""
    out = np.empty(4)
    _observe(np.ascontiguousarray(x, dtype=np.float64), closed, out)
    return out


def full_observables(x, closed: bool = True) -> dict:
    """Per-bond lengths, per-bead cosines and 1-3 distances of one configuration (numpy)."""
    x = np.asarray(x, dtype=np.float64)
    n = len(x)
    if closed:
        b = np.roll(x, -1, axis=0) - x
        d13 = np.linalg.norm(np.roll(x, -2, axis=0) - x, axis=1)
    else:
        b = x[1:] - x[:-1]
        d13 = np.linalg.norm(x[2:] - x[:-2], axis=1)
    ell = np.linalg.norm(b, axis=1)
    e = b / ell[:, None]
    cos = np.sum(e * np.roll(e, -1, axis=0), axis=1) if closed else np.sum(e[:-1] * e[1:], 1)
    assert len(cos) == (n if closed else n - 2)
    return {"bond": ell, "cos": cos, "d13": d13}


# -- the Markov chain ----------------------------------------------------------------------------
@numba.njit(cache=True)
def _seed(seed):
    np.random.seed(seed)


@numba.njit(cache=True, inline="always")
def _segment_hits_triangle(a, b, p0, p1, p2):
    """Whether the segment a-b meets the triangle (p0, p1, p2) (Moller-Trumbore)."""
    e1x = p1[0] - p0[0]
    e1y = p1[1] - p0[1]
    e1z = p1[2] - p0[2]
    e2x = p2[0] - p0[0]
    e2y = p2[1] - p0[1]
    e2z = p2[2] - p0[2]
    dx = b[0] - a[0]
    dy = b[1] - a[1]
    dz = b[2] - a[2]
    hx = dy * e2z - dz * e2y
    hy = dz * e2x - dx * e2z
    hz = dx * e2y - dy * e2x
    det = e1x * hx + e1y * hy + e1z * hz
    if abs(det) < 1e-14:
        return False  # parallel (coplanar: measure zero)
    inv = 1.0 / det
    sx = a[0] - p0[0]
    sy = a[1] - p0[1]
    sz = a[2] - p0[2]
    u = inv * (sx * hx + sy * hy + sz * hz)
    if u < 0.0 or u > 1.0:
        return False
    qx = sy * e1z - sz * e1y
    qy = sz * e1x - sx * e1z
    qz = sx * e1y - sy * e1x
    v = inv * (dx * qx + dy * qy + dz * qz)
    if v < 0.0 or u + v > 1.0:
        return False
    t = inv * (e2x * qx + e2y * qy + e2z * qz)
    return 0.0 <= t <= 1.0


@numba.njit(cache=True)
def passes_strand(x, i, old):
    """Whether moving bead i of the ring from ``old`` to ``x[i]`` may change the knot type.

    The straight-line move sweeps the triangles (x[i-1], old, x[i]) and (x[i+1], old, x[i]);
    if no other bond meets them the knot type is unchanged (bonds that share a vertex with a
    triangle can meet it only there and are skipped for it). The test is symmetric in the move
    and its reverse, so rejecting such moves keeps detailed balance within the knot type.
    """
    n = x.shape[0]
    a = (i - 1) % n
    c = (i + 1) % n
    new = x[i]
    step = math.sqrt((new[0] - old[0]) ** 2 + (new[1] - old[1]) ** 2 + (new[2] - old[2]) ** 2)
    ra = math.sqrt((x[a, 0] - old[0]) ** 2 + (x[a, 1] - old[1]) ** 2 + (x[a, 2] - old[2]) ** 2)
    rc = math.sqrt((x[c, 0] - old[0]) ** 2 + (x[c, 1] - old[1]) ** 2 + (x[c, 2] - old[2]) ** 2)
    reach = max(ra, rc) + step
    for k in range(n):
        k1 = (k + 1) % n
        if k == a or k == i:  # the two moving bonds
            continue
        mx = 0.5 * (x[k, 0] + x[k1, 0]) - old[0]
        my = 0.5 * (x[k, 1] + x[k1, 1]) - old[1]
        mz = 0.5 * (x[k, 2] + x[k1, 2]) - old[2]
        half = 0.5 * math.sqrt((x[k1, 0] - x[k, 0]) ** 2 + (x[k1, 1] - x[k, 1]) ** 2
                               + (x[k1, 2] - x[k, 2]) ** 2)
        if mx * mx + my * my + mz * mz > (reach + half) ** 2:
            continue
        if k != a and k1 != a and _segment_hits_triangle(x[k], x[k1], x[a], old, new):
            return True
        if k != c and k1 != c and _segment_hits_triangle(x[k], x[k1], x[c], old, new):
            return True
    return False


@numba.njit(cache=True)
def _sweeps(x, n_sweeps, delta, kT, closed, B, l0, A, sigma, eps, stride, series, full, keep,
            fixed_topology):
    """``n_sweeps`` sweeps of N single-bead moves; every ``stride`` sweeps a sample.

    ``series[s]`` gets the chain averages of sample ``s``; if ``keep``, ``full[s]`` gets the
    per-bond lengths, cosines and 1-3 distances. With ``fixed_topology`` (rings only) a move
    whose swept triangles a bond crosses is rejected (:func:`passes_strand`). Returns the
    number of accepted moves.
    """
    n = x.shape[0]
    beta = 1.0 / kT
    accepted = 0
    old = np.empty(3)
    s = 0
    nb = n if closed else n - 1
    m = n if closed else n - 2
    for sweep in range(n_sweeps):
        for _ in range(n):
            i = np.random.randint(n)
            e_old = local_energy(x, i, closed, B, l0, A, sigma, eps)
            for c in range(3):
                old[c] = x[i, c]
                x[i, c] += delta * (2.0 * np.random.random() - 1.0)
            de = local_energy(x, i, closed, B, l0, A, sigma, eps) - e_old
            if (de <= 0.0 or np.random.random() < math.exp(-beta * de)) and not (
                    fixed_topology and passes_strand(x, i, old)):
                accepted += 1
            else:
                for c in range(3):
                    x[i, c] = old[c]
        if (sweep + 1) % stride == 0 and s < series.shape[0]:
            _observe(x, closed, series[s])
            if keep:
                for k in range(nb):
                    j = (k + 1) % n
                    full[s, 0, k] = math.sqrt((x[j, 0] - x[k, 0]) ** 2 + (x[j, 1] - x[k, 1]) ** 2
                                              + (x[j, 2] - x[k, 2]) ** 2)
                for k in range(m):
                    k1 = (k + 1) % n
                    k2 = (k + 2) % n
                    ax = x[k1, 0] - x[k, 0]
                    ay = x[k1, 1] - x[k, 1]
                    az = x[k1, 2] - x[k, 2]
                    bx = x[k2, 0] - x[k1, 0]
                    by = x[k2, 1] - x[k1, 1]
                    bz = x[k2, 2] - x[k1, 2]
                    na = math.sqrt(ax * ax + ay * ay + az * az)
                    nbb = math.sqrt(bx * bx + by * by + bz * bz)
                    full[s, 1, k] = (ax * bx + ay * by + az * bz) / (na * nbb)
                    full[s, 2, k] = math.sqrt((ax + bx) ** 2 + (ay + by) ** 2 + (az + bz) ** 2)
            s += 1
    return accepted


@dataclass
class MCResult:
    """A Monte Carlo run: per-sample chain averages (``series``, columns :data:`SERIES`)."""

    kT: float
    closed: bool
    series: np.ndarray
    acceptance: float
    delta: float
    sweeps: int
    stride: int
    final: np.ndarray
    full: np.ndarray | None = None
    wall: float = 0.0
    stats: dict = field(default_factory=dict)

    def estimates(self, n_blocks: int = 40) -> dict:
        """``{name: (value, standard error)}`` for ``bond_sd``, ``cos``, ``d13`` and ``bond``."""
        return chain_estimates(self.series, n_blocks)


def metropolis(x0, kT: float, sweeps: int = 200_000, burn_in: int = 20_000, stride: int = 5,
               seed: int = 0, closed: bool = True, keep_full: bool = False,
               delta: float | None = None, fixed_topology: bool = False,
               **overrides) -> MCResult:
    """Metropolis Monte Carlo of the chain's energy at ``kT`` (F0 d), from ``x0`` (n, 3).

    ``sweeps`` production sweeps (``n`` single-bead moves each) after ``burn_in`` sweeps,
    sampled every ``stride`` sweeps. ``fixed_topology``: keep the ring's knot type (moves
    that would pass a bond through another are rejected; a ring only). Energy parameters:
    :data:`STUDY`, overridden by keyword (``bond_stiffness=..., bending_stiffness=0,
    lj_epsilon=0``, ...).
    """
    import time

    p = dict(STUDY)
    p.update(overrides)
    args = (p["bond_stiffness"], p["bond_length"], p["bending_stiffness"], p["lj_sigma"],
            p["lj_epsilon"])
    x = np.array(x0, dtype=np.float64, copy=True)
    n = len(x)
    _seed(int(seed))
    if delta is None:
        delta = 0.12 * math.sqrt(kT)
    t0 = time.perf_counter()
    dummy = np.empty((1, 4))
    nofull = np.empty((1, 3, 1))
    # burn-in in chunks, steering delta towards an acceptance of 0.4
    chunk = max(1, min(2000, burn_in // 10))
    done = 0
    while done < burn_in:
        k = min(chunk, burn_in - done)
        acc = _sweeps(x, k, delta, kT, closed, *args, 1 << 30, dummy, nofull, False,
                     fixed_topology) / (k * n)
        delta *= min(2.0, max(0.5, math.exp(1.5 * (acc - 0.4))))
        done += k
    n_samples = sweeps // stride
    series = np.empty((n_samples, 4))
    full = np.empty((n_samples, 3, n)) if keep_full else nofull
    accepted = _sweeps(x, sweeps, delta, kT, closed, *args, stride, series, full, keep_full,
                      fixed_topology)
    wall = time.perf_counter() - t0
    m = n if closed else n - 2
    nb = n if closed else n - 1
    out_full = None
    if keep_full:
        out_full = {"bond": full[:, 0, :nb].copy(), "cos": full[:, 1, :m].copy(),
                    "d13": full[:, 2, :m].copy()}
    return MCResult(kT=kT, closed=closed, series=series, acceptance=accepted / (sweeps * n),
                    delta=delta, sweeps=sweeps, stride=stride, final=x, full=out_full, wall=wall)


# -- statistics -------------------------------------------------------------------------------
def _derived(means: np.ndarray) -> np.ndarray:
    """``[bond_sd, cos, d13, bond]`` from the means of the four series (along the last axis)."""
    sd = np.sqrt(np.maximum(means[..., 1] - means[..., 0] ** 2, 0.0))
    return np.stack([sd, means[..., 2], means[..., 3], means[..., 0]], axis=-1)


DERIVED = ("bond_sd", "cos", "d13", "bond")


def chain_estimates(series: np.ndarray, n_blocks: int = 40) -> dict:
    """Values and jackknife standard errors over ``n_blocks`` contiguous blocks.

    ``series``: (n_samples, 4), columns :data:`SERIES` (per-sample chain averages, in time
    order). The bond-length standard deviation is the pooled one,
    ``sqrt(<l^2> - <l>^2)`` over every bond and sample. Blocks must be much longer than the
    autocorrelation time for the errors to hold (:func:`blocking_error`).
    """
    series = np.asarray(series, dtype=np.float64)
    n = (len(series) // n_blocks) * n_blocks
    blocks = series[:n].reshape(n_blocks, -1, 4).mean(axis=1)
    total = blocks.sum(axis=0)
    value = _derived(series[:n].mean(axis=0))
    leave_out = _derived((total[None, :] - blocks) / (n_blocks - 1))
    err = np.sqrt((n_blocks - 1) / n_blocks * np.sum((leave_out - leave_out.mean(0)) ** 2, 0))
    return {name: (float(value[k]), float(err[k])) for k, name in enumerate(DERIVED)}


def blocking_error(a: np.ndarray) -> tuple[float, float, list]:
    """Flyvbjerg-Petersen blocking: ``(standard error, integrated autocorrelation time, curve)``.

    The series is halved by pairwise averaging while more than 32 blocks remain; the error is
    the largest of the last few levels (the plateau), and ``tau = (se / se_naive)^2 / 2`` in
    samples.
    """
    a = np.asarray(a, dtype=np.float64)
    curve = []
    b = a.copy()
    while len(b) >= 32:
        curve.append(float(np.std(b, ddof=1) / math.sqrt(len(b))))
        m = len(b) // 2
        b = 0.5 * (b[0 : 2 * m : 2] + b[1 : 2 * m : 2])
    se = max(curve[-4:]) if len(curve) >= 4 else max(curve)
    tau = 0.5 * (se / curve[0]) ** 2 if curve[0] > 0 else 0.0
    return se, tau, curve


def circle(n: int, bond: float = 0.6) -> np.ndarray:
    """A planar regular n-gon of side ``bond`` (an unknot), shape (n, 3)."""
    radius = bond / (2.0 * math.sin(math.pi / n))
    t = 2.0 * math.pi * np.arange(n) / n
    return np.stack([radius * np.cos(t), radius * np.sin(t), np.zeros(n)], axis=1)


def reference(kT: float, knot: str | None = "3_1", n_beads: int = 60, sweeps: int = 400_000,
              seed: int = 1, **kw) -> dict:
    """The Monte Carlo reference for a ring of ``n_beads`` at ``kT``.

    ``knot``: ``"3_1"`` starts from T(2,3) and keeps the trefoil, ``"0_1"`` starts from a
    circle and keeps the unknot (``fixed_topology``), ``None`` starts from T(2,3) and lets
    bonds pass through each other (the plain Boltzmann distribution of the energy, which at
    N = 60 and kT >~ 0.5 is almost all unknot). Returns ``{name: (value, standard error)}``
    (:data:`DERIVED`) plus ``acceptance``, ``wall`` (s) and the autocorrelation times of the
    four series in sweeps (``tau_*``).
    """
    if knot == "0_1":
        x0 = circle(n_beads)
    elif knot in ("3_1", None):
        from knotmm.shapes.geometry import torus_knot  # the start only; the energy is ours

        x0 = torus_knot(2, 3, n_beads)
    else:
        raise ValueError(f"knot={knot!r}: '3_1', '0_1' or None")
    res = metropolis(x0, kT, sweeps=sweeps, seed=seed, fixed_topology=knot is not None, **kw)
    out = dict(res.estimates())
    for k, name in enumerate(SERIES):
        out["tau_" + name] = blocking_error(res.series[:, k])[1] * res.stride
    out.update(acceptance=res.acceptance, wall=res.wall, sweeps=sweeps, delta=res.delta,
               knot=knot)
    return out


def trimer_exact(kT, p=STUDY):
    """<cos theta> and <|r_3 - r_1|> of an open trimer by quadrature over (r1, r2, theta)."""
    avg = trimer_averages(kT, p)
    return avg["cos"], avg["d13"]


def trimer_averages(kT, p=STUDY) -> dict:
    """An open trimer's equilibrium averages by quadrature over (r1, r2, theta): ``cos``
    (successive bonds), ``d13`` (|r_3 - r_1|), ``bond_mean`` and ``bond_sd`` (one bond)."""
    B, l0, A = p["bond_stiffness"], p["bond_length"], p["bending_stiffness"]
    s, eps = p["lj_sigma"], p["lj_epsilon"]
    w = 9 * math.sqrt(kT / B)
    gr, wr = np.polynomial.legendre.leggauss(80)
    r = l0 + w * gr
    wr = wr * w
    gt, wt = np.polynomial.legendre.leggauss(400)
    th = 0.5 * math.pi * (gt + 1)
    wt = wt * 0.5 * math.pi
    r1, r2, t = np.meshgrid(r, r, th, indexing="ij")
    d13 = np.sqrt(r1**2 + r2**2 + 2 * r1 * r2 * np.cos(t))
    lj = np.where(d13 < 2 ** (1 / 6) * s, eps * ((s / d13) ** 12 - (s / d13) ** 6), 0.0)
    e = 0.5 * B * ((r1 - l0) ** 2 + (r2 - l0) ** 2) + 0.5 * A * t**2 + lj
    weight = (r1**2 * r2**2 * np.sin(t) * np.exp(-(e - e.min()) / kT)
              * wr[:, None, None] * wr[None, :, None] * wt[None, None, :])
    z = weight.sum()
    mean = float((weight * r1).sum() / z)
    return {"cos": float((weight * np.cos(t)).sum() / z), "d13": float((weight * d13).sum() / z),
            "bond_mean": mean,
            "bond_sd": math.sqrt(float((weight * (r1 - mean) ** 2).sum() / z))}
