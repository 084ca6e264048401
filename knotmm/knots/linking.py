"""Linking numbers of closed chains: the Gauss double integral between two polygons.

``Lk(A, B) = 1/(4 pi) oint_A oint_B (dr1 x dr2) . (r1 - r2) / |r1 - r2|^3``, summed exactly
segment pair by segment pair with :func:`knotmm.knots.writhe.segment_pair_gauss` (the same
kernel as the writhe). For two disjoint closed polygons the sum is an integer up to rounding;
its sign follows the writhe's convention (the right-handed Hopf link ``T(2,2)`` has +1).

Examples
--------
>>> import numpy as np
>>> t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
>>> a = np.c_[np.cos(t), np.sin(t), 0 * t]
>>> b = np.c_[1 + np.cos(t), 0 * t, np.sin(t)]
>>> abs(linking_number(a, b))
1
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from knotmm.knots.writhe import as_chain, segment_pair_gauss

__all__ = ["gauss_linking_integral", "linking_number", "linking_numbers"]

#: A Gauss integral farther than this from an integer means the chains touch (or are not
#: closed polygons): no linking number.
INTEGER_TOLERANCE = 0.05
#: Segment pairs of the Gauss integral evaluated at once (about 60 MB of temporaries).
_BLOCK_PAIRS = 100_000


def gauss_linking_integral(a, b) -> float:
    """The Gauss linking integral of two closed polygons (a float, an integer for disjoint
    closed chains).

    Parameters
    ----------
    a, b : array_like, shape (n_a, 3) and (n_b, 3)
        Bead coordinates of two closed chains (any length unit).
    """
    a = as_chain(a, "a")
    b = as_chain(b, "b")
    if a.ndim != 2 or b.ndim != 2:
        raise ValueError("a and b must be single frames, shape (n_beads, 3)")
    a2, b2 = np.roll(a, -1, axis=0), np.roll(b, -1, axis=0)
    rows = max(1, _BLOCK_PAIRS // len(b))  # a block of rows at a time: memory bounded for
    total = 0.0                            # any length (all pairs of two 50000-bead rings at
    for start in range(0, len(a), rows):   # once would take over 1 TB)
        i, j = np.meshgrid(np.arange(start, min(start + rows, len(a))), np.arange(len(b)),
                           indexing="ij")
        i, j = i.ravel(), j.ravel()
        total += float(segment_pair_gauss(a[i], a2[i], b[j], b2[j]).sum())
    return total


def linking_number(a, b) -> int:
    """The linking number of two disjoint closed chains.

    Raises
    ------
    ValueError
        If the Gauss integral is not within ``INTEGER_TOLERANCE`` of an integer (the chains
        intersect or nearly so).
    """
    value = gauss_linking_integral(a, b)
    k = round(value)
    if abs(value - k) > INTEGER_TOLERANCE:
        raise ValueError(
            f"the Gauss linking integral is {value:.3f}, not an integer: the chains touch"
        )
    return int(k)


def linking_numbers(components: Sequence[np.ndarray]) -> dict[tuple[int, int], int]:
    """Linking numbers of every pair of closed chains, ``{(i, j): Lk}`` for ``i < j``."""
    out = {}
    for i in range(len(components)):
        for j in range(i + 1, len(components)):
            out[(i, j)] = linking_number(components[i], components[j])
    return out
