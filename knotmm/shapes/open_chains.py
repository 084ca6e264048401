"""Open filaments: straight rods, circular arcs and helices with equal bonds.

Each builder returns the bead positions of one open chain (no bond from the last bead back
to the first) with every bond exactly ``bond_length`` long and the centre of mass at the
origin. Units: d (``docs/model.md``). The run-file side (``knot.kind = "straight"``,
``"arc"``, ``"helix"``; ``knot.closed = false``) is :mod:`knotmm.shapes.builder`'s.

>>> x = helix(30, 0.6, radius=2.0, pitch=3.0)
>>> bool(np.allclose(np.linalg.norm(np.diff(x, axis=0), axis=1), 0.6))
True
"""

from __future__ import annotations

import math

import numpy as np

from knotmm.errors import TemplateError
from knotmm.limits import LENGTH_WHY, MAX_LENGTH

__all__ = ["OPEN_KINDS", "arc", "closest_nonbonded_open", "helix", "straight"]

#: Template kinds that are open filaments.
OPEN_KINDS = ("straight", "arc", "helix")


def _centred(x: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(x - x.mean(axis=0), dtype=np.float64)


def straight(beads: int, bond_length: float) -> np.ndarray:
    """A straight rod along x.

    Returns
    -------
    ndarray, shape (beads, 3), in d
    """
    x = np.zeros((beads, 3))
    x[:, 0] = bond_length * np.arange(beads)
    return _centred(x)


def arc(beads: int, bond_length: float, degrees: float) -> np.ndarray:
    """A circular arc in the horizontal (x, y) plane spanning ``degrees``.

    The radius is ``bond_length / (2 sin(theta / (2 (beads - 1))))`` with ``theta`` the
    angle in radians, so that every chord is ``bond_length``.

    Returns
    -------
    ndarray, shape (beads, 3), in d

    Raises
    ------
    TemplateError
        For an arc whose ends would meet (``degrees`` >= 360), or one so flat that its radius
        exceeds :data:`knotmm.limits.MAX_LENGTH` (1e5 d).
    """
    theta = math.radians(degrees)
    if not 0.0 < theta < 2.0 * math.pi:
        raise TemplateError(
            f"knot.arc_degrees={degrees:g}: an arc spans more than 0 and less than 360 degrees"
        )
    step = theta / (beads - 1)
    radius = bond_length / (2.0 * math.sin(step / 2.0))
    if not radius <= MAX_LENGTH:  # 1e-300 degrees: a radius of 1e300 d, not a shape
        flattest = math.degrees(2.0 * math.asin(min(1.0, bond_length / (2.0 * MAX_LENGTH))))
        raise TemplateError(
            f"knot.arc_degrees={degrees:g} with knot.beads={beads} bends the arc on a radius "
            f"of {radius:.3g} d, more than {MAX_LENGTH:g} d ({LENGTH_WHY}); use "
            f"knot.arc_degrees >= {1.001 * flattest * (beads - 1):.3g}, or kind = 'straight'"
        )
    phi = step * np.arange(beads) - theta / 2.0
    x = np.stack([radius * np.cos(phi), radius * np.sin(phi), np.zeros(beads)], axis=1)
    return _centred(x)


def helix(beads: int, bond_length: float, radius: float, pitch: float) -> np.ndarray:
    """A helix about the z axis (right-handed for ``pitch > 0``), equal chords.

    Bead ``k`` sits at angle ``k dphi``, where ``dphi`` solves
    ``(2 R sin(dphi / 2))^2 + (pitch dphi / (2 pi))^2 = bond_length^2`` (bisection: the left
    side grows with ``dphi`` on ``[0, pi]``).

    Returns
    -------
    ndarray, shape (beads, 3), in d

    Raises
    ------
    TemplateError
        When no turn angle up to half a turn per bond gives the bond length (a pitch of
        zero and a diameter below the bond length), or for a radius or pitch past
        :data:`knotmm.limits.MAX_LENGTH` (1e5 d; 1e300 would overflow the chord below).
    """
    for name, value in (("helix_radius", radius), ("helix_pitch", pitch)):
        if not abs(value) <= MAX_LENGTH:
            raise TemplateError(f"knot.{name}={value:g}: must be within {MAX_LENGTH:g} d "
                                f"({LENGTH_WHY})")
    rise = pitch / (2.0 * math.pi)

    def chord2(d):
        return (2.0 * radius * math.sin(d / 2.0)) ** 2 + (rise * d) ** 2

    if chord2(math.pi) < bond_length**2:
        raise TemplateError(
            f"knot.helix_radius={radius:g} with knot.helix_pitch={pitch:g} cannot hold bonds "
            f"of {bond_length:g} d at up to half a turn per bond; use a larger helix_radius "
            "or helix_pitch"
        )
    lo, hi = 0.0, math.pi
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if chord2(mid) < bond_length**2 else (lo, mid)
    phi = 0.5 * (lo + hi) * np.arange(beads)
    x = np.stack([radius * np.cos(phi), radius * np.sin(phi), rise * phi], axis=1)
    return _centred(x)


def closest_nonbonded_open(x: np.ndarray) -> tuple[float, tuple[int, int]]:
    """Closest pair of beads ``i < j`` of an open chain that are not bonded (``j > i + 1``).

    Returns
    -------
    distance : float, in d (``inf`` for fewer than 3 beads)
    pair : tuple of int
    """
    n = x.shape[0]
    best, pair = math.inf, (0, 0)
    for i in range(n - 2):
        d = np.linalg.norm(x[i + 2 :] - x[i], axis=1)
        k = int(np.argmin(d))
        if d[k] < best:
            best, pair = float(d[k]), (i, i + 2 + k)
    return best, pair
