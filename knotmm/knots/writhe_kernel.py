"""The compiled writhe kernel (numba), imported only when a writhe is large enough to need it.

:func:`knotmm.knots.writhe.writhe` imports this module for many frames or long chains; a
single small chain is quicker in numpy than loading a compiled kernel (numba's first call in
a process costs most of a second). The formula is that of :mod:`knotmm.knots.writhe`.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["writhe_kernel"]


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
def writhe_kernel(frames, out):
    """``frames`` (T, N, 3) float64 -> writhe into ``out`` (T,)."""
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
