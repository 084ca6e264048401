"""Knot templates as arrays: torus knots, closed braids, named knots, frames of files.

Every function returns a closed polygon of ``beads`` points (bead ``i`` bonded to ``i + 1``
and the last to the first), in d, centre of mass at the origin (files: as stored). Beads
sit at equal chord on the curves of :mod:`knotmm.shapes.curves`, so every bond has the same
length. When the major radius is left unset (``None``) it is chosen so that this length is
exactly the bond length; when it is given, the bond length follows from it (perimeter /
beads). See ``docs/model.md`` ("Starting shapes").

Examples
--------
>>> x = torus_knot(2, 3, beads=120)
>>> x.shape
(120, 3)
>>> from knotmm.knots.writhe import writhe
>>> writhe(x) > 0
True
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from knotmm.errors import TemplateError
from knotmm.io.structure import read_structure
from knotmm.shapes.curves import TooFewBeads, TubeCurve, braid_curve, equal_chord, torus_curve
from knotmm.shapes.knotinfo import named_knot_word
from knotmm.shapes.validation import (
    PLAIN_NAMES,
    check_int,
    check_positive,
    check_torus,
    check_word,
)

__all__ = [
    "TooFewBeadsError",
    "braid_knot",
    "from_file",
    "mirror_image",
    "named_knot",
    "place_on_curve",
    "torus_knot",
]


def mirror_image(positions) -> np.ndarray:
    """The mirror image z -> -z of a chain (a copy; a right-handed knot becomes left-handed).

    Parameters
    ----------
    positions : array_like, shape (n_beads, 3), in d

    Returns
    -------
    ndarray, shape (n_beads, 3), float64, in d
    """
    x = np.array(positions, dtype=np.float64)
    x[:, 2] *= -1.0
    return x



class TooFewBeadsError(TemplateError):
    """The bead count cannot go round the template's torus (a TemplateError)."""


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
        _, auto_r0, _ = equal_chord(curve, beads, None, bond_length)
    except (TooFewBeads, RuntimeError):
        return major_radius
    return None if abs(auto_r0 - major_radius) <= 1e-9 * major_radius else major_radius


def place_on_curve(
    curve: TubeCurve,
    beads: int,
    bond_length: float,
    major_radius: float | None,
    mirror: bool,
    names: Mapping[str, str],
    what: str,
) -> tuple[np.ndarray, float, float]:
    """Equal-chord beads on ``curve``; positions centred, mirrored if asked."""
    beads = check_int(beads, names["beads"], 4)
    bond_length = check_positive(bond_length, names["bond_length"])
    if major_radius is not None:
        major_radius = check_positive(major_radius, names["major_radius"])
        if major_radius + curve.rho_min <= 0.0:
            raise TemplateError(
                f"{names['major_radius']}={major_radius:g} is too small for {what}: the strands "
                f"reach {-curve.rho_min:g} d from the torus centre-line; use "
                f"{names['major_radius']} > {-curve.rho_min:g} or leave it unset"
            )
    try:
        s, r0, chord = equal_chord(
            curve, beads, _same_as_auto(curve, beads, major_radius, bond_length), bond_length
        )
    except TooFewBeads as exc:
        need = math.ceil(exc.length / bond_length) + 1
        raise TooFewBeadsError(
            f"{names['beads']}={beads} is too few for {what}: at bond length {bond_length:g} d "
            f"the chain is {beads * bond_length:.3g} d long, but the smallest torus that "
            f"holds {what} needs {exc.length:.3g} d; use {names['beads']} > {need} or a "
            f"smaller {names['minor_radius']}"
        ) from None
    except RuntimeError:
        raise TooFewBeadsError(
            f"{names['beads']}={beads} is too few for {what}: the beads cannot be spaced "
            f"equally on so small a torus; use more {names['beads']}"
        ) from None
    x = curve.points(s, r0)
    if mirror:
        x = mirror_image(x)
    x -= x.mean(axis=0)
    return x, r0, chord


# ----------------------------------------------------------------------------------------
# Public geometry
# ----------------------------------------------------------------------------------------
def _torus_geometry(
    p, q, beads, bond_length, minor_radius, major_radius, mirror, names=PLAIN_NAMES
):
    p, q = check_torus(p, q, names)
    a = check_positive(minor_radius, names["minor_radius"])
    return place_on_curve(
        torus_curve(p, q, a), beads, bond_length, major_radius, mirror, names, f"T({p},{q})"
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
    return _torus_geometry(p, q, beads, bond_length, minor_radius, major_radius, mirror)[0]


def _braid_geometry(
    word, beads, bond_length, minor_radius, major_radius, mirror, names=PLAIN_NAMES
):
    word = check_word(word, names)
    a = check_positive(minor_radius, names["minor_radius"])
    what = f"the closed braid {list(word)}"
    curve = braid_curve(word, a)
    return place_on_curve(curve, beads, bond_length, major_radius, mirror, names, what)


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
    return _braid_geometry(word, beads, bond_length, minor_radius, major_radius, mirror)[0]

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
    return _braid_geometry(word, beads, bond_length, minor_radius, major_radius, mirror)[0]


def from_file(path, frame: int = 0, topology=None) -> np.ndarray:
    """Bead positions from one frame of a PDB or DCD file.

    Parameters ``path`` (a PDB, a DCD or a run directory), ``frame`` (negative counts from
    the end) and ``topology`` (a DCD's PDB; default: beside it) and the errors raised are
    those of :func:`knotmm.io.structure.read_structure`.

    Returns
    -------
    ndarray, shape (n_beads, 3), float64, in d
        The frame's coordinates converted from Angstrom (1 d = 10 A), as stored (not
        centred), every bead in atom order; its chains (rings, open chains) are
        :attr:`knotmm.io.structure.Structure.layout` of ``read_structure``.
    """
    return read_structure(path, frame, topology, PLAIN_NAMES).positions

