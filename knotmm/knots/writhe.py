"""Writhe and average crossing number of bead chains: exact Gauss double integrals.

A chain is read as a polygon: bead ``i`` is joined to bead ``i + 1`` and, for a closed chain
(the default), the last bead to the first. :func:`writhe` sums, segment pair by segment pair,
the solid-angle formula of Klenin and Langowski (Biopolymers 54, 307, 2000): vectorised numpy
(:func:`_gauss_numpy`) for a small problem, a compiled kernel (numba,
:mod:`knotmm.knots.writhe_kernel`) for many frames or long closed chains; the tests hold the
two to each other. Its sign is the handedness (:mod:`knotmm.knots.chirality`): the
right-handed trefoil T(2,3) has writhe > 0.

:func:`average_crossing_number` is the same double integral with the absolute value of the
integrand: the number of crossings of a projection averaged over all directions. Along two
straight segments the sign of ``(t1 x t2) . (r1 - r2)`` is constant, so the absolute
integral of a segment pair is the absolute value of its signed solid angle, and the ACN of a
polygon is exact too: ``2 sum_{i<j} |segment_pair_gauss|`` over segment pairs that share no
bead.

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

__all__ = ["as_chain", "average_crossing_number", "segment_pair_gauss", "writhe"]

# Pairs of segments evaluated at once per chunk in writhe(); bounds the temporary memory
# (about 40 float64 arrays of this length).
_PAIR_CHUNK = 400_000


def as_chain(positions, name: str = "positions", closed: bool = True) -> np.ndarray:
    """``positions`` as float64, shape (n_beads, 3) or (n_frames, n_beads, 3), checked.

    A closed chain needs at least 3 beads, an open one 2.
    """
    x = np.asarray(positions, dtype=np.float64)
    if x.ndim not in (2, 3) or x.shape[-1] != 3:
        raise ValueError(
            f"{name} has shape {x.shape}: expected (n_beads, 3) or (n_frames, n_beads, 3)"
        )
    least = 3 if closed else 2
    if x.shape[-2] < least:
        kind = "a closed" if closed else "an open"
        raise ValueError(f"{name} has {x.shape[-2]} beads: {kind} chain needs at least {least}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name} contains non-finite coordinates")
    return x


@functools.lru_cache(maxsize=32)
def _pair_indices(n: int, closed: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Segment pairs (i < j) that share no vertex: of a closed n-gon (segments 0..n-1,
    segment n-1 closing the ring), or of an open chain of n beads (segments 0..n-2)."""
    if not closed:
        return np.triu_indices(n - 1, k=2)
    i, j = np.triu_indices(n, k=2)
    keep = ~((i == 0) & (j == n - 1))  # segment n-1 closes the ring onto segment 0
    return i[keep], j[keep]


def _unit(v: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        u = v / norm
    return np.where(norm > 0.0, u, 0.0)


def segment_pair_gauss(p1, p2, p3, p4) -> np.ndarray:
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


def _gauss_numpy(frames: np.ndarray, closed: bool = True, absolute: bool = False) -> np.ndarray:
    """Reference kernel: ``frames`` (T, N, 3) -> twice the sum over segment pairs (T,) of
    the signed (writhe) or absolute (``absolute``: ACN) contributions, vectorised."""
    n = frames.shape[1]
    i, j = _pair_indices(n, closed)
    out = np.zeros(frames.shape[0])
    if i.size == 0:
        return out
    nxt = np.roll(np.arange(n), -1)  # open chains never use the closing segment n-1
    per_chunk = max(1, _PAIR_CHUNK // i.size)
    for start in range(0, frames.shape[0], per_chunk):
        f = frames[start : start + per_chunk]
        a, b = f, f[:, nxt]
        contrib = segment_pair_gauss(a[:, i], b[:, i], a[:, j], b[:, j])
        if absolute:
            contrib = np.abs(contrib)
        out[start : start + per_chunk] = 2.0 * contrib.sum(axis=1)
    return out


def _numba_kernel():
    """The compiled writhe kernel (cached on disk by numba)."""
    from knotmm.knots.writhe_kernel import writhe_kernel

    return writhe_kernel


def _writhe_numpy(frames: np.ndarray) -> np.ndarray:
    """Reference writhe of closed chains, ``frames`` (T, N, 3) -> (T,) (the compiled
    kernel's twin)."""
    return _gauss_numpy(frames)


def _frames(positions, closed: bool) -> tuple[np.ndarray, bool]:
    """(T, N, 3) C-contiguous writeable float64 frames, and whether one frame was given."""
    x = as_chain(positions, closed=closed)
    single = x.ndim == 2
    # one compiled signature: C-contiguous, writeable float64 (copies read-only input)
    return np.require(x[None] if single else x, np.float64, ["C", "W"]), single


def writhe(positions, closed: bool = True) -> float | np.ndarray:
    """Writhe of a polygon (exact discrete Gauss integral), closed by default.

    Every pair of segments that share no vertex contributes its signed solid angle
    (Klenin-Langowski formula); adjacent segments are coplanar and contribute nothing. The
    result is exact for the polygon, not an approximation of a smooth curve.

    Parameters
    ----------
    positions : array_like, shape (n_beads, 3) or (n_frames, n_beads, 3)
        Bead coordinates (any length unit).
    closed : bool
        True: the chain is closed from the last bead to the first (a knot, a link
        component). False: an open chain, segments ``i -> i + 1`` only (its writhe is not
        an integer limit of anything; it is still the Gauss integral of that polygon).

    Returns
    -------
    float or ndarray, shape (n_frames,)
        The writhe (dimensionless). Positive for a right-handed knot such as the
        unmirrored T(2,3) template.

    Raises
    ------
    ValueError
        For a wrong shape, fewer than 3 beads (2 for an open chain) or non-finite
        coordinates.

    Notes
    -----
    Cost is O(n_beads^2) per frame; a 120-bead chain takes well under a millisecond per
    frame when frames are batched.
    """
    frames, single = _frames(positions, closed)
    if not closed or frames.shape[0] * frames.shape[1] ** 2 <= 2 * _PAIR_CHUNK:
        out = _gauss_numpy(frames, closed)  # one numpy chunk, or an open chain
    else:
        out = np.zeros(frames.shape[0])
        _numba_kernel()(frames, out)
    return float(out[0]) if single else out


def average_crossing_number(positions, closed: bool = True) -> float | np.ndarray:
    """Average crossing number (ACN) of a polygon: the Gauss integral of ``|integrand|``.

    ``ACN = 1/(4 pi) oint oint |(dr1 x dr2) . (r1 - r2)| / |r1 - r2|^3``, the number of
    crossings of the curve's projection averaged over all projection directions (uniform
    on the sphere). For two straight segments the integrand keeps one sign, so each segment
    pair contributes ``|segment_pair_gauss|`` (its solid angle over 4 pi) and the result is
    exact for the polygon: ``2 sum_{i<j} |Omega_ij| / (4 pi)`` over the pairs that share no
    bead (times 2: ordered pairs, as in :func:`writhe`). A planar curve has ACN equal to
    its crossings, 0 for a circle; ``ACN >= |writhe|`` always.

    Parameters
    ----------
    positions : array_like, shape (n_beads, 3) or (n_frames, n_beads, 3)
        Bead coordinates (any length unit).
    closed : bool
        True: the last bead is joined to the first; False: an open chain.

    Returns
    -------
    float or ndarray, shape (n_frames,)
        Dimensionless, >= 0.

    Raises
    ------
    ValueError
        As :func:`writhe`.
    """
    frames, single = _frames(positions, closed)
    out = _gauss_numpy(frames, closed, absolute=True)
    return float(out[0]) if single else out
