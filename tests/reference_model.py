"""An independent numpy implementation of the model in docs/model.md, for the tests.

Written from the formulas of docs/model.md only (nothing is imported from knotmm), in model units:
d = 1, F0 = 1, mu0 = 1. Loops are kept naive on purpose: this is the slow, obviously
correct version the engine is checked against.
"""

from __future__ import annotations

import numpy as np

#: The study's parameters (docs/model.md).
STUDY = dict(
    bond_length=0.6,
    bond_stiffness=50.0,
    bending_stiffness=5.0,
    lj_sigma=0.5,
    lj_epsilon=0.25,
    gravity=1.0,
)


def params(**overrides) -> dict:
    p = dict(STUDY)
    p.update(overrides)
    return p


def nonbonded_pairs(n: int):
    """Every pair (i, j), i < j, that is not bonded in a ring of n beads (1-3 pairs kept)."""
    for i in range(n):
        for j in range(i + 1, n):
            if j - i == 1 or (i == 0 and j == n - 1):
                continue
            yield i, j


def nonbonded_mask(n: int) -> np.ndarray:
    """Boolean (n, n) mask of the pairs i < j that are not bonded (see nonbonded_pairs)."""
    i, j = np.triu_indices(n, k=1)
    mask = np.zeros((n, n), dtype=bool)
    keep = ~((j - i == 1) | ((i == 0) & (j == n - 1)))
    mask[i[keep], j[keep]] = True
    return mask


def _nonbonded_distances(x) -> np.ndarray:
    """(n, n) distances for non-bonded pairs i < j; inf elsewhere."""
    r = np.linalg.norm(x[None, :, :] - x[:, None, :], axis=-1)
    return np.where(nonbonded_mask(len(x)), r, np.inf)


def _angle(u, w):
    """Angle between vectors u and w, accurate near 0 and pi (atan2 of |u x w| and u.w)."""
    return np.arctan2(np.linalg.norm(np.cross(u, w)), np.dot(u, w))


def chain_topology(chains):
    """Bonds and bending triples of chains given as [(n_beads, closed), ...], one after the
    other in bead order (a ring bonds its last bead to its first; an open chain bends at its
    inner beads only)."""
    bonds, triples, start = [], [], 0
    for n, closed in chains:
        idx = list(range(start, start + n))
        bonds += [(idx[k], idx[k + 1]) for k in range(n - 1)]
        if closed:
            bonds.append((idx[-1], idx[0]))
            triples += [(idx[k - 1], idx[k], idx[(k + 1) % n]) for k in range(n)]
        else:
            triples += [(idx[k - 1], idx[k], idx[k + 1]) for k in range(1, n - 1)]
        start += n
    return bonds, triples


def _system_distances(x, bonds) -> np.ndarray:
    """(n, n) distances for pairs i < j not in ``bonds``; inf elsewhere."""
    n = len(x)
    r = np.linalg.norm(x[None, :, :] - x[:, None, :], axis=-1)
    mask = np.triu(np.ones((n, n), dtype=bool), k=1)
    for i, j in bonds:
        mask[min(i, j), max(i, j)] = False
    return np.where(mask, r, np.inf)


def energies(x, chains=None, **overrides) -> dict:
    """Energy of each term of docs/model.md, in F0 d (one ring, or ``chains`` as in
    :func:`chain_topology`)."""
    p = params(**overrides)
    x = np.asarray(x, dtype=np.float64)
    n = len(x)
    bonds, triples = chain_topology([(n, True)] if chains is None else chains)
    e_bond = 0.0
    for i, j in bonds:
        ell = np.linalg.norm(x[j] - x[i])
        e_bond += 0.5 * p["bond_stiffness"] * (ell - p["bond_length"]) ** 2
    e_bend = 0.0
    for a, i, c in triples:
        u = x[a] - x[i]
        w = x[c] - x[i]
        e_bend += 0.5 * p["bending_stiffness"] * (_angle(u, w) - np.pi) ** 2
    s, eps = p["lj_sigma"], p["lj_epsilon"]
    rc = 2.0 ** (1.0 / 6.0) * s
    r = _nonbonded_distances(x) if chains is None else _system_distances(x, bonds)
    inside = r < rc
    e_steric = float(np.sum(eps * ((s / r[inside]) ** 12 - (s / r[inside]) ** 6)))
    e_gravity = p["gravity"] * float(np.sum(x[:, 2]))
    out = {"bond": e_bond, "bend": e_bend, "steric": e_steric, "gravity": e_gravity}
    out["total"] = sum(out.values())
    return out


def forces(x, chains=None, **overrides) -> dict:
    """Force of each term (minus the analytic gradient of its energy), shape (n, 3), in F0
    (one ring, or ``chains`` as in :func:`chain_topology`)."""
    p = params(**overrides)
    x = np.asarray(x, dtype=np.float64)
    n = len(x)
    bonds, triples = chain_topology([(n, True)] if chains is None else chains)
    f_bond = np.zeros_like(x)
    for i, j in bonds:
        rij = x[j] - x[i]
        ell = np.linalg.norm(rij)
        g = p["bond_stiffness"] * (ell - p["bond_length"]) * rij / ell  # dE/dx_j
        f_bond[j] -= g
        f_bond[i] += g
    f_bend = np.zeros_like(x)
    for a, i, c in triples:
        u = x[a] - x[i]
        w = x[c] - x[i]
        lu, lw = np.linalg.norm(u), np.linalg.norm(w)
        uh, wh = u / lu, w / lw
        phi = _angle(u, w)
        # d phi / d u = -(wh - cos(phi) uh) / (|u| sin(phi)); (wh - cos uh) / sin is the unit
        # vector in the plane, perpendicular to u, pointing towards w: build it from cross
        # products so that it stays accurate when phi is close to pi.
        nrm = np.cross(u, w)
        nn = np.linalg.norm(nrm)
        if nn == 0.0:
            continue  # exactly straight or folded: no torque direction, zero force at pi
        nh = nrm / nn
        perp_u = np.cross(nh, uh)  # in-plane, perpendicular to u, rotated towards w
        perp_w = np.cross(wh, nh)  # in-plane, perpendicular to w, rotated towards u
        dphi_du = -perp_u / lu
        dphi_dw = -perp_w / lw
        de_dphi = p["bending_stiffness"] * (phi - np.pi)
        f_bend[a] -= de_dphi * dphi_du
        f_bend[c] -= de_dphi * dphi_dw
        f_bend[i] += de_dphi * (dphi_du + dphi_dw)
    s, eps = p["lj_sigma"], p["lj_epsilon"]
    rc = 2.0 ** (1.0 / 6.0) * s
    f_steric = np.zeros_like(x)
    r = _nonbonded_distances(x) if chains is None else _system_distances(x, bonds)
    for i, j in zip(*np.nonzero(r < rc), strict=True):
        rij = x[j] - x[i]
        rr = np.linalg.norm(rij)
        de_dr = eps * (-12.0 * s**12 / rr**13 + 6.0 * s**6 / rr**7)
        f_steric[j] -= de_dr * rij / rr
        f_steric[i] += de_dr * rij / rr
    f_gravity = np.zeros_like(x)
    f_gravity[:, 2] = -p["gravity"]
    out = {"bond": f_bond, "bend": f_bend, "steric": f_steric, "gravity": f_gravity}
    out["total"] = f_bond + f_bend + f_steric + f_gravity
    return out


def steric_pair_force(r, sigma=0.5, eps=0.25):
    """Magnitude of the repulsive steric force -dE/dr at distance r (0 beyond the cutoff)."""
    if r >= 2.0 ** (1.0 / 6.0) * sigma:
        return 0.0
    return eps * (12.0 * sigma**12 / r**13 - 6.0 * sigma**6 / r**7)


def rpy_block(ri, rj):
    """The 3x3 RPY mobility mu_ij / mu0 of docs/model.md (beads of diameter d = 1)."""
    if ri is rj:
        return np.eye(3)
    rvec = np.asarray(rj, float) - np.asarray(ri, float)
    r = np.sqrt(rvec @ rvec)
    if r == 0.0:
        return np.eye(3)  # coincident beads: the r -> 0 limit of the overlap branch
    rr = np.outer(rvec, rvec) / r**2
    if r >= 1.0:
        return (
            3.0
            / (8.0 * r)
            * ((1.0 + 1.0 / (6.0 * r**2)) * np.eye(3) + (1.0 - 1.0 / (2.0 * r**2)) * rr)
        )
    return (1.0 - 9.0 * r / 16.0) * np.eye(3) + (3.0 * r / 16.0) * rr


def rpy_velocities(x, f):
    """v_i = sum_j mu_ij F_j by a naive double loop over docs/model.md's tensor."""
    x = np.asarray(x, dtype=np.float64)
    f = np.asarray(f, dtype=np.float64)
    v = np.zeros_like(x)
    for i in range(len(x)):
        for j in range(len(x)):
            block = np.eye(3) if i == j else rpy_block(x[i], x[j])
            v[i] += block @ f[j]
    return v


def rpy_dense(x):
    """The 3N x 3N tensor, bead-major, from :func:`rpy_block`."""
    n = len(x)
    m = np.zeros((3 * n, 3 * n))
    for i in range(n):
        for j in range(n):
            m[3 * i : 3 * i + 3, 3 * j : 3 * j + 3] = np.eye(3) if i == j else rpy_block(x[i], x[j])
    return m


def gauss_linking(a, b, sub=6):
    """Gauss's linking integral of two closed polygons by the midpoint rule, every bond cut
    into ``sub`` pieces: (1/4 pi) sum (da x db) . (ra - rb) / |ra - rb|^3."""
    def pieces(x):
        nxt = np.roll(x, -1, axis=0)
        t = (np.arange(sub) + 0.5) / sub
        pts = x[:, None] + t[None, :, None] * (nxt - x)[:, None]
        return pts.reshape(-1, 3), np.repeat((nxt - x) / sub, sub, axis=0)

    pa, da = pieces(np.asarray(a, float))
    pb, db = pieces(np.asarray(b, float))
    r = pa[:, None] - pb[None]
    cross = np.cross(da[:, None], db[None])
    return float(np.sum(np.einsum("ijk,ijk->ij", cross, r)
                        / np.linalg.norm(r, axis=-1) ** 3) / (4 * np.pi))


# -- configurations ---------------------------------------------------------------------------
def circle(n, bond=0.6, z=0.0):
    """A planar regular polygon of n beads with bonds ``bond``."""
    radius = bond / (2.0 * np.sin(np.pi / n))
    t = 2.0 * np.pi * np.arange(n) / n
    return np.stack([radius * np.cos(t), radius * np.sin(t), np.full(n, z)], axis=1)


def random_ring(n, rng, noise=0.12, bond=0.6):
    """A polygon ring with random bond lengths, angles and out-of-plane kinks."""
    return circle(n, bond) + rng.normal(scale=noise, size=(n, 3))


def min_nonbonded_distance(x):
    return float(np.min(_nonbonded_distances(np.asarray(x, dtype=np.float64))))


def nearly_straight_ring(rng, n=1200, symmetry=4, lo=1.5e-3, lift=0.3, bond=0.6):
    """A closed ring whose every bead bends by about 1e-3 to 1e-2 rad (for n = 1200).

    In the plane, the turning angles of one arc of ``n / symmetry`` beads are drawn uniformly
    from ``[lo, 2 (2 pi / n) - lo]`` and rescaled to add up to ``2 pi / symmetry``; the
    ring is ``symmetry`` rotated copies of that arc, so it closes exactly. A vertical wave
    ``lift sin(6 pi k / n)`` makes it non-planar.
    """
    m = n // symmetry
    mean = 2.0 * np.pi / n
    arc = rng.uniform(lo, 2.0 * mean - lo, m)
    arc *= (2.0 * np.pi / symmetry) / arc.sum()
    heading = np.cumsum(np.tile(arc, symmetry))
    steps = bond * np.stack([np.cos(heading), np.sin(heading)], axis=1)
    xy = np.cumsum(steps, axis=0)
    xy -= xy.mean(axis=0)
    k = np.arange(n)
    z = lift * np.sin(6.0 * np.pi * k / n)
    return np.column_stack([xy, z])


def bend_deviation(x) -> np.ndarray:
    """pi minus the angle at every bead (0 for a straight chain), in rad."""
    n = len(x)
    return np.array(
        [np.pi - _angle(x[(i - 1) % n] - x[i], x[(i + 1) % n] - x[i]) for i in range(n)]
    )


def close_contact_ring(n, rng, contacts=6, lo=0.45, hi=0.56):
    """A random ring in which ``contacts`` non-bonded pairs sit at distances in [lo, hi].

    Includes one 1-3 pair (beads i and i+2) pushed inside the steric range. No non-bonded
    pair is closer than ``lo``.
    """
    while True:
        x = random_ring(n, rng, noise=0.05)
        # fold bead 2 back so that 0 and 2 (a 1-3 pair) are inside the steric range
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        x[2] = x[0] + rng.uniform(lo, hi) * direction
        placed = 1
        tries = 0
        while placed < contacts and tries < 200:
            tries += 1
            i, j = sorted(rng.choice(n, size=2, replace=False))
            if j - i <= 2 or (i + n - j) <= 2 or {i, j} & {0, 1, 2}:
                continue
            direction = rng.normal(size=3)
            direction /= np.linalg.norm(direction)
            trial = x.copy()
            trial[j] = x[i] + rng.uniform(lo, hi) * direction
            if min_nonbonded_distance(trial) >= lo:
                x = trial
                placed += 1
        if placed == contacts and min_nonbonded_distance(x) >= lo:
            return x


def flat_ring(n: int, bond: float = 0.6, wave: float = 0.0) -> np.ndarray:
    """A regular n-gon of side ``bond`` in the xy plane, z = ``wave`` sin(2 phi); (n, 3), d."""
    ang = 2 * np.pi * np.arange(n) / n
    radius = bond / (2 * np.sin(np.pi / n))
    return np.column_stack([radius * np.cos(ang), radius * np.sin(ang),
                            wave * np.sin(2 * ang)])


def dense_jacobian(fn, x: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    """Jacobian of ``fn: (n, 3) -> (n, 3)`` at ``x``, column by column (forward differences)."""
    n3 = x.size
    f0 = np.asarray(fn(x)).ravel()
    jac = np.empty((f0.size, n3))
    for k in range(n3):
        e = np.zeros(n3)
        e[k] = eps
        jac[:, k] = (np.asarray(fn(x + e.reshape(x.shape))).ravel() - f0) / eps
    return jac
