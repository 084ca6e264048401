"""Knot templates: starting shapes of the bead chain, built and checked before any run.

Every template is a closed polygon of ``beads`` points, in model units (d), with its centre of
mass at the origin. Three sources:

* **Torus knots** ``T(p, q)``, from the parametrisation of the study on a horizontal torus
  (axis along z), major radius ``r0``, minor radius ``a``, ``alpha`` in ``[0, 2 pi p)``::

      rho = r0 + a sin(q alpha / p),  z = a cos(q alpha / p),  azimuth = alpha

  ``T(2, 3)`` unmirrored is right-handed (positive writhe). ``T(p, q)`` and ``T(q, p)`` are
  the same knot type but different shapes: ``p`` loops around the vertical axis winding
  ``q`` times around the tube.
* **Closed braids**: a braid word of signed generator indices (``[1, -2, 1, -2]`` is the
  figure-eight knot) drawn on a horizontal torus. The ``n`` strands run around the vertical
  axis at the torus radius, stacked one above the other ``2 a`` apart (``a`` = minor
  radius); each generator ``sigma_i`` takes an equal share of the turn, in which strands
  ``i`` and ``i + 1`` (counted from the bottom) swap places by a smooth half turn about their
  midpoint, one passing inside (nearer the axis) and one outside. A positive generator is a
  positive (right-handed) crossing, so ``[1, 1, 1]`` is the right-handed trefoil, the same
  shape as T(2,3). Named knots (``"5_2"``) use the braid words of
  the KnotInfo tables: a small built-in table covers the experiments' knots (3_1, 4_1, 5_1,
  5_2, 6_1, 7_1), the optional ``database_knotinfo`` package all tabulated knots.
* **Files**: any frame of a PDB file, or of a DCD file with its topology PDB.

Beads are placed at equal chord along the curve, so every bond has the same length. When the
major radius is left unset (``None``) it is chosen so that this length is exactly the
model's bond length; when it is given, the bond length follows from it (perimeter / beads)
and the checks report a mismatch.

:func:`build_template` turns a run file's ``[knot]`` table into a checked :class:`Template`
and raises :class:`knotmm.errors.TemplateError` naming the run-file key to change.

Examples
--------
>>> x = torus_knot(2, 3, beads=120)
>>> x.shape
(120, 3)
>>> from knotmm.knots.identify import writhe
>>> writhe(x) > 0
True
"""

from __future__ import annotations

import functools
import json
import logging
import math
import os
import re
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import scipy.optimize
import scipy.sparse
import scipy.sparse.linalg
import scipy.spatial.distance

from knotmm.errors import TemplateError, TrajectoryFileError
from knotmm.knots.identify import (
    UNKNOWN,
    identify_knot,
    normalise_knot_name,
    quiet_output,
    topoly_available,
    writhe,
)
from knotmm.units import LJ_CUTOFF_FACTOR, angstrom_to_d

__all__ = [
    "BUILTIN_BRAIDS",
    "BOND_TOLERANCE",
    "Template",
    "TemplateCheck",
    "braid_knot",
    "build_template",
    "check_template",
    "from_file",
    "knotinfo_available",
    "list_named_knots",
    "minimal_beads",
    "named_knot",
    "named_knot_word",
    "torus_knot",
]

logger = logging.getLogger(__name__)

#: Largest relative deviation of a template bond from the model's bond length (0.5 %).
BOND_TOLERANCE = 0.005

#: Braid words of the experiments' knots, available without ``database_knotinfo``. Each is
#: the word KnotInfo lists; each closes to the named knot (checked with topoly in the tests).
BUILTIN_BRAIDS: dict[str, tuple[int, ...]] = {
    "3_1": (1, 1, 1),
    "4_1": (1, -2, 1, -2),
    "5_1": (1, 1, 1, 1, 1),
    "5_2": (1, 1, 1, 2, -1, 2),
    "6_1": (1, 1, 2, -1, -3, 2, -3),
    "7_1": (1, 1, 1, 1, 1, 1, 1),
}

#: Amphichiral knots among the built-in ones (no handedness to report).
_BUILTIN_AMPHICHIRAL = frozenset({"4_1"})

#: Names topoly gives the torus knots of the study (checked in the tests).
_TORUS_NAMES = {
    (2, 3): "3_1",
    (2, 5): "5_1",
    (2, 7): "7_1",
    (2, 9): "9_1",
    (3, 4): "8_19",
    (3, 5): "10_124",
}

#: Default tube radius of the run files (knot.minor_radius), in d.
SCHEMA_MINOR_RADIUS = 0.6

# Largest bead count tried when looking for the smallest one that works.
_MAX_BEADS_SEARCH = 4096

# Argument names as the public functions call them; build_template uses the run-file keys.
_PLAIN = {
    "p": "p",
    "q": "q",
    "word": "word",
    "name": "name",
    "path": "path",
    "frame": "frame",
    "topology": "topology",
    "beads": "beads",
    "minor_radius": "minor_radius",
    "major_radius": "major_radius",
    "bond_length": "bond_length",
    "lj_sigma": "lj_sigma",
    "perturbation": "perturbation",
}
_KEYS = {
    **{k: f"knot.{k}" for k in _PLAIN},
    "bond_length": "model.bond_length",
    "lj_sigma": "model.lj_sigma",
}


# ----------------------------------------------------------------------------------------
# Curves on a horizontal torus
# ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _TubeCurve:
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


def _torus_curve(p: int, q: int, a: float) -> _TubeCurve:
    k = q / p

    def offsets(t):
        phase = k * t
        s, c = np.sin(phase), np.cos(phase)
        return a * s, a * c, a * k * c, -a * k * s

    return _TubeCurve(offsets, p, -a, f"T({p},{q})")


def _smooth_half_turn(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Angle 0 -> pi over u in [0, 1] with zero rate at both ends; and d(angle)/du."""
    theta = np.pi * (u - np.sin(2.0 * np.pi * u) / (2.0 * np.pi))
    dtheta = np.pi * (1.0 - np.cos(2.0 * np.pi * u))
    return theta, dtheta


def _braid_cycles(word: Sequence[int], strands: int) -> list[list[int]]:
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


def _braid_curve(word: Sequence[int], a: float, tilt: float = np.pi / 2) -> _TubeCurve:
    """The closed braid of ``word`` (one component; checked by the caller).

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
    (cycle,) = _braid_cycles(word, strands)
    # slot_at[lap, k]: slot of the travelling strand at the start of section k of lap
    slot_at = np.empty((strands, m), dtype=int)
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
        lap = np.clip(np.floor(t / (2.0 * np.pi)).astype(int), 0, strands - 1)
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
    return _TubeCurve(offsets, strands, rho_min, "braid")


def _equal_arc_parameters(curve: _TubeCurve, r0: float, beads: int) -> np.ndarray:
    """Curve parameters of ``beads`` points at equal arc length (the Newton start)."""
    t, _, _ = curve._grid
    speed = curve.speed(r0)
    t = np.append(t, curve.period)
    speed = np.append(speed, speed[0])
    arc = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(t))])
    targets = np.arange(beads) * arc[-1] / beads
    return np.interp(targets, arc, t)


def _equal_chord(
    curve: _TubeCurve, beads: int, r0: float | None, bond_length: float
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
    _TooFewBeads
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
            raise _TooFewBeads(lowest, curve.length(lowest))
        hi = max(2.0 * lowest, target / (2.0 * np.pi * curve.laps) + 1.0)
        while curve.length(hi) < target:
            hi *= 2.0
        r0 = scipy.optimize.brentq(lambda r: curve.length(r) - target, lowest, hi, xtol=1e-12)
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
        jac = scipy.sparse.csc_matrix(
            (np.concatenate([d_lo, d_hi, d_extra]), (rows, cols)), shape=(n, n)
        )
        return g, jac

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
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", scipy.sparse.linalg.MatrixRankWarning)
            step = scipy.sparse.linalg.spsolve(jac, -g)
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
            raise _TooFewBeads(r0, curve.length(r0))
        chord = bond_length
    else:
        chord = float(extra)
    return s, float(r0), float(chord)


class _TooFewBeadsError(TemplateError):
    """The bead count cannot go round the template's torus (a TemplateError)."""


class _TooFewBeads(Exception):
    """The chain is too short to go round the torus at any positive major radius."""

    def __init__(self, r0: float, length: float):
        super().__init__(r0, length)
        self.r0 = r0
        self.length = length


# ----------------------------------------------------------------------------------------
# Validation helpers
# ----------------------------------------------------------------------------------------
def _check_int(value, name: str, minimum: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TemplateError(f"{name}={value!r}: expected an integer")
    if minimum is not None and value < minimum:
        raise TemplateError(f"{name}={value}: must be >= {minimum}")
    return int(value)


def _check_positive(value, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise TemplateError(f"{name}={value!r}: expected a number")
    value = float(value)
    if not (math.isfinite(value) and value > 0.0):
        raise TemplateError(f"{name}={value!r}: expected a finite number > 0")
    return value


def _check_torus(p, q, names: Mapping[str, str]) -> tuple[int, int]:
    p = _check_int(p, names["p"])
    q = _check_int(q, names["q"])
    if p < 1 or q < 1:
        raise TemplateError(
            f"{names['p']}={p}, {names['q']}={q}: both must be positive integers >= 2"
        )
    if p == 1 or q == 1:
        raise TemplateError(
            f"{names['p']}={p}, {names['q']}={q}: T({p},{q}) is the unknot; "
            "use p >= 2 and q >= 2 (T(2,3) is the trefoil)"
        )
    g = math.gcd(p, q)
    if g != 1:
        raise TemplateError(
            f"{names['p']}={p}, {names['q']}={q}: T({p},{q}) is a link of {g} components, not "
            f"a knot (p and q share the factor {g}); p and q must be coprime, e.g. "
            f"T({p},{_next_coprime(p, q)})"
        )
    return p, q


def _next_coprime(p: int, q: int) -> int:
    q += 1
    while math.gcd(p, q) != 1:
        q += 1
    return q


def _check_word(word, names: Mapping[str, str]) -> tuple[int, ...]:
    key = names["word"]
    if word is None:
        raise TemplateError(f"{key} is not set: give a braid word, e.g. [1, -2, 1, -2]")
    if isinstance(word, str):
        word = _parse_word_text(word, key)
    try:
        items = list(word)
    except TypeError:
        raise TemplateError(f"{key}={word!r}: expected a list of integers") from None
    if not items:
        raise TemplateError(f"{key}=[]: a braid word needs at least one generator")
    for g in items:
        if isinstance(g, bool) or not isinstance(g, (int, np.integer)):
            raise TemplateError(f"{key}={items!r}: expected a list of integers, got {g!r}")
        if g == 0:
            raise TemplateError(
                f"{key}={items!r}: generator 0 does not exist; use +-1, +-2, ... "
                "(sigma_i, or its inverse when negative)"
            )
    items = [int(g) for g in items]
    strands = max(abs(g) for g in items) + 1
    used = {abs(g) for g in items}
    missing = sorted(set(range(1, strands)) - used)
    cycles = _braid_cycles(items, strands)
    if len(cycles) > 1:
        hint = (
            f"generator {missing[0]} never appears, so the strands split apart"
            if missing
            else "an odd number of crossings between some strands would join them"
        )
        raise TemplateError(
            f"{key}={items!r} closes to a link of {len(cycles)} components, not a knot "
            f"({hint}); the strand permutation must be a single cycle"
        )
    return tuple(items)


def _parse_word_text(text: str, key: str) -> list[int]:
    parts = [p for p in re.split(r"[\s,]+", text.strip().strip("[](){}")) if p]
    try:
        return [int(p) for p in parts]
    except ValueError:
        raise TemplateError(
            f"{key}={text!r}: expected signed generator indices such as 1,-2,1,-2"
        ) from None


def _same_as_auto(curve, beads, major_radius, bond_length):
    """``None`` (solve for the radius) if ``major_radius`` is the automatic choice.

    A run records the radius it chose (``knot.major_radius``); given back, that radius must
    rebuild the very same template, bit for bit. Solving with the radius fixed would give
    the same beads only to rounding, so a radius within 1e-9 (relative) of the automatic
    one is treated as unset.
    """
    if major_radius is None:
        return None
    try:
        _, auto_r0, _ = _equal_chord(curve, beads, None, bond_length)
    except (_TooFewBeads, RuntimeError):
        return major_radius
    return None if abs(auto_r0 - major_radius) <= 1e-9 * major_radius else major_radius


def _place(
    curve: _TubeCurve,
    beads: int,
    bond_length: float,
    major_radius: float | None,
    mirror: bool,
    names: Mapping[str, str],
    what: str,
) -> tuple[np.ndarray, float, float]:
    """Equal-chord beads on ``curve``; positions centred, mirrored if asked."""
    beads = _check_int(beads, names["beads"], 4)
    bond_length = _check_positive(bond_length, names["bond_length"])
    if major_radius is not None:
        major_radius = _check_positive(major_radius, names["major_radius"])
        if major_radius + curve.rho_min <= 0.0:
            raise TemplateError(
                f"{names['major_radius']}={major_radius:g} is too small for {what}: the strands "
                f"reach {-curve.rho_min:g} d from the torus centre-line; use "
                f"{names['major_radius']} > {-curve.rho_min:g} or leave it unset"
            )
    try:
        s, r0, chord = _equal_chord(
            curve, beads, _same_as_auto(curve, beads, major_radius, bond_length), bond_length
        )
    except _TooFewBeads as exc:
        need = math.ceil(exc.length / bond_length) + 1
        raise _TooFewBeadsError(
            f"{names['beads']}={beads} is too few for {what}: at bond length {bond_length:g} d "
            f"the chain is {beads * bond_length:.3g} d long, but the smallest torus that "
            f"holds {what} needs {exc.length:.3g} d; use {names['beads']} > {need} or a "
            f"smaller {names['minor_radius']}"
        ) from None
    except RuntimeError:
        raise _TooFewBeadsError(
            f"{names['beads']}={beads} is too few for {what}: the beads cannot be spaced "
            f"equally on so small a torus; use more {names['beads']}"
        ) from None
    x = curve.points(s, r0)
    if mirror:
        x[:, 2] *= -1.0
    x -= x.mean(axis=0)
    return x, r0, chord


# ----------------------------------------------------------------------------------------
# Public geometry
# ----------------------------------------------------------------------------------------
def _torus_geometry(p, q, beads, bond_length, minor_radius, major_radius, mirror, names):
    p, q = _check_torus(p, q, names)
    a = _check_positive(minor_radius, names["minor_radius"])
    return _place(
        _torus_curve(p, q, a), beads, bond_length, major_radius, mirror, names, f"T({p},{q})"
    )


def torus_knot(
    p: int,
    q: int,
    beads: int,
    bond_length: float = 0.6,
    minor_radius: float = 0.6,
    major_radius: float | None = None,
    mirror: bool = False,
) -> np.ndarray:
    """Torus knot ``T(p, q)`` on a horizontal torus, beads at equal spacing.

    Parameters
    ----------
    p : int
        Loops around the vertical (z) axis, >= 2.
    q : int
        Windings around the tube, >= 2, coprime to ``p``.
    beads : int
        Number of beads N.
    bond_length : float, optional
        Bond length l0, in d.
    minor_radius : float, optional
        Tube radius a, in d.
    major_radius : float or None, optional
        Torus radius r0, in d. ``None``: chosen so that every bond is exactly
        ``bond_length`` (r0 comes out close to ``N l0 / (2 pi p)``). Given: kept, and the
        bond length is the curve's perimeter / N (the template checks report a mismatch).
    mirror : bool, optional
        Mirror image (z -> -z). Unmirrored ``T(2, 3)`` is right-handed (writhe > 0).

    Returns
    -------
    ndarray, shape (beads, 3), float64, in d
        Bead positions, centre of mass at the origin; bead ``i`` bonded to ``i + 1`` and the
        last to the first.

    Raises
    ------
    TemplateError
        If ``p`` and ``q`` are not coprime (a link) or one is 1 (the unknot), or the beads
        are too few to go around the torus.
    """
    return _torus_geometry(p, q, beads, bond_length, minor_radius, major_radius, mirror, _PLAIN)[0]


def _braid_geometry(word, beads, bond_length, minor_radius, major_radius, mirror, names):
    word = _check_word(word, names)
    a = _check_positive(minor_radius, names["minor_radius"])
    what = f"the closed braid {list(word)}"
    return _place(_braid_curve(word, a), beads, bond_length, major_radius, mirror, names, what)


def braid_knot(
    word: Sequence[int],
    beads: int,
    bond_length: float = 0.6,
    minor_radius: float = 0.6,
    major_radius: float | None = None,
    mirror: bool = False,
) -> np.ndarray:
    """Closed braid drawn on a horizontal torus, beads at equal spacing.

    The ``n = max|g| + 1`` strands run around the z axis at radius ``major_radius``,
    stacked one above the other ``2 minor_radius`` apart (so that no strand has to wind
    tightly round the axis). Each generator takes ``2 pi / len(word)`` of the turn;
    ``g = +i`` swaps strands ``i`` and ``i + 1`` (counted from the bottom) by a smooth half
    turn about their midpoint in the vertical (rho, z) plane, the lower one passing inside:
    a positive (right-handed) crossing, so positive words have positive writhe. ``-i`` is
    the mirror crossing.

    Parameters
    ----------
    word : sequence of int
        Signed generator indices, e.g. ``[1, -2, 1, -2]`` (figure-eight knot). The closure
        must be a knot: the strand permutation a single cycle.
    beads : int
        Number of beads N.
    bond_length : float, optional
        Bond length l0, in d.
    minor_radius : float, optional
        Half the distance between neighbouring strands, in d (the radius of the half turn at
        a crossing; for a two-strand braid the same as a torus knot's tube radius).
    major_radius : float or None, optional
        Radius of the braid axis circle, in d; ``None``: chosen so every bond is exactly
        ``bond_length``.
    mirror : bool, optional
        Mirror image (z -> -z).

    Returns
    -------
    ndarray, shape (beads, 3), float64, in d
        Bead positions, centre of mass at the origin.

    Raises
    ------
    TemplateError
        For an empty word, a generator 0, a word whose closure is a link, or too few beads.
    """
    return _braid_geometry(word, beads, bond_length, minor_radius, major_radius, mirror, _PLAIN)[0]


# ----------------------------------------------------------------------------------------
# Named knots
# ----------------------------------------------------------------------------------------
def knotinfo_available() -> bool:
    """Whether the optional ``database_knotinfo`` package can be imported."""
    import importlib.util  # noqa: PLC0415

    return importlib.util.find_spec("database_knotinfo") is not None


def _normalise_name(name: str) -> str:
    """'5_2', '5.2', ' 5_2 ' -> '5_2'; '11a367' -> '11a_367' (KnotInfo spelling)."""
    return normalise_knot_name(str(name).strip())


@functools.lru_cache(maxsize=1)
def _knotinfo_table() -> dict[str, dict[str, Any]]:
    """KnotInfo's knots: name -> {'word': tuple, 'symmetry': str}; {} if not installed."""
    try:
        import database_knotinfo  # noqa: PLC0415 - optional extra
    except ImportError:
        return {}
    table: dict[str, dict[str, Any]] = {}
    for row in database_knotinfo.link_list():
        name = row.get("name", "")
        text = (row.get("braid_notation") or "").replace(" ", "")
        if not re.fullmatch(r"\d+[an]?_\d+", name) or not text.startswith("["):
            continue
        try:
            parsed = json.loads(text)
        except ValueError:
            continue
        options = parsed if parsed and isinstance(parsed[0], list) else [parsed]
        options = [o for o in options if o and all(isinstance(g, int) and g for g in o)]
        if not options:
            continue
        best = min(options, key=lambda o: (max(abs(g) for g in o), len(o)))
        table[name] = {"word": tuple(best), "symmetry": row.get("symmetry_type", "")}
    return table


def list_named_knots() -> list[str]:
    """Names of the knots :func:`named_knot` can build.

    Returns
    -------
    list of str
        The built-in knots (3_1, 4_1, 5_1, 5_2, 6_1, 7_1) and, if ``database_knotinfo`` is
        installed, every knot of the KnotInfo tables (up to 13 crossings), in table order
        (by crossing number).
    """
    names = dict.fromkeys(BUILTIN_BRAIDS)
    names.update(dict.fromkeys(_knotinfo_table()))
    return sorted(names, key=_name_order)


def _name_order(name: str) -> tuple[int, str, int]:
    m = re.fullmatch(r"(\d+)([an]?)_(\d+)", name)
    if not m:
        return (10**6, name, 0)
    return int(m.group(1)), m.group(2), int(m.group(3))


def named_knot_word(name: str, key: str = "name") -> tuple[str, tuple[int, ...], str]:
    """The braid word of a named knot.

    Parameters
    ----------
    name : str
        Knot name, ``"5_2"`` (Rolfsen) or ``"11a_367"`` (KnotInfo, 11-13 crossings).
    key : str, optional
        Argument name used in error messages.

    Returns
    -------
    name : str
        The normalised name.
    word : tuple of int
        Its braid word.
    source : str
        ``"built-in"`` or ``"KnotInfo"``.

    Raises
    ------
    TemplateError
        For a name in neither table; says whether ``database_knotinfo`` is missing.
    """
    if not isinstance(name, str) or not name.strip():
        raise TemplateError(f"{key}={name!r}: expected a knot name such as '5_2'")
    norm = _normalise_name(name)
    if norm in BUILTIN_BRAIDS:
        return norm, BUILTIN_BRAIDS[norm], "built-in"
    if norm == "0_1":
        raise TemplateError(
            f"{key}={name!r}: the unknot has no braid word in the tables; knotmm starts from "
            "knots (e.g. '3_1')"
        )
    table = _knotinfo_table()
    if norm in table:
        return norm, table[norm]["word"], "KnotInfo"
    builtin = ", ".join(BUILTIN_BRAIDS)
    if not knotinfo_available():
        raise TemplateError(
            f"{key}={name!r} is not a built-in knot ({builtin}); other knots need the optional "
            "package database_knotinfo: pip install 'knotmm[knots]'"
        )
    import difflib  # noqa: PLC0415

    close = difflib.get_close_matches(norm, list(table), n=1)
    hint = f"; did you mean '{close[0]}'?" if close else ""
    raise TemplateError(
        f"{key}={name!r} is not in the KnotInfo tables (knots up to 13 crossings, named like "
        f"'5_2' or '11a_367'){hint}"
    )


def _symmetry(name: str) -> str:
    """KnotInfo's symmetry type of a knot name ('' when unknown)."""
    if name == "0_1":
        return "fully amphicheiral"
    if name in BUILTIN_BRAIDS:
        return "fully amphicheiral" if name in _BUILTIN_AMPHICHIRAL else "chiral"
    return _knotinfo_table().get(name, {}).get("symmetry", "")


def named_knot(
    name: str,
    beads: int,
    bond_length: float = 0.6,
    minor_radius: float = 0.6,
    major_radius: float | None = None,
    mirror: bool = False,
) -> np.ndarray:
    """A knot from the tables, drawn as its closed braid (see :func:`braid_knot`).

    Parameters
    ----------
    name : str
        ``"3_1"``, ``"4_1"``, ``"5_1"``, ``"5_2"``, ``"6_1"``, ``"7_1"`` always; any knot of
        the KnotInfo tables (``"8_17"``, ``"11a_367"``, ...) with ``database_knotinfo``.
    beads, bond_length, minor_radius, major_radius, mirror
        As for :func:`braid_knot`.

    Returns
    -------
    ndarray, shape (beads, 3), float64, in d
        Bead positions, centre of mass at the origin.
    """
    _, word, _ = named_knot_word(name, "name")
    return _braid_geometry(word, beads, bond_length, minor_radius, major_radius, mirror, _PLAIN)[0]


# ----------------------------------------------------------------------------------------
# Files
# ----------------------------------------------------------------------------------------
def _find_topology(path: Path, topology, names) -> Path:
    if topology is not None:
        top = Path(topology)
        if not top.is_file():
            raise TrajectoryFileError(
                f"{names['topology']}={str(topology)!r}: file not found; give the PDB written "
                "with the trajectory"
            )
        return top
    for candidate in (path.with_suffix(".pdb"), path.parent / "topology.pdb"):
        if candidate.is_file():
            return candidate
    raise TrajectoryFileError(
        f"{names['path']}={str(path)!r} is a DCD file, which holds no topology, and no "
        f"{path.with_suffix('.pdb').name} or topology.pdb lies beside it; set "
        f"{names['topology']} to its PDB file"
    )


def _frame_index(frame, n_frames: int, path: Path, names, claimed: int = 0) -> int:
    frame = _check_int(frame, names["frame"])
    if n_frames == 0:
        raise TrajectoryFileError(
            f"{names['path']}={str(path)!r} holds no complete frame"
            + (f" (its header claims {claimed}): the file is truncated" if claimed else "")
        )
    if claimed > n_frames and n_frames <= frame < claimed:
        raise TrajectoryFileError(
            f"{names['path']}={str(path)!r} is truncated: its header claims {claimed} frames but "
            f"only {n_frames} are complete, so {names['frame']}={frame} is missing; use "
            f"{names['frame']} < {n_frames} (or -1, the last complete frame)"
        )
    if not -n_frames <= frame < n_frames:
        raise TemplateError(
            f"{names['frame']}={frame} is out of range: {path.name} has {n_frames} frame"
            f"{'s' if n_frames != 1 else ''} (0..{n_frames - 1}, or -{n_frames}..-1 from the end)"
        )
    return frame % n_frames


def _read_file(path, frame, topology, names) -> np.ndarray:
    import mdtraj  # noqa: PLC0415

    if path is None:
        raise TemplateError(f"{names['path']} is not set: give a PDB or DCD file")
    path = Path(os.fspath(path))
    if not path.exists():
        raise TrajectoryFileError(f"{names['path']}={str(path)!r}: file not found")
    if path.is_dir():
        if (path / "trajectory.dcd").is_file():  # a run directory
            path = path / "trajectory.dcd"
        else:
            raise TrajectoryFileError(
                f"{names['path']}={str(path)!r} is a directory without trajectory.dcd; give a "
                "PDB or DCD file"
            )
    if path.stat().st_size == 0:
        raise TrajectoryFileError(f"{names['path']}={str(path)!r} is empty")
    suffix = path.suffix.lower()
    if suffix == ".pdb":
        if not _has_atoms(path):
            raise TrajectoryFileError(
                f"{names['path']}={str(path)!r} holds no ATOM or HETATM records: not a PDB file "
                "of beads"
            )
        try:
            traj = mdtraj.load_pdb(os.fspath(path), standard_names=False)
        except Exception as exc:  # mdtraj raises many kinds on a bad file
            raise TrajectoryFileError(
                f"{names['path']}={str(path)!r} cannot be read as PDB: {_one_line(exc)}"
            ) from None
        if traj.n_atoms == 0:
            raise TrajectoryFileError(f"{names['path']}={str(path)!r} holds no atoms")
        index = _frame_index(frame, traj.n_frames, path, names)
        xyz_angstrom = traj.xyz[index] * 10.0  # mdtraj keeps nm
    elif suffix == ".dcd":
        top_path = _find_topology(path, topology, names)
        try:
            top = mdtraj.load_pdb(os.fspath(top_path), standard_names=False)
        except Exception as exc:
            raise TrajectoryFileError(
                f"{names['topology']}={str(top_path)!r} cannot be read as PDB: {_one_line(exc)}"
            ) from None
        claimed = _dcd_claimed_frames(path)
        try:
            with quiet_output(), mdtraj.formats.DCDTrajectoryFile(os.fspath(path), "r") as fh:
                n_frames = len(fh)
                n_atoms = _dcd_atoms(fh)
                if n_atoms is not None and n_atoms != top.n_atoms:
                    raise TrajectoryFileError(
                        f"{names['path']}={str(path)!r} has {n_atoms} atoms per frame but its "
                        f"topology {top_path.name} has {top.n_atoms}; give the matching "
                        f"{names['topology']}"
                    )
                index = _frame_index(frame, n_frames, path, names, claimed)
                fh.seek(index)
                xyz, _, _ = fh.read(n_frames=1)
        except (TemplateError, TrajectoryFileError):
            raise
        except Exception as exc:
            raise TrajectoryFileError(
                f"{names['path']}={str(path)!r} cannot be read as DCD (truncated or not a DCD "
                f"file?): {_one_line(exc)}"
            ) from None
        if claimed > n_frames:
            logger.warning(
                "%s is truncated: its header claims %d frames, %d are complete; using frame %d",
                path,
                claimed,
                n_frames,
                index,
            )
        if xyz.shape[0] != 1:
            raise TrajectoryFileError(
                f"{names['path']}={str(path)!r} is truncated: frame {index} could not be read"
            )
        if xyz.shape[1] != top.n_atoms:
            raise TrajectoryFileError(
                f"{names['path']}={str(path)!r} has {xyz.shape[1]} atoms per frame but its "
                f"topology {top_path.name} has {top.n_atoms}; give the matching "
                f"{names['topology']}"
            )
        xyz_angstrom = np.asarray(xyz[0], dtype=np.float64)
    else:
        raise TrajectoryFileError(f"{names['path']}={str(path)!r}: expected a .pdb or .dcd file")
    x = angstrom_to_d(np.asarray(xyz_angstrom, dtype=np.float64))
    if not np.all(np.isfinite(x)):
        raise TrajectoryFileError(
            f"{names['path']}={str(path)!r}: frame {frame} holds non-finite coordinates"
        )
    if x.shape[0] < 4:
        raise TemplateError(
            f"{names['path']}={str(path)!r} holds {x.shape[0]} beads: a knot needs at least 4"
        )
    return x


def _has_atoms(path: Path) -> bool:
    try:
        with open(path, errors="replace") as fh:
            return any(line.startswith(("ATOM", "HETATM")) for line in fh)
    except OSError:
        return False


def _dcd_claimed_frames(path: Path) -> int:
    """Frame count written in a DCD header (0 if unreadable or not set)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(12)
    except OSError:
        return 0
    if len(head) < 12:
        return 0
    for order in ("<", ">"):
        marker = int.from_bytes(head[:4], "little" if order == "<" else "big")
        if marker == 84 and head[4:8] == b"CORD":
            return max(
                0, int.from_bytes(head[8:12], "little" if order == "<" else "big", signed=True)
            )
    return 0


def _dcd_atoms(fh) -> int | None:
    for attr in ("n_atoms", "_n_atoms"):
        value = getattr(fh, attr, None)
        if isinstance(value, (int, np.integer)):
            return int(value)
    return None


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return text or type(exc).__name__


def from_file(path, frame: int = 0, topology=None) -> np.ndarray:
    """Bead positions from one frame of a PDB or DCD file.

    Parameters
    ----------
    path : str or Path
        A PDB file (any MODEL) or a DCD file (lengths in Angstrom, as knotmm writes them);
        a run directory stands for its ``trajectory.dcd``.
    frame : int, optional
        Frame index; negative counts from the end (-1: the last frame).
    topology : str or Path, optional
        The PDB belonging to a DCD file. Default: ``path`` with suffix ``.pdb``, or
        ``topology.pdb`` in the same folder.

    Returns
    -------
    ndarray, shape (n_beads, 3), float64, in d
        The frame's coordinates converted from Angstrom (1 d = 10 A), as stored (not
        centred); the chain is read in atom order and closed from the last bead to the
        first.

    Raises
    ------
    TrajectoryFileError
        For a missing, empty, truncated or unreadable file, or a DCD whose atom count does
        not match its topology.
    TemplateError
        For a frame out of range.
    """
    return _read_file(path, frame, topology, _PLAIN)


# ----------------------------------------------------------------------------------------
# Checks
# ----------------------------------------------------------------------------------------
@dataclass
class TemplateCheck:
    """What :func:`check_template` measured.

    Attributes
    ----------
    n_beads : int
    bond_min, bond_max, bond_mean : float
        Bond lengths, in d (the ring-closing bond included).
    bond_error : float
        Largest relative deviation ``|l - bond_length| / bond_length``.
    worst_bond : int
        Index ``i`` of the bond ``(i, i + 1 mod N)`` with that deviation.
    min_distance : float
        Smallest distance between beads that are not bonded, in d.
    closest_pair : tuple of int
        The two beads at that distance.
    steric_range : float
        ``2**(1/6) lj_sigma``, in d.
    writhe : float
    knot_type : str or None
        From topoly; ``None`` if not checked.
    problems : list of str
        One line per failed check (empty when all pass).
    notes : list of str
        Remarks that are not failures (e.g. knot type not checked).
    amphichiral : bool or None
        Whether topoly finds the knot type equal to its mirror image (``None``: not
        checked or type unknown).
    """

    n_beads: int
    bond_min: float
    bond_max: float
    bond_mean: float
    bond_error: float
    worst_bond: int
    min_distance: float
    closest_pair: tuple[int, int]
    steric_range: float
    writhe: float
    knot_type: str | None
    problems: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    amphichiral: bool | None = None

    @property
    def ok(self) -> bool:
        """True when no check failed."""
        return not self.problems


def _closest_nonbonded(x: np.ndarray) -> tuple[float, tuple[int, int]]:
    n = x.shape[0]
    d = scipy.spatial.distance.pdist(x)
    i, j = np.triu_indices(n, k=1)
    bonded = (j - i == 1) | ((i == 0) & (j == n - 1))
    d = np.where(bonded, np.inf, d)
    k = int(np.argmin(d))
    return float(d[k]), (int(i[k]), int(j[k]))


def _unsigned(name: str | None) -> str | None:
    """'+3_1' -> '3_1', '+3_1#-3_1' -> '3_1#3_1' (topoly's chirality marks removed)."""
    if name is None:
        return None
    return re.sub(r"(^|(?<=[|#]))[+-]", "", name)


def _same_knot(found: str, expected: str) -> bool:
    def norm(name):
        return {_normalise_name(n.lstrip("+-")) for n in name.split("|")}

    return bool(norm(found) & norm(expected))


def _identify(x: np.ndarray, expected: str | None, report: TemplateCheck) -> None:
    """Fill in the knot type (and problems/notes) of a check report, with topoly."""
    signed_all = identify_knot(x, chiral=True, minimal=False)
    if signed_all is None:
        return
    if signed_all == UNKNOWN:
        report.knot_type = UNKNOWN
        if expected is not None:
            report.notes.append(
                f"knot type not confirmed: topoly could not name it (expected {expected})"
            )
        return
    # several knots may share the polynomial ('10_132|5_1'): the claimed one if it is among
    # them, else those with the fewest crossings
    candidates = [c for c in signed_all.split("|") if c]
    plain = [_unsigned(c) for c in candidates]
    if expected is not None and any(_same_knot(p, expected) for p in plain):
        chosen = [c for c, p in zip(candidates, plain, strict=True) if _same_knot(p, expected)]
    else:
        fewest = min(_crossing_number(p) for p in plain)
        chosen = [
            c for c, p in zip(candidates, plain, strict=True) if _crossing_number(p) == fewest
        ]
    names = list(dict.fromkeys(_normalise_name(_unsigned(c)) for c in chosen))
    report.knot_type = "|".join(names)
    report.amphichiral = not any(re.search(r"(^|#)[+-]", c) for c in chosen)
    others = sorted({_normalise_name(p) for p in plain} - set(names), key=_name_order)
    fewest = min(_crossing_number(p) for p in plain)
    simplest = expected is not None and _crossing_number(names[0]) == fewest
    if others and not simplest:
        report.notes.append(
            f"the HOMFLY-PT polynomial does not tell {report.knot_type} from {', '.join(others)}"
        )
    if expected is not None and not _same_knot(report.knot_type, expected):
        report.problems.append(f"the template is the knot {report.knot_type}, not {expected}")


def _crossing_number(name: str) -> int:
    """Crossing number of a prime knot name, sum over a composite ('3_1#3_1' -> 6)."""
    return sum(int(m) for m in re.findall(r"(?:^|#)(\d+)", name)) or 10**6


def check_template(
    positions,
    bond_length: float,
    lj_sigma: float,
    *,
    bond_tolerance: float | None = BOND_TOLERANCE,
    expected_knot: str | None = None,
    identify: bool = True,
    min_distance: float | None = None,
    raise_errors: bool = False,
) -> TemplateCheck:
    """Check a template before a run: bonds, steric overlaps, knot type.

    Parameters
    ----------
    positions : array_like, shape (n_beads, 3), in d
        Closed chain (last bead bonded to the first).
    bond_length : float
        The model's bond length l0, in d.
    lj_sigma : float
        The steric length sigma, in d; non-bonded beads must be at least ``2**(1/6) sigma``
        apart (the range of the truncated Lennard-Jones repulsion).
    bond_tolerance : float or None, optional
        Largest allowed relative bond deviation (default 0.5 %); ``None`` skips the check and
        only reports the bond lengths.
    expected_knot : str, optional
        Knot name the template must have (``"3_1"``); compared with topoly's answer.
    identify : bool, optional
        Whether to identify the knot type with topoly (when installed).
    min_distance : float, optional
        Smallest allowed non-bonded distance, in d; default the steric range.
    raise_errors : bool, optional
        Raise :class:`TemplateError` with the first problem instead of returning it.

    Returns
    -------
    TemplateCheck
        Measurements, ``problems`` (failed checks) and ``notes``.
    """
    x = np.asarray(positions, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 3 or x.shape[0] < 4:
        raise TemplateError(
            f"positions has shape {x.shape}: expected (n_beads, 3) with n_beads >= 4"
        )
    if not np.all(np.isfinite(x)):
        raise TemplateError("positions contains non-finite coordinates")
    bond_length = _check_positive(bond_length, "bond_length")
    lj_sigma = _check_positive(lj_sigma, "lj_sigma")
    n = x.shape[0]
    bonds = np.linalg.norm(np.roll(x, -1, axis=0) - x, axis=1)
    rel = np.abs(bonds - bond_length) / bond_length
    worst = int(np.argmax(rel))
    steric = LJ_CUTOFF_FACTOR * lj_sigma
    limit = steric if min_distance is None else float(min_distance)
    dmin, pair = _closest_nonbonded(x)
    wr = float(writhe(x))
    report = TemplateCheck(
        n_beads=n,
        bond_min=float(bonds.min()),
        bond_max=float(bonds.max()),
        bond_mean=float(bonds.mean()),
        bond_error=float(rel[worst]),
        worst_bond=worst,
        min_distance=dmin,
        closest_pair=pair,
        steric_range=steric,
        writhe=wr,
        knot_type=None,
    )
    if bond_tolerance is not None and rel[worst] > bond_tolerance:
        report.problems.append(
            f"bond {worst}-{(worst + 1) % n} is {bonds[worst]:.4f} d long, "
            f"{100 * rel[worst]:.2f}% off the bond length {bond_length:g} d "
            f"(allowed {100 * bond_tolerance:g}%)"
        )
    if dmin < limit:
        report.problems.append(
            f"beads {pair[0]} and {pair[1]} are {dmin:.3f} d apart, inside the steric range "
            f"{limit:.3f} d (2^(1/6) lj_sigma)"
        )
    if identify and topoly_available():
        _identify(x, expected_knot, report)
    elif identify:
        report.notes.append("knot type not checked: topoly not installed (pip install topoly)")
    if raise_errors and report.problems:
        raise TemplateError(report.problems[0])
    return report


# ----------------------------------------------------------------------------------------
# Templates from run files
# ----------------------------------------------------------------------------------------
@dataclass
class Template:
    """A checked starting shape.

    Attributes
    ----------
    positions : ndarray, shape (n_beads, 3), float64, in d
        Bead positions, centre of mass at the origin.
    description : str
        E.g. ``"T(2,3), right-handed"``.
    resolved : dict
        Dotted run-file keys -> values the run should record (``{"knot.major_radius": 4.2}``).
    writhe : float
        Writhe of the closed chain (> 0: right-handed).
    knot_type : str or None
        Knot type found by topoly (``"3_1"``), ``None`` if not checked.
    notes : list of str
        Remarks for the user and the run's record.
    check : TemplateCheck or None
        The full check report.
    """

    positions: np.ndarray
    description: str
    resolved: dict[str, Any]
    writhe: float
    knot_type: str | None
    notes: list[str] = field(default_factory=list)
    check: TemplateCheck | None = None

    @property
    def n_beads(self) -> int:
        return int(self.positions.shape[0])


def _handedness(wr: float, symmetry: str = "", amphichiral: bool | None = None) -> str:
    """'amphichiral' for a knot equal to its mirror image, else the sign of the writhe.

    The tables' symmetry type decides when known; else topoly's chiral HOMFLY-PT answer
    (which misses the chirality of a few knots, such as 9_42); else the knot is taken as
    chiral.
    """
    if symmetry:
        amphichiral = "amphicheiral" in symmetry or "amphichiral" in symmetry
    if amphichiral:
        return "amphichiral"
    return "right-handed" if wr > 0 else "left-handed"


@dataclass
class _Spec:
    """What build_template needs to rebuild the geometry at another bead count."""

    label: str
    expected: str | None
    symmetry: str
    build: Callable[[int], tuple[np.ndarray, float, float]]
    explicit_radius: bool
    resolved: dict[str, Any] = field(default_factory=dict)


def _spec_from_config(cfg, names=_KEYS) -> _Spec:
    kind = cfg["knot.kind"]
    bond = cfg["model.bond_length"]
    a = cfg["knot.minor_radius"]
    r0 = cfg["knot.major_radius"]
    mirror = bool(cfg["knot.mirror"])
    if kind == "torus":
        p, q = _check_torus(cfg["knot.p"], cfg["knot.q"], names)
        curve = _torus_curve(p, q, _check_positive(a, names["minor_radius"]))
        label = f"T({p},{q})"
        expected = _TORUS_NAMES.get((min(p, q), max(p, q)))
        symmetry = "chiral"  # every non-trivial torus knot is chiral
        resolved = {"knot.p": p, "knot.q": q}
    elif kind in ("braid", "knotinfo"):
        if kind == "braid":
            word = _check_word(cfg["knot.word"], names)
            label = f"closed braid {list(word)}"
            expected, symmetry = None, ""
            resolved = {"knot.word": list(word)}
        else:
            if cfg["knot.name"] is None:
                raise TemplateError(
                    "knot.name is not set: knot.kind = 'knotinfo' needs a knot name, e.g. "
                    "name = '5_2'"
                )
            name, word, source = named_knot_word(cfg["knot.name"], names["name"])
            word = _check_word(word, names)
            label = f"{name} (braid {list(word)}, {source})"
            expected, symmetry = name, _symmetry(name)
            resolved = {"knot.name": name}
        curve = _braid_curve(word, _check_positive(a, names["minor_radius"]))
    else:
        raise TemplateError(f"knot.kind={kind!r}: expected torus, braid, knotinfo or file")

    def build(beads: int):
        return _place(curve, beads, bond, r0, mirror, names, label.split(" (")[0])

    return _Spec(label, expected, symmetry, build, r0 is not None, resolved)


def _label_of(spec: _Spec) -> str:
    """Short name of a template spec for messages ("T(2,5)", "5_2", "closed braid [...]")."""
    return spec.label.split(" (")[0]


def _passes(spec: _Spec, beads: int, bond: float, steric: float) -> bool:
    try:
        x, _, chord = spec.build(beads)
    except TemplateError:
        return False
    if abs(chord - bond) > BOND_TOLERANCE * bond:
        return False
    return _closest_nonbonded(x)[0] >= steric


def _search_minimal(spec: _Spec, bond: float, steric: float, start: int = 4) -> int | None:
    """Smallest bead count ``n >= start`` such that every count from ``n`` up to a passing
    count found by doubling passes (odd passing counts below a failing one are ignored)."""
    hi = max(start, 16)
    while not _passes(spec, hi, bond, steric):
        hi *= 2
        if hi > _MAX_BEADS_SEARCH:
            return None
    n = hi
    while n - 1 >= start and _passes(spec, n - 1, bond, steric):
        n -= 1
    return n


def minimal_beads(cfg) -> int | None:
    """Smallest ``knot.beads`` for which the template of a run file passes the checks.

    Bond lengths and steric distances are checked at each bead count (the knot type is not
    re-checked); a given ``knot.major_radius`` is ignored (left to choose itself), since it
    fixes the bead count. The search assumes that more beads never hurt, which holds for
    the torus and braid shapes (the torus only grows).

    Parameters
    ----------
    cfg : RunConfig
        Run parameters; ``knot.kind`` must not be ``"file"``.

    Returns
    -------
    int or None
        The bead count, or ``None`` if none up to 4096 works (the minor radius is then too
        small for the steric range).
    """
    if cfg["knot.kind"] == "file":
        raise TemplateError("knot.kind='file': the file fixes the number of beads")
    spec = _spec_from_config(_AutoRadius(cfg))
    steric = LJ_CUTOFF_FACTOR * cfg["model.lj_sigma"]
    return _search_minimal(spec, cfg["model.bond_length"], steric)


class _AutoRadius(Mapping):
    """A view of a config with knot.major_radius unset."""

    def __init__(self, cfg):
        self._cfg = cfg

    def __getitem__(self, key):
        return None if key == "knot.major_radius" else self._cfg[key]

    def __iter__(self):
        return iter(self._cfg)

    def __len__(self):
        return len(self._cfg)


def _steric_message(spec: _Spec, cfg, beads: int, steric: float, problem: str) -> str:
    """The one-line error for a template with beads inside the steric range."""
    bond = cfg["model.bond_length"]
    a = cfg["knot.minor_radius"]
    what = _label_of(spec)
    if spec.explicit_radius:
        return (
            f"knot.major_radius={cfg['knot.major_radius']:g} with knot.beads={beads} is too "
            f"tight for {what}: {problem}; use a larger knot.major_radius together with more "
            "knot.beads, or leave knot.major_radius unset"
        )
    best = _search_minimal(spec, bond, steric, start=beads + 1)
    if best is not None:
        return (
            f"knot.beads={beads} is too few for {what} at knot.minor_radius={a:g}: {problem}; "
            f"use knot.beads >= {best}"
        )
    larger = f", e.g. {SCHEMA_MINOR_RADIUS:g} (the default)" if a < SCHEMA_MINOR_RADIUS else ""
    return (
        f"knot.minor_radius={a:g} is too small for {what}: {problem}, and no bead count up to "
        f"{_MAX_BEADS_SEARCH} helps; use a larger knot.minor_radius{larger}"
    )


def build_template(cfg) -> Template:
    """Build and check the starting shape a run file asks for.

    Parameters
    ----------
    cfg : RunConfig
        Uses ``knot.*`` (kind, p, q, word, name, path, frame, topology, beads,
        minor_radius, major_radius, mirror, perturbation, seed), ``model.bond_length``,
        ``model.lj_sigma`` and ``run.seed``.

    Returns
    -------
    Template
        Centred positions in d, a description, the resolved keys to record
        (``knot.major_radius`` when chosen automatically, ``knot.beads`` for a file,
        ``knot.seed`` when a perturbation was applied), writhe, knot type and notes.

    Raises
    ------
    TemplateError
        With one line naming the run-file key to change: an impossible specification (a
        link, the unknot, an unknown name), too few beads, bonds off the bond length by more
        than 0.5 %, beads inside the steric range, or a template of the wrong knot type.
    TrajectoryFileError
        For ``knot.kind = "file"`` with a missing, truncated or mismatched file.

    Notes
    -----
    A perturbation (``knot.perturbation`` > 0) adds independent normal displacements of that
    standard deviation, in d, to every coordinate of every bead, drawn from
    ``numpy.random.default_rng(knot.seed or run.seed)``. Bond lengths are checked before the
    perturbation, the steric distance and the knot type after it.
    """
    kind = cfg["knot.kind"]
    bond = _check_positive(cfg["model.bond_length"], "model.bond_length")
    sigma = _check_positive(cfg["model.lj_sigma"], "model.lj_sigma")
    steric = LJ_CUTOFF_FACTOR * sigma
    notes: list[str] = []
    resolved: dict[str, Any] = {}
    spec = None
    if kind == "file":
        x = _read_file(cfg["knot.path"], cfg["knot.frame"], cfg["knot.topology"], _KEYS)
        x = x - x.mean(axis=0)
        if cfg["knot.mirror"]:
            x[:, 2] *= -1.0
        n = x.shape[0]
        resolved["knot.beads"] = n
        if cfg["knot.beads"] != n:
            notes.append(f"knot.beads={cfg['knot.beads']} ignored: the file holds {n} beads")
        label = f"{Path(cfg['knot.path']).name} frame {cfg['knot.frame']}"
        expected, symmetry = None, ""
    else:
        spec = _spec_from_config(cfg)
        beads = _check_int(cfg["knot.beads"], "knot.beads", 4)
        what = _label_of(spec)
        try:
            x, r0, chord = spec.build(beads)
        except _TooFewBeadsError as exc:
            best = _search_minimal(spec, bond, steric, start=beads + 1)
            if best is None:
                raise
            detail = str(exc).split(": ", 1)[1].split("; use")[0]
            raise TemplateError(
                f"knot.beads={beads} is too few for {what}: {detail}; use knot.beads >= {best}"
            ) from None
        resolved.update(spec.resolved)
        resolved["knot.major_radius"] = r0
        resolved["knot.beads"] = beads
        label, expected, symmetry = spec.label, spec.expected, spec.symmetry
        rel = abs(chord - bond) / bond
        if rel > BOND_TOLERANCE:
            perimeter = chord * beads
            fit = max(4, round(perimeter / bond))
            hint = ""
            try:
                _, r_fit, _ = _spec_from_config(_AutoRadius(cfg)).build(fit)
                hint = f" (knot.beads={fit} fits knot.major_radius={r_fit:.4g})"
            except TemplateError:
                pass
            raise TemplateError(
                f"knot.major_radius={cfg['knot.major_radius']:g} with knot.beads={beads} gives "
                f"bonds of {chord:.4f} d, {100 * rel:.1f}% off model.bond_length={bond:g} "
                f"(allowed {100 * BOND_TOLERANCE:g}%): the bead count fixes the radius; leave "
                f"knot.major_radius unset{hint}"
            )
        pre = check_template(x, bond, sigma, identify=False)
        if pre.problems:
            raise TemplateError(_steric_message(spec, cfg, beads, steric, pre.problems[0]))

    perturbation = float(cfg["knot.perturbation"])
    if perturbation > 0.0:
        seed = cfg["knot.seed"] if cfg["knot.seed"] is not None else cfg["run.seed"]
        rng = np.random.default_rng(seed)
        x = x + rng.normal(scale=perturbation, size=x.shape)
        x -= x.mean(axis=0)
        resolved["knot.seed"] = int(seed)
        notes.append(f"perturbed by {perturbation:g} d (std per coordinate), seed {seed}")

    is_file = kind == "file"
    check = check_template(
        x,
        bond,
        sigma,
        bond_tolerance=None if (is_file or perturbation > 0.0) else BOND_TOLERANCE,
        expected_knot=expected,
        min_distance=sigma if is_file else None,
    )
    notes.extend(check.notes)
    if is_file and check.min_distance < steric:
        notes.append(
            f"beads {check.closest_pair[0]} and {check.closest_pair[1]} are "
            f"{check.min_distance:.3f} d apart, inside the steric range {steric:.3f} d"
        )
    if is_file:
        rel = check.bond_error
        if rel > BOND_TOLERANCE:
            notes.append(
                f"bonds range {check.bond_min:.3f}-{check.bond_max:.3f} d "
                f"(model.bond_length={bond:g})"
            )
        if check.bond_max > cfg["run.max_bond_length"]:
            raise TemplateError(
                f"knot.path={cfg['knot.path']!r} frame {cfg['knot.frame']}: bond "
                f"{check.worst_bond} is {check.bond_max:.3f} d, longer than "
                f"run.max_bond_length={cfg['run.max_bond_length']:g}; is this a knotmm "
                "chain in bead order?"
            )
    if check.problems:
        problem = check.problems[0]
        if perturbation > 0.0:
            raise TemplateError(
                f"knot.perturbation={perturbation:g} is too large: after it {problem}; use a "
                "smaller perturbation or another knot.seed"
            )
        if is_file:
            raise TemplateError(
                f"knot.path={cfg['knot.path']!r} frame {cfg['knot.frame']}: {problem}; "
                "pick another knot.frame"
            )
        raise TemplateError(f"knot.kind={kind!r} {label}: {problem}; use more knot.beads")
    if check.knot_type == "0_1" and kind == "braid":
        notes.append("the braid closes to the unknot")
    wr = check.writhe
    if kind == "file":
        description = f"{label}, writhe {wr:+.2f}"
        if check.knot_type not in (None, UNKNOWN):
            description = f"{check.knot_type} from {description}"
    else:
        if not symmetry and check.knot_type not in (None, UNKNOWN) and "|" not in check.knot_type:
            symmetry = _symmetry(check.knot_type)
        description = f"{label}, {_handedness(wr, symmetry, check.amphichiral)}"
        if cfg["knot.mirror"]:
            description += " (mirror image)"
    for note in notes:
        logger.info("template: %s", note)
    return Template(
        positions=np.ascontiguousarray(x, dtype=np.float64),
        description=description,
        resolved=resolved,
        writhe=wr,
        knot_type=check.knot_type,
        notes=notes,
        check=check,
    )
