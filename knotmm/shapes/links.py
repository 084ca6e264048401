"""Links: several closed chains drawn together on one horizontal torus.

A link is built as a knot is (:mod:`knotmm.shapes.curves`), one curve per component, all on
the torus of one major radius so that the components cross one another as the diagram says:

* :func:`torus_link`: ``T(p, q)`` with ``g = gcd(p, q) > 1``: ``g`` copies of the torus knot
  ``T(p/g, q/g)``, turned about the tube's centre-line by ``2 pi g / p`` from one another
  (``T(2, 2)``: the Hopf link, ``T(2, 4)``: Solomon's link). Every component is the same
  length and gets the same number of beads.
* :func:`braid_link`: the closure of a braid whose strand permutation has several cycles,
  one component per cycle; the beads are shared in proportion to the components' lengths.
* :func:`named_link`: a common name (``hopf``, ``solomon``, ``whitehead``, ``borromean``) or
  a LinkInfo name (``L4a1{1}``, from database_knotinfo's braid notation).

Beads are placed at equal chord on each component (:func:`knotmm.shapes.curves.equal_chord`),
all at the major radius at which the component with the most beads has bonds of exactly
``bond_length``, or at a given ``major_radius`` (each component's bonds are then its
perimeter over its beads, off ``bond_length``). A torus link's components are congruent, so
all its bonds are exact; a braid link's other components differ by about ``1 / (2 n_k)``
relative (``n_k`` beads on component k; whole bead counts shared in proportion to length).
Lengths are in d.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from knotmm.errors import TemplateError
from knotmm.shapes.curves import TooFewBeads, TubeCurve, braid_curve, braid_cycles, equal_chord
from knotmm.shapes.validation import check_int, check_positive

__all__ = ["COMMON_LINKS", "LINKINFO_NAME", "LinkShape", "braid_link", "named_link",
           "torus_link"]

#: A LinkInfo link name: ``L4a1``, or with its orientation ``L4a1{1}``.
LINKINFO_NAME = re.compile(r"L\d+[an]\d+(\{[\d,]+\})?")

#: Common names of links: ("torus", (p, q)) or ("braid", word). Whitehead and Borromean
#: rings from their braid words (LinkInfo L5a1{0}, L6a4{0}).
COMMON_LINKS: dict[str, tuple[str, tuple[int, ...]]] = {
    "hopf": ("torus", (2, 2)),
    "solomon": ("torus", (2, 4)),
    "whitehead": ("braid", (-1, 2, -1, 2, -1)),
    "borromean": ("braid", (1, -2, 1, -2, 1, -2)),
}


@dataclass(frozen=True)
class LinkShape:
    """A link's bead positions, one array per component.

    Attributes
    ----------
    name : str
        What the link is (``"T(2,4)"``, ``"the closed braid [...]"``, ``"hopf"``).
    components : tuple of ndarray, each shape (n_k, 3), in d
        The closed chains, centred together (the link's centre of mass at the origin).
    major_radius : float
        The torus radius, in d.
    bond_lengths : tuple of float
        Each component's bond length, in d.
    """

    name: str
    components: tuple[np.ndarray, ...]
    major_radius: float
    bond_lengths: tuple[float, ...]

    @property
    def n_beads(self) -> int:
        return sum(c.shape[0] for c in self.components)


def _rotated_torus_curve(p: int, q: int, a: float, phase: float) -> TubeCurve:
    """``T(p, q)`` (one component, gcd 1) turned by ``phase`` about the tube centre-line."""
    k = q / p

    def offsets(t):
        angle = k * t + phase
        s, c = np.sin(angle), np.cos(angle)
        return a * s, a * c, a * k * c, -a * k * s

    return TubeCurve(offsets, p, -a, f"T({p},{q})")


def _too_few(beads: int, length: float, bond_length: float, what: str) -> TemplateError:
    need = math.ceil(length / bond_length) + 1
    return TemplateError(
        f"knot.beads={beads} is too few for {what}: the smallest torus that holds it needs "
        f"{length:.3g} d of chain at bond length {bond_length:g} d; use knot.beads > {need} "
        f"or a smaller knot.minor_radius"
    )


def _shared_radius(curves: Sequence[TubeCurve], beads: int, bond_length: float,
                   what: str) -> float:
    """The major radius at which the curves together are ``beads * bond_length`` long (a
    first guess, arc length rather than chords), in d."""
    target = beads * bond_length
    lowest = max(-c.rho_min for c in curves) + 1e-9

    def total(r):
        return sum(c.length(r) for c in curves)

    if total(lowest) >= target:
        raise _too_few(beads, total(lowest), bond_length, what)
    hi = max(2.0 * lowest, target / (2.0 * np.pi * sum(c.laps for c in curves)) + 1.0)
    while total(hi) < target:
        hi *= 2.0
    lo = lowest
    for _ in range(200):  # bisection: the total length is increasing in r
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if total(mid) < target else (lo, mid)
        if hi - lo <= 1e-12 * hi:
            break
    return 0.5 * (lo + hi)


def _given_radius(curves: Sequence[TubeCurve], major_radius: float, what: str) -> float:
    """``major_radius`` checked: positive, and large enough that no strand crosses the axis."""
    r0 = check_positive(major_radius, "knot.major_radius")
    reach = max(-c.rho_min for c in curves)
    if r0 <= reach:
        raise TemplateError(
            f"knot.major_radius={r0:g} is too small for {what}: the strands reach {reach:g} d "
            f"from the torus centre-line; use knot.major_radius > {reach:g} or leave it unset"
        )
    return r0


def _exact_radius(curve: TubeCurve, n: int, bond_length: float, beads: int, what: str) -> float:
    """The major radius at which ``n`` equal chords of ``curve`` are ``bond_length``."""
    try:
        return equal_chord(curve, n, None, bond_length)[1]
    except TooFewBeads as exc:
        raise _too_few(beads, exc.length * beads / n, bond_length, what) from None
    except RuntimeError:
        raise TemplateError(
            f"knot.beads={beads} is too few for {what}: the beads cannot be spaced "
            f"equally on so small a torus; use more knot.beads"
        ) from None


def _place(curves: Sequence[TubeCurve], counts: Sequence[int], r0: float, bond_length: float,
           mirror: bool, name: str, beads: int, given: bool = False) -> LinkShape:
    comps, chords = [], []
    for curve, n in zip(curves, counts, strict=True):
        if n < 3:
            raise _too_few(beads, sum(c.length(r0) for c in curves), bond_length, name)
        try:
            s, _, chord = equal_chord(curve, n, r0, bond_length)
        except (TooFewBeads, RuntimeError):
            if given:
                raise TemplateError(
                    f"knot.major_radius={r0:g} with knot.beads={beads}: the beads cannot be "
                    f"spaced equally on {name} at that radius (bonds near "
                    f"{curve.length(r0) / n:.3g} d, the bond length is {bond_length:g} d); "
                    "use a radius that gives bonds near the bond length, or leave it unset"
                ) from None
            raise TemplateError(
                f"knot.beads={beads} is too few for {name}: the beads cannot be spaced "
                f"equally on so small a torus; use more knot.beads"
            ) from None
        comps.append(curve.points(s, r0))
        chords.append(float(chord))
    if mirror:
        comps = [x * np.array([1.0, 1.0, -1.0]) for x in comps]
    centre = np.concatenate(comps).mean(axis=0)
    comps = tuple(np.ascontiguousarray(x - centre) for x in comps)
    return LinkShape(name, comps, float(r0), tuple(chords))


def torus_link(p: int, q: int, beads: int, bond_length: float = 0.6,
               minor_radius: float = 0.6, mirror: bool = False,
               major_radius: float | None = None) -> LinkShape:
    """The torus link ``T(p, q)``, ``gcd(p, q) = g > 1``: ``g`` components of ``beads / g``
    beads, each the torus knot ``T(p/g, q/g)`` (an unknot when ``p/g = 1``).

    Any two components link ``(p/g)(q/g)`` times: positive for ``p, q > 0`` (the Hopf link
    ``T(2,2)`` has linking number +1), negative for the mirror image.

    Parameters
    ----------
    p, q : int
        Laps about the z axis and turns about the tube, both >= 2 with gcd > 1.
    beads : int
        Beads of the whole link, a multiple of ``g``.
    bond_length, minor_radius : float, optional
        In d.
    mirror : bool, optional
        The mirror image (z -> -z).
    major_radius : float, optional
        The torus radius, in d; default: the radius at which the bonds are ``bond_length``.

    Raises
    ------
    TemplateError
        If ``gcd(p, q) = 1`` (a knot), ``beads`` is not a multiple of ``g``, too few, or
        ``major_radius`` is too small for the strands.
    """
    p, q = check_int(p, "knot.p", 1), check_int(q, "knot.q", 1)
    g = math.gcd(p, q)
    if g < 2:
        raise TemplateError(f"knot.p={p}, knot.q={q}: gcd 1 is a knot, not a link")
    beads = check_int(beads, "knot.beads", 3 * g)
    if beads % g:
        lo, hi = beads - beads % g, beads - beads % g + g
        raise TemplateError(
            f"knot.beads={beads} does not share equally among the {g} components of "
            f"T({p},{q}); use knot.beads = {lo} or {hi}"
        )
    bond_length = check_positive(bond_length, "model.bond_length")
    a = check_positive(minor_radius, "knot.minor_radius")
    # offsets of the meridian phase by 2 pi / p' give the same curve again (alpha -> alpha +
    # 2 pi): the g components are turned by 2 pi / (g p') from one another
    curves = [_rotated_torus_curve(p // g, q // g, a, 2.0 * np.pi * k / (g * (p // g)))
              for k in range(g)]
    name = f"T({p},{q})"
    if major_radius is not None:
        r0 = _given_radius(curves, major_radius, name)
    else:
        r0 = _exact_radius(curves[0], beads // g, bond_length, beads, name)  # all congruent
    return _place(curves, [beads // g] * g, r0, bond_length, mirror, name, beads,
                  given=major_radius is not None)


def braid_link(word: Sequence[int], beads: int, bond_length: float = 0.6,
               minor_radius: float = 0.6, mirror: bool = False,
               name: str | None = None, major_radius: float | None = None) -> LinkShape:
    """The closure of ``word`` with two or more components (cycles of its permutation).

    Component k starts in the lowest slot of its cycle; the beads are shared in proportion
    to the components' lengths at the shared major radius (at least 3 each): ``major_radius``
    (in d) if given, else the radius at which the longest component's bonds are
    ``bond_length``.

    Raises
    ------
    TemplateError
        For an empty word, a generator 0, a word whose closure is a knot, too few beads, or a
        ``major_radius`` too small for the strands.
    """
    try:
        word = [int(g) for g in word]
    except (TypeError, ValueError):
        raise TemplateError(f"knot.word={word!r}: expected a list of non-zero integers") from None
    if not word or 0 in word:
        raise TemplateError(f"knot.word={word!r}: expected a non-empty list of non-zero integers")
    strands = max(abs(g) for g in word) + 1
    cycles = braid_cycles(word, strands)
    label = name or f"the closed braid {word}"
    if len(cycles) < 2:
        raise TemplateError(f"knot.word={word}: its closure is a knot, not a link")
    beads = check_int(beads, "knot.beads", 3 * len(cycles))
    bond_length = check_positive(bond_length, "model.bond_length")
    a = check_positive(minor_radius, "knot.minor_radius")
    curves = [braid_curve(word, a, cycle=c) for c in cycles]
    if major_radius is not None:
        r0 = _given_radius(curves, major_radius, label)
        counts = _share(beads, np.array([c.length(r0) for c in curves]))
        return _place(curves, counts, r0, bond_length, mirror, label, beads, given=True)
    r0 = _shared_radius(curves, beads, bond_length, label)
    lengths = np.array([c.length(r0) for c in curves])
    counts = _share(beads, lengths)
    if min(counts) >= 3:  # the longest component's bonds exactly bond_length
        k = int(np.argmax(counts))
        r0 = _exact_radius(curves[k], counts[k], bond_length, beads, label)
    return _place(curves, counts, r0, bond_length, mirror, label, beads)


def _share(beads: int, lengths: np.ndarray) -> list[int]:
    """Whole bead counts summing to ``beads``, in proportion to ``lengths`` (largest
    remainders)."""
    exact = beads * lengths / lengths.sum()
    counts = np.floor(exact).astype(int)
    for k in np.argsort(-(exact - counts))[: beads - int(counts.sum())]:
        counts[k] += 1
    return [int(c) for c in counts]


def _linkinfo_word(name: str) -> tuple[int, ...] | None:
    """The braid word of a LinkInfo link (``L4a1{1}``; ``L4a1`` is ``L4a1{0}``), None if the
    name is not in the table or database_knotinfo is not installed."""
    try:
        from database_knotinfo import link_list
    except ImportError:
        return None
    key = name if "{" in name else f"{name}{{0}}"
    for row in link_list(True):
        if row.get("name") == key or (row.get("name_unoriented") == name and "{" not in name
                                      and not str(row.get("name", "")).count("{")):
            numbers = re.findall(r"-?\d+", str(row.get("braid_notation") or ""))
            return tuple(int(n) for n in numbers[1:]) if len(numbers) > 1 else None
    return None


def named_link(name: str, beads: int, bond_length: float = 0.6, minor_radius: float = 0.6,
               mirror: bool = False, major_radius: float | None = None) -> LinkShape:
    """A link by name: :data:`COMMON_LINKS` or a LinkInfo name such as ``L4a1{1}`` (needs
    database_knotinfo; ``L4a1`` means its orientation ``{0}``). ``major_radius``: as for
    :func:`torus_link` and :func:`braid_link`.

    Raises
    ------
    TemplateError
        For a name in neither table.
    """
    key = str(name).strip()
    common = COMMON_LINKS.get(key.lower())
    if common is not None:
        kind, data = common
        if kind == "torus":
            shape = torus_link(*data, beads, bond_length, minor_radius, mirror, major_radius)
            return LinkShape(f"{key.lower()} link {shape.name}", shape.components,
                             shape.major_radius, shape.bond_lengths)
        return braid_link(data, beads, bond_length, minor_radius, mirror,
                          name=f"the {key.lower()} link", major_radius=major_radius)
    if LINKINFO_NAME.fullmatch(key):
        word = _linkinfo_word(key)
        if word is not None:
            return braid_link(word, beads, bond_length, minor_radius, mirror, name=key,
                              major_radius=major_radius)
        try:
            import database_knotinfo  # noqa: F401
        except ImportError:
            raise TemplateError(
                f"knot.name={name!r}: LinkInfo links need the optional package "
                f"database_knotinfo: pip install 'knotmm[knots]'"
            ) from None
        from database_knotinfo import link_list

        base = key.partition("{")[0]
        known = [str(r["name"]) for r in link_list(True) if r.get("name_unoriented") == base]
        hint = (f"{base} is there as {', '.join(known)}: the braces give the orientation, one "
                f"0 or 1 per component after the first" if known
                else "links named like 'L4a1{1}'")
        raise TemplateError(f"knot.name={name!r} is not in the LinkInfo tables ({hint})")
    raise TemplateError(
        f"knot.name={name!r} is not a link name: use {', '.join(COMMON_LINKS)} or a LinkInfo "
        f"name such as 'L4a1{{1}}'"
    )
