"""Closed curves on a horizontal torus, and beads placed on them at equal chord.

Two curve families (``docs/model.md``, "Starting shapes"), both near a horizontal circle of
radius ``r0`` about the z axis:

* :func:`torus_curve`: the torus knot ``T(p, q)`` of the study, ``rho = r0 + a sin(q alpha /
  p)``, ``z = a cos(q alpha / p)``, azimuth ``alpha`` in ``[0, 2 pi p)``;
* :func:`braid_curve`: a closed braid, its strands stacked ``2 a`` apart, each generator a
  smooth half turn of two neighbouring strands.

:func:`equal_chord` places ``beads`` points on such a curve with every chord (bond) equal,
by Newton's method on the chord equations, started from equal arc length; with the major
radius left free it solves for the radius that makes the chord the model's bond length.
Lengths are in d.
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

__all__ = [
    "TooFewBeads",
    "TubeCurve",
    "braid_curve",
    "braid_cycles",
    "circle_curve",
    "equal_chord",
    "torus_curve",
]


@dataclass(frozen=True)
class TubeCurve:
    """A closed curve near a horizontal circle of radius r0 about the z axis.

    The curve is ``(r0 + rho(t)) (cos t, sin t) + z(t) e_z`` for ``t`` in
    ``[0, period)``, ``period = 2 pi laps``; ``offsets(t)`` returns ``rho, z`` and their
    derivatives in ``t``. ``rho_min`` is the smallest ``rho`` (the radius must stay > 0).
    """

    offsets: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]
    laps: int
    rho_min: float
    label: str

    @property
    def period(self) -> float:
        return 2.0 * np.pi * self.laps

    def points(self, t: np.ndarray, r0: float) -> np.ndarray:
        rho, z, _, _ = self.offsets(t)
        radius = r0 + rho
        return np.stack([radius * np.cos(t), radius * np.sin(t), z], axis=-1)

    def derivative(self, t: np.ndarray, r0: float) -> np.ndarray:
        rho, _, drho, dz = self.offsets(t)
        radius = r0 + rho
        c, s = np.cos(t), np.sin(t)
        return np.stack([drho * c - radius * s, drho * s + radius * c, dz], axis=-1)

    @functools.cached_property
    def _grid(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Fine parameter grid with ``r0``-independent parts of the speed: t, rho, rest."""
        t = np.linspace(0.0, self.period, 8192 * self.laps, endpoint=False)
        rho, _, drho, dz = self.offsets(t)
        return t, rho, drho * drho + dz * dz

    def speed(self, r0: float) -> np.ndarray:
        """|dC/dt| on the fine grid (the azimuth term is the only one that depends on r0)."""
        _, rho, rest = self._grid
        return np.sqrt(rest + (r0 + rho) ** 2)

    def length(self, r0: float) -> float:
        """Length of the curve at major radius ``r0``, in d (mean speed x period)."""
        return float(self.speed(r0).mean() * self.period)

    def length_slope(self, r0: float) -> float:
        """``d length / d r0`` (dimensionless), in (0, period]: the length is increasing
        and convex in ``r0``, each speed being ``sqrt(rest + (r0 + rho)^2)``."""
        _, rho, _ = self._grid
        return float(((r0 + rho) / self.speed(r0)).mean() * self.period)

    def radius_for_length(self, target: float, start: float) -> float:
        """The major radius at which the curve is ``target`` long, in d.

        Newton's method from ``start``, a radius at which the curve is at least ``target``
        long: on an increasing convex function the iterates then fall monotonically onto
        the root, with no overshoot, so no bracketing is needed.
        """
        r = float(start)
        for _ in range(100):
            step = (self.length(r) - target) / self.length_slope(r)
            r -= step
            if abs(step) <= 1e-13 * max(1.0, abs(r)):
                break
        return r


def torus_curve(p: int, q: int, a: float) -> TubeCurve:
    k = q / p

    def offsets(t):
        phase = k * t
        s, c = np.sin(phase), np.cos(phase)
        return a * s, a * c, a * k * c, -a * k * s

    return TubeCurve(offsets, p, -a, f"T({p},{q})")


def circle_curve() -> TubeCurve:
    """The unknot: the horizontal circle of radius r0 itself (no offsets)."""

    def offsets(t):
        zero = np.zeros_like(np.asarray(t, dtype=np.float64))
        return zero, zero, zero, zero

    return TubeCurve(offsets, 1, 0.0, "circle")


def _smooth_half_turn(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Angle 0 -> pi over u in [0, 1] with zero rate at both ends; and d(angle)/du."""
    theta = np.pi * (u - np.sin(2.0 * np.pi * u) / (2.0 * np.pi))
    dtheta = np.pi * (1.0 - np.cos(2.0 * np.pi * u))
    return theta, dtheta


def braid_cycles(word: Sequence[int], strands: int) -> list[list[int]]:
    """Cycles of the permutation of slots that one pass through the braid performs."""
    perm = list(range(strands))  # perm[start slot] = slot after the word
    for g in word:
        i = abs(g) - 1
        for s in range(strands):
            if perm[s] == i:
                perm[s] = i + 1
            elif perm[s] == i + 1:
                perm[s] = i
    seen, cycles = set(), []
    for start in range(strands):
        if start in seen:
            continue
        cycle, s = [], start
        while s not in seen:
            seen.add(s)
            cycle.append(s)
            s = perm[s]
        cycles.append(cycle)
    return cycles


def braid_curve(word: Sequence[int], a: float, tilt: float = np.pi / 2,
                cycle: Sequence[int] | None = None) -> TubeCurve:
    """The closed braid of ``word``: the one component of a knot, or the component of a
    link that starts in the slots of ``cycle`` (one of :func:`braid_cycles`).

    The strands' slots lie on a line through the tube centre in the (rho, z) cross-section,
    ``2 a`` apart, at angle ``tilt`` from the horizontal (pi / 2: stacked vertically, slot 0
    at the bottom; 0: side by side, slot 0 innermost). A swap is a smooth half turn of the
    pair about its midpoint, in the same sense of rotation of the cross-section for every
    positive generator; rotating the whole cross-section (``tilt``) changes neither the
    knot nor its handedness. Vertical stacking keeps every strand at the torus radius, so
    no strand has to wind tightly round the axis: it needs the fewest beads.
    """
    word = [int(g) for g in word]
    strands = max(abs(g) for g in word) + 1
    m = len(word)
    if cycle is None:
        (cycle,) = braid_cycles(word, strands)
    laps = len(cycle)
    # slot_at[lap, k]: slot of the travelling strand at the start of section k of lap
    slot_at = np.empty((laps, m), dtype=int)
    for lap, start in enumerate(cycle):
        s = start
        for k, g in enumerate(word):
            slot_at[lap, k] = s
            i = abs(g) - 1
            if s == i:
                s = i + 1
            elif s == i + 1:
                s = i
    pair = np.array([abs(g) - 1 for g in word])
    sign = np.array([1 if g > 0 else -1 for g in word])
    centre = (strands - 1) / 2.0
    section = 2.0 * np.pi / m

    def offsets(t):
        t = np.asarray(t, dtype=np.float64)
        lap = np.clip(np.floor(t / (2.0 * np.pi)).astype(int), 0, laps - 1)
        phi = t - 2.0 * np.pi * lap
        k = np.clip(np.floor(phi / section).astype(int), 0, m - 1)
        u = phi / section - k
        slot = slot_at[lap, k]
        i = pair[k]
        theta, dtheta = _smooth_half_turn(u)
        dtheta = dtheta / section
        # -1: the lower-slot strand of the swapping pair, +1: the upper one, 0: a bystander
        role = np.where(slot == i, -1, np.where(slot == i + 1, 1, 0))
        moving = role != 0
        mid = (i + 0.5 - centre) * 2.0 * a
        still = (slot - centre) * 2.0 * a
        # along the slot line (u) and across it (w); in a positive crossing the lower-slot
        # strand passes on the +w side (for tilt = pi/2: rho = -w, nearer the axis)
        u_ = np.where(moving, mid + role * a * np.cos(theta), still)
        w_ = np.where(moving, -role * sign[k] * a * np.sin(theta), 0.0)
        du = np.where(moving, -role * a * np.sin(theta) * dtheta, 0.0)
        dw = np.where(moving, -role * sign[k] * a * np.cos(theta) * dtheta, 0.0)
        ct, st = np.cos(tilt), np.sin(tilt)
        return ct * u_ - st * w_, st * u_ + ct * w_, ct * du - st * dw, st * du + ct * dw

    ct, st = abs(np.cos(tilt)), abs(np.sin(tilt))
    rho_min = -((strands - 1) * a * ct + a * st)
    return TubeCurve(offsets, laps, rho_min, "braid")


def _equal_arc_parameters(curve: TubeCurve, r0: float, beads: int) -> np.ndarray:
    """Curve parameters of ``beads`` points at equal arc length (the Newton start)."""
    t, _, _ = curve._grid
    speed = curve.speed(r0)
    t = np.append(t, curve.period)
    speed = np.append(speed, speed[0])
    arc = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(t))])
    targets = np.arange(beads) * arc[-1] / beads
    return np.interp(targets, arc, t)


#: Up to this many beads the placement's Newton systems are solved dense (numpy): quicker
#: than importing scipy.sparse; above, sparse (scipy.sparse.linalg.spsolve).
_DENSE_BEADS = 500


def _solve_newton_system(values, rows, cols, rhs) -> np.ndarray:
    """Solve ``A x = rhs`` for the n x n matrix with ``A[rows, cols] = values``.

    A singular matrix gives non-finite entries (the caller stops), as spsolve does.
    """
    n = rhs.shape[0]
    if n <= _DENSE_BEADS:
        a = np.zeros((n, n))
        np.add.at(a, (rows, cols), values)
        try:
            return np.linalg.solve(a, rhs)
        except np.linalg.LinAlgError:
            return np.full(n, np.nan)
    import scipy.sparse
    import scipy.sparse.linalg

    a = scipy.sparse.csc_matrix((values, (rows, cols)), shape=(n, n))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", scipy.sparse.linalg.MatrixRankWarning)
        return scipy.sparse.linalg.spsolve(a, rhs)


def equal_chord(
    curve: TubeCurve, beads: int, r0: float | None, bond_length: float
) -> tuple[np.ndarray, float, float]:
    """Place ``beads`` points on the closed curve with all chords equal.

    With ``r0`` given the common chord is solved for; with ``r0=None`` the chord is
    ``bond_length`` and the major radius is solved for. Newton's method on the ``beads``
    equations ``|C(s_{i+1}) - C(s_i)|^2 = chord^2`` (``s_0 = 0``, ``s_beads = period``),
    started from equal arc-length spacing.

    Returns
    -------
    s : ndarray, shape (beads,)
        Curve parameters of the beads.
    r0 : float
        Major radius, in d.
    chord : float
        The common bond length, in d.

    Raises
    ------
    TooFewBeads
        If no positive major radius gives the bond length (``r0=None``).
    RuntimeError
        If Newton's method fails.
    """
    n = beads
    period = curve.period
    free_radius = r0 is None
    if free_radius:
        target = n * bond_length
        lowest = -curve.rho_min + 1e-9
        if curve.length(lowest) >= target:
            raise TooFewBeads(lowest, curve.length(lowest))
        hi = max(2.0 * lowest, target / (2.0 * np.pi * curve.laps) + 1.0)
        while curve.length(hi) < target:
            hi *= 2.0
        r0 = curve.radius_for_length(target, hi)
        chord = bond_length
    else:
        chord = curve.length(r0) / n
    s = _equal_arc_parameters(curve, r0, n)
    extra = r0 if free_radius else chord

    rows = np.concatenate([np.arange(1, n), np.arange(0, n - 1), np.arange(n)])
    cols = np.concatenate([np.arange(0, n - 1), np.arange(0, n - 1), np.full(n, n - 1)])

    def residual(s, extra, jacobian=False):
        r, c = (extra, chord) if free_radius else (r0, extra)
        s_all = np.concatenate([s, [period]])
        pts = curve.points(s_all, r)
        diff = pts[1:] - pts[:-1]  # (n, 3): chord i from s_i to s_{i+1}
        g = np.einsum("ij,ij->i", diff, diff) - c * c
        if not jacobian:
            return g, None
        der = curve.derivative(s_all, r)
        # d g_i / d s_i (i >= 1) and d g_i / d s_{i+1} (i + 1 <= n - 1)
        d_lo = -2.0 * np.einsum("ij,ij->i", diff[1:], der[1:n])
        d_hi = 2.0 * np.einsum("ij,ij->i", diff[:-1], der[1:n])
        if free_radius:
            radial = np.stack([np.cos(s_all), np.sin(s_all), np.zeros_like(s_all)], axis=-1)
            d_extra = 2.0 * np.einsum("ij,ij->i", diff, radial[1:] - radial[:-1])
        else:
            d_extra = np.full(n, -2.0 * c)
        return g, np.concatenate([d_lo, d_hi, d_extra])

    def admissible(s, extra):
        if not (np.all(np.isfinite(s)) and np.isfinite(extra)):
            return False
        if np.any(np.diff(np.concatenate([s, [period]])) <= 0.0):
            return False
        return extra + curve.rho_min > 0.0 if free_radius else extra > 0.0

    # |chord^2 - c^2| below tol: relative bond error ~ tol / (2 c^2), far below 0.5 %; rounding
    # of the coordinates (up to ~100 d) leaves a floor near 1e-13 d^2
    tol = 1e-10 * bond_length**2
    converged = False
    for _ in range(100):
        g, jac = residual(s, extra, jacobian=True)
        norm = float(np.linalg.norm(g))
        if np.max(np.abs(g)) < tol:
            converged = True
            break
        step = _solve_newton_system(jac, rows, cols, -g)
        if not np.all(np.isfinite(step)):
            break
        # damped Newton: halve the step until the residual drops and beads stay in order
        alpha = 1.0
        while alpha > 1e-6:
            s_new = s.copy()
            s_new[1:] += alpha * step[:-1]
            extra_new = extra + alpha * step[-1]
            if admissible(s_new, extra_new):
                g_new, _ = residual(s_new, extra_new)
                if np.linalg.norm(g_new) < (1.0 - 1e-4 * alpha) * norm:
                    break
            alpha *= 0.5
        else:
            break
        s, extra = s_new, extra_new
    if not converged:
        raise RuntimeError("equal-chord placement did not converge")
    gaps = np.diff(np.concatenate([s, [period]]))
    if not (np.all(np.isfinite(s)) and np.all(gaps > 0) and np.isfinite(extra)):
        raise RuntimeError("equal-chord placement failed (beads out of order)")
    if free_radius:
        r0 = float(extra)
        if r0 + curve.rho_min <= 0.0:
            raise TooFewBeads(r0, curve.length(r0))
        chord = bond_length
    else:
        chord = float(extra)
    return s, float(r0), float(chord)


class TooFewBeads(Exception):
    """The chain is too short to go round the torus at any positive major radius."""

    def __init__(self, r0: float, length: float):
        super().__init__(r0, length)
        self.r0 = r0
        self.length = length
