"""Writhe of closed bead chains: the exact Gauss double integral of the polygon.

The chain is read as a closed polygon: bead ``i`` is joined to bead ``i + 1`` and the last
bead to the first. :func:`writhe` sums, segment pair by segment pair, the solid-angle formula
of Klenin and Langowski (Biopolymers 54, 307, 2000): a compiled kernel (numba) behind a thin
public function, with a vectorised numpy reference (:func:`_writhe_numpy`) that the tests
hold it to. Its sign is the handedness (:mod:`knotmm.knots.chirality`): the right-handed
trefoil T(2,3) has writhe > 0.

Examples
--------
>>> import numpy as np
>>> t = np.linspace(0, 2 * np.pi, 60, endpoint=False)
>>> circle = np.c_[np.cos(t), np.sin(t), np.zeros_like(t)]
>>> round(writhe(circle), 12)
0.0
"""

from __future__ import annotations

import functools

import numpy as np

try:
    import numba
except ImportError:  # pragma: no cover - numba is a dependency
    numba = None

__all__ = ["as_chain", "writhe"]

# Pairs of segments evaluated at once per chunk in writhe(); bounds the temporary memory
# (about 40 float64 arrays of this length).
_PAIR_CHUNK = 400_000


def as_chain(positions, name: str = "positions") -> np.ndarray:
    """``positions`` as float64, shape (n_beads, 3) or (n_frames, n_beads, 3), checked."""
    x = np.asarray(positions, dtype=np.float64)
    if x.ndim not in (2, 3) or x.shape[-1] != 3:
        raise ValueError(
            f"{name} has shape {x.shape}: expected (n_beads, 3) or (n_frames, n_beads, 3)"
        )
    if x.shape[-2] < 3:
        raise ValueError(f"{name} has {x.shape[-2]} beads: a closed chain needs at least 3")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name} contains non-finite coordinates")
    return x


@functools.lru_cache(maxsize=32)
def _pair_indices(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Segment pairs (i < j) of a closed n-gon that share no vertex."""
    i, j = np.triu_indices(n, k=2)
    keep = ~((i == 0) & (j == n - 1))  # segment n-1 closes the ring onto segment 0
    return i[keep], j[keep]


def _unit(v: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        u = v / norm
    return np.where(norm > 0.0, u, 0.0)


def _pair_solid_angles(p1, p2, p3, p4) -> np.ndarray:
    """Signed solid angle (times 1/(4 pi): the Gauss-integral contribution) of segment pairs.

    Parameters
    ----------
    p1, p2 : ndarray, shape (m, 3)
        Start and end of the first segments.
    p3, p4 : ndarray, shape (m, 3)
        Start and end of the second segments.

    Returns
    -------
    ndarray, shape (m,)
        The contribution of each ordered pair to the writhe, ``Omega / (4 pi)``.
    """
    r13 = p3 - p1
    r14 = p4 - p1
    r23 = p3 - p2
    r24 = p4 - p2
    n1 = _unit(np.cross(r13, r14))
    n2 = _unit(np.cross(r14, r24))
    n3 = _unit(np.cross(r24, r23))
    n4 = _unit(np.cross(r23, r13))

    def _asin_dot(a, b):
        return np.arcsin(np.clip(np.einsum("...k,...k->...", a, b), -1.0, 1.0))

    omega = _asin_dot(n1, n2) + _asin_dot(n2, n3) + _asin_dot(n3, n4) + _asin_dot(n4, n1)
    sign = np.sign(np.einsum("...k,...k->...", np.cross(p4 - p3, p2 - p1), r13))
    return omega * sign / (4.0 * np.pi)


def _writhe_numpy(frames: np.ndarray) -> np.ndarray:
    """Reference kernel: ``frames`` (T, N, 3) -> writhe (T,), vectorised over pairs."""
    n = frames.shape[1]
    i, j = _pair_indices(n)
    out = np.zeros(frames.shape[0])
    if i.size == 0:
        return out
    nxt = np.roll(np.arange(n), -1)
    per_chunk = max(1, _PAIR_CHUNK // i.size)
    for start in range(0, frames.shape[0], per_chunk):
        f = frames[start : start + per_chunk]
        a, b = f, f[:, nxt]
        contrib = _pair_solid_angles(a[:, i], b[:, i], a[:, j], b[:, j])
        out[start : start + per_chunk] = 2.0 * contrib.sum(axis=1)
    return out


if numba is not None:

    @numba.njit(cache=True, inline="always")
    def _unit_cross(ax, ay, az, bx, by, bz):
        cx = ay * bz - az * by
        cy = az * bx - ax * bz
        cz = ax * by - ay * bx
        norm = np.sqrt(cx * cx + cy * cy + cz * cz)
        if norm > 0.0:
            return cx / norm, cy / norm, cz / norm
        return 0.0, 0.0, 0.0

    @numba.njit(cache=True, inline="always")
    def _asin_dot(ax, ay, az, bx, by, bz):
        d = ax * bx + ay * by + az * bz
        if d > 1.0:
            d = 1.0
        elif d < -1.0:
            d = -1.0
        return np.arcsin(d)

    @numba.njit(cache=True)
    def _writhe_kernel(frames, out):
        n_frames, n = frames.shape[0], frames.shape[1]
        for f in range(n_frames):
            x = frames[f]
            total = 0.0
            for i in range(n):
                i1 = i + 1 if i + 1 < n else 0
                p1x, p1y, p1z = x[i, 0], x[i, 1], x[i, 2]
                p2x, p2y, p2z = x[i1, 0], x[i1, 1], x[i1, 2]
                # segments j > i + 1 that share no vertex with segment i
                j_end = n if i > 0 else n - 1
                for j in range(i + 2, j_end):
                    j1 = j + 1 if j + 1 < n else 0
                    p3x, p3y, p3z = x[j, 0], x[j, 1], x[j, 2]
                    p4x, p4y, p4z = x[j1, 0], x[j1, 1], x[j1, 2]
                    r13x, r13y, r13z = p3x - p1x, p3y - p1y, p3z - p1z
                    r14x, r14y, r14z = p4x - p1x, p4y - p1y, p4z - p1z
                    r23x, r23y, r23z = p3x - p2x, p3y - p2y, p3z - p2z
                    r24x, r24y, r24z = p4x - p2x, p4y - p2y, p4z - p2z
                    n1x, n1y, n1z = _unit_cross(r13x, r13y, r13z, r14x, r14y, r14z)
                    n2x, n2y, n2z = _unit_cross(r14x, r14y, r14z, r24x, r24y, r24z)
                    n3x, n3y, n3z = _unit_cross(r24x, r24y, r24z, r23x, r23y, r23z)
                    n4x, n4y, n4z = _unit_cross(r23x, r23y, r23z, r13x, r13y, r13z)
                    omega = (
                        _asin_dot(n1x, n1y, n1z, n2x, n2y, n2z)
                        + _asin_dot(n2x, n2y, n2z, n3x, n3y, n3z)
                        + _asin_dot(n3x, n3y, n3z, n4x, n4y, n4z)
                        + _asin_dot(n4x, n4y, n4z, n1x, n1y, n1z)
                    )
                    ax, ay, az = p4x - p3x, p4y - p3y, p4z - p3z
                    bx, by, bz = p2x - p1x, p2y - p1y, p2z - p1z
                    t = (
                        (ay * bz - az * by) * r13x
                        + (az * bx - ax * bz) * r13y
                        + (ax * by - ay * bx) * r13z
                    )
                    if t > 0.0:
                        total += omega
                    elif t < 0.0:
                        total -= omega
            out[f] = 2.0 * total / (4.0 * np.pi)


def _numba_kernel():
    """The compiled writhe kernel (cached on disk by numba), or None without numba."""
    return None if numba is None else _writhe_kernel


def writhe(positions) -> float | np.ndarray:
    """Writhe of a closed polygon (exact discrete Gauss integral).

    Every pair of segments that share no vertex contributes its signed solid angle
    (Klenin-Langowski formula); adjacent segments are coplanar and contribute nothing. The
    result is exact for the polygon, not an approximation of a smooth curve.

    Parameters
    ----------
    positions : array_like, shape (n_beads, 3) or (n_frames, n_beads, 3)
        Bead coordinates (any length unit); the chain is closed from the last bead to the
        first.

    Returns
    -------
    float or ndarray, shape (n_frames,)
        The writhe (dimensionless). Positive for a right-handed knot such as the
        unmirrored T(2,3) template.

    Raises
    ------
    ValueError
        For a wrong shape, fewer than 3 beads or non-finite coordinates.

    Notes
    -----
    Cost is O(n_beads^2) per frame; a 120-bead chain takes well under a millisecond per
    frame when frames are batched.
    """
    x = as_chain(positions)
    single = x.ndim == 2
    # one compiled signature: C-contiguous, writeable float64 (copies read-only input)
    frames = np.require(x[None] if single else x, np.float64, ["C", "W"])
    kernel = _numba_kernel()
    if kernel is None:  # pragma: no cover - numba is a dependency
        out = _writhe_numpy(frames)
    else:
        out = np.zeros(frames.shape[0])
        kernel(frames, out)
    return float(out[0]) if single else out
