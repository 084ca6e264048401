"""Systems of several chains: chains placed in one fluid, links, open filaments.

:func:`assemble` joins checked one-chain templates (each a :class:`Template`) into one
system template: positions one chain after another, a
:class:`knotmm.model.layout.ChainLayout`, the parts kept for their facts. Chains of
different templates must not overlap: the closest pair of beads of two chains must be at
least the steric range apart, or :class:`knotmm.errors.TemplateError` names the chains and
how far to move them. :func:`place` turns and moves a template (``[[chains]]``'s
``rotation`` and ``offset``). Units: d.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from knotmm.errors import TemplateError
from knotmm.model.layout import concatenate
from knotmm.shapes.template import Template, _joined

__all__ = ["assemble", "closest_between", "place", "rotation_matrix"]

_BLOCK = 4_000_000  # distances held at once in closest_between (32 MB)


def rotation_matrix(axis_angle: Sequence[float]) -> np.ndarray:
    """The rotation by ``degrees`` about ``(x, y, z)`` (right-hand rule), Rodrigues' formula.

    Parameters
    ----------
    axis_angle : sequence of 4 floats
        ``[x, y, z, degrees]``; the axis need not be a unit vector.

    Returns
    -------
    ndarray, shape (3, 3)

    Raises
    ------
    TemplateError
        For an axis without a direction: zero, not finite, or its largest component
        subnormal (below 2.2e-308).
    """
    axis = np.asarray(axis_angle[:3], dtype=np.float64)
    scale = float(np.max(np.abs(axis)))  # first: the norm of [1e200, 1e200, 0] overflows
    if not (math.isfinite(scale) and scale >= np.finfo(np.float64).tiny):
        raise TemplateError(f"rotation = {list(axis_angle)!r}: the axis (x, y, z) has no "
                            "direction; give a non-zero axis, e.g. [0, 0, 1, 90]")
    axis = axis / scale
    axis = axis / np.linalg.norm(axis)
    angle = math.radians(float(axis_angle[3]))
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)


def place(x: np.ndarray, rotation: Sequence[float] | None, offset: Sequence[float]) -> np.ndarray:
    """``x`` turned about its centre of mass by ``rotation``, then its centre moved to
    ``offset``.

    Parameters
    ----------
    x : ndarray, shape (n, 3), in d
    rotation : [x, y, z, degrees] or None
    offset : [x, y, z], in d

    Returns
    -------
    ndarray, shape (n, 3), in d
    """
    centred = x - x.mean(axis=0)
    if rotation is not None:
        centred = centred @ rotation_matrix(rotation).T
    return np.ascontiguousarray(centred + np.asarray(offset, dtype=np.float64))


def closest_between(a: np.ndarray, b: np.ndarray) -> tuple[float, int, int]:
    """The closest pair of beads, one of ``a`` and one of ``b``.

    Returns
    -------
    distance : float, in d
    i, j : int
        The bead of ``a`` and the bead of ``b``.
    """
    best, pair = math.inf, (0, 0)
    rows = max(1, _BLOCK // max(1, b.shape[0]))
    for start in range(0, a.shape[0], rows):
        block = a[start : start + rows]
        d = np.linalg.norm(block[:, None, :] - b[None, :, :], axis=-1)
        k = int(np.argmin(d))
        if d.flat[k] < best:
            best, pair = float(d.flat[k]), (start + k // b.shape[0], k % b.shape[0])
    return best, pair[0], pair[1]


def _advised_distance(a: np.ndarray, b: np.ndarray, steric_range: float) -> float:
    """The distance of the centres of ``a`` and ``b``, rounded up to 0.01 d, at which no
    pair is within ``steric_range`` once ``b`` moves away from ``a`` along the line of their
    centres (x when the centres coincide), in d.

    The bisection finds the clearing shift to 0.005 d; the distance is then rounded up (never
    down) and checked at a hair below its value, so that chains put there, whatever the
    rounding of their offsets, pass :func:`assemble`'s check.
    """
    u = b.mean(0) - a.mean(0)
    gap = float(np.linalg.norm(u))
    u = u / gap if gap > 1e-12 else np.array([1.0, 0.0, 0.0])

    def clear(s):
        return closest_between(a, b + s * u)[0] >= steric_range

    hi = 0.5
    while not clear(hi):
        hi *= 2.0
    lo = 0.0
    while hi - lo > 0.005:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if clear(mid) else (mid, hi)
    advised = math.ceil(round((gap + hi) * 100.0, 6)) / 100.0
    while not clear(advised - gap - 1e-6):
        advised += 0.01
    return advised


def assemble(
    parts: Sequence[Template],
    names: Sequence[str],
    steric_range: float,
    facts: dict | None = None,
) -> Template:
    """One system template from templates at their places.

    Parameters
    ----------
    parts : sequence of Template
        Each a checked template of one or more chains (a link's components are its own
        ``parts``), already placed.
    names : sequence of str
        How each part is named in messages (``"chains[1]"``).
    steric_range : float
        The closest two beads of different parts may come, in d (``2^(1/6) lj_sigma``).
    facts : dict, optional
        Facts of the whole system for run.toml (``linking_numbers``).

    Raises
    ------
    TemplateError
        When two parts overlap: names both, the beads, their distance and how far apart to
        move the parts.
    """
    for a in range(len(parts)):
        for b in range(a + 1, len(parts)):
            d, i, j = closest_between(parts[a].positions, parts[b].positions)
            if d < steric_range:
                xa, xb = parts[a].positions, parts[b].positions
                gap = float(np.linalg.norm(xb.mean(0) - xa.mean(0)))
                raise TemplateError(
                    f"{names[a]} and {names[b]} overlap: bead {i} of {names[a]} and bead {j} "
                    f"of {names[b]} are {d:.3f} d apart, inside the steric range "
                    f"{steric_range:.3f} d; put their centres at least "
                    f"{_advised_distance(xa, xb, steric_range):.2f} d apart along the line "
                    f"joining them (now {gap:.2f} d), e.g. with their offsets"
                )
    chains = [c for part in parts for c in (part.parts or [part])]
    layout = concatenate([part.layout for part in parts])
    positions = np.ascontiguousarray(np.concatenate([p.positions for p in parts]))
    notes = [f"{name}: {note}"
             for name, part in zip(names, parts, strict=True) for note in part.notes]
    description = "; ".join(
        f"{cid} {chain.description}" for cid, chain in zip(layout.ids, chains, strict=True)
    )
    return Template(
        positions=positions,
        description=f"{layout.n_chains} chains: {description}",
        resolved={},
        writhe=float("nan"),
        knot_type=_joined(c.knot_type for c in chains),
        notes=notes,
        check=None,
        layout=layout,
        parts=list(chains),
        chain_facts=dict(facts or {}),
    )
