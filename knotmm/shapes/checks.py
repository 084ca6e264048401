"""Checks of a template before a run: bond lengths, steric distances, knot type.

:func:`check_template` measures a closed chain (bonds, the closest non-bonded pair, the
writhe) and, with topoly installed, names its knot type, returning a :class:`TemplateCheck`
with the problems found. Every measurement takes memory in proportion to the number of
beads (the closest pair comes from a k-d tree, not from all pairs), so a template of tens of
thousands of beads can be checked. Units: d (``docs/model.md``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from knotmm.errors import TemplateError
from knotmm.knots.chirality import is_signed, unsigned_knot_type
from knotmm.knots.identify import (
    UNKNOWN,
    identify_knot,
    submit_identification,
    topoly_available,
)
from knotmm.knots.writhe import writhe
from knotmm.model.layout import ChainLayout
from knotmm.shapes.knotinfo import name_order, normalise_name
from knotmm.shapes.validation import check_positive
from knotmm.units import LJ_CUTOFF_FACTOR

__all__ = [
    "BOND_TOLERANCE",
    "TemplateCheck",
    "check_template",
    "closest_nonbonded",
    "judge_knot_type",
    "submit_knot_check",
]

#: Largest relative deviation of a template bond from the model's bond length (0.5 %).
BOND_TOLERANCE = 0.005

#: How a template's knot type is identified: chiral, every knot sharing the polynomial named.
_TEMPLATE_IDENTIFICATION = {"chiral": True, "minimal": False}

#: Up to this many beads the closest pair is found from all pairs (numpy, in blocks), which
#: is quicker than importing scipy.spatial (most of a second); above, with a k-d tree.
_ALL_PAIRS_BEADS = 3000
_BLOCK_PAIRS = 2_000_000  # distances held at once in that search (16 MB)


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
        From topoly's chiral HOMFLY-PT polynomial, signed as :mod:`knotmm.knots.chirality`
        spells it (``"+3_1"``, ``"4_1"``); ``None`` if not checked.
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


def closest_nonbonded(x: np.ndarray) -> tuple[float, tuple[int, int]]:
    """The closest pair of beads that are not bonded in the ring, in O(N) memory.

    A k-d tree finds each bead's four nearest beads (itself, at most two bonded ones and so
    at least one that is not bonded, hence the closest non-bonded pair); every pair within
    a hair of that distance is then measured exactly, and of exact ties the first pair in
    ``(i, j)`` order wins (as an all-pairs scan would report it).

    Parameters
    ----------
    x : ndarray, shape (n_beads, 3), in d
        A closed chain, ``n_beads >= 4``.

    Returns
    -------
    distance : float
        In d.
    pair : tuple of int
        ``(i, j)`` with ``i < j``.
    """
    n = x.shape[0]
    if n <= _ALL_PAIRS_BEADS:
        return _closest_nonbonded_all_pairs(x)
    import scipy.spatial

    tree = scipy.spatial.cKDTree(x)
    dist, idx = tree.query(x, k=min(4, n))
    i = np.repeat(np.arange(n), dist.shape[1])
    j = idx.ravel()
    keep = (i != j) & ~_bonded(np.minimum(i, j), np.maximum(i, j), n)
    reach = float(dist.ravel()[keep].min())
    pairs = tree.query_pairs(reach * (1.0 + 1e-9), output_type="ndarray")
    i, j = pairs[:, 0], pairs[:, 1]
    pairs = pairs[~_bonded(i, j, n)]
    diff = x[pairs[:, 0]] - x[pairs[:, 1]]
    # the same arithmetic as scipy's pdist, so that ties are broken alike
    d = np.sqrt(diff[:, 0] * diff[:, 0] + diff[:, 1] * diff[:, 1] + diff[:, 2] * diff[:, 2])
    best = np.flatnonzero(d == d.min())
    k = best[np.lexsort((pairs[best, 1], pairs[best, 0]))[0]]
    return float(d[k]), (int(pairs[k, 0]), int(pairs[k, 1]))


def _closest_nonbonded_all_pairs(x: np.ndarray) -> tuple[float, tuple[int, int]]:
    """:func:`closest_nonbonded` from every pair ``i < j``, a block of rows at a time."""
    n = x.shape[0]
    best, pair = np.inf, (0, 0)
    rows = max(1, _BLOCK_PAIRS // n)
    for start in range(0, n - 1, rows):
        i = np.arange(start, min(start + rows, n - 1))
        diff = x[i, None, :] - x[None, :, :]
        d = np.sqrt(diff[..., 0] * diff[..., 0] + diff[..., 1] * diff[..., 1]
                    + diff[..., 2] * diff[..., 2])
        j = np.arange(n)
        d[~(j[None, :] > i[:, None]) | _bonded(i[:, None], j[None, :], n)] = np.inf
        k = int(np.argmin(d))  # row-major: the first pair in (i, j) order wins a tie
        if d.flat[k] < best:
            best, pair = float(d.flat[k]), (int(i[k // n]), int(k % n))
    return best, pair


def _bonded(i: np.ndarray, j: np.ndarray, n: int) -> np.ndarray:
    """Whether beads ``i < j`` of a ring of ``n`` are bonded."""
    return (j - i == 1) | ((i == 0) & (j == n - 1))


def _same_knot(found: str, expected: str) -> bool:
    def norm(name):
        return {normalise_name(n.lstrip("+-")) for n in name.split("|")}

    return bool(norm(found) & norm(expected))


def submit_knot_check(x: np.ndarray):
    """Start the template's knot identification in the worker; return at once.

    Returns the handle of :func:`knotmm.knots.identify.submit_identification` (``None``
    without topoly); its ``result()`` goes to :func:`judge_knot_type`.
    """
    return submit_identification(x, **_TEMPLATE_IDENTIFICATION)


def judge_knot_type(signed_all: str | None, expected: str | None, report: TemplateCheck) -> None:
    """Fill in the knot type (and problems/notes) of a check report from topoly's answer.

    Parameters
    ----------
    signed_all : str or None
        The identification's answer (chiral, every knot sharing the polynomial listed);
        ``None``: not identified, the report is left as it is.
    expected : str or None
        The knot the template must be.
    report : TemplateCheck
        Updated in place: ``knot_type``, ``amphichiral``, ``problems``, ``notes``.
    """
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
    plain = [unsigned_knot_type(c) for c in candidates]
    if expected is not None and any(_same_knot(p, expected) for p in plain):
        chosen = [c for c, p in zip(candidates, plain, strict=True) if _same_knot(p, expected)]
    else:
        fewest = min(_crossing_number(p) for p in plain)
        chosen = [
            c for c, p in zip(candidates, plain, strict=True) if _crossing_number(p) == fewest
        ]
    names = list(dict.fromkeys(normalise_name(unsigned_knot_type(c)) for c in chosen))
    report.knot_type = "|".join(dict.fromkeys(normalise_name(c) for c in chosen))  # signed
    report.amphichiral = not any(is_signed(c) for c in chosen)
    others = sorted({normalise_name(p) for p in plain} - set(names), key=name_order)
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
    bond_length = check_positive(bond_length, "bond_length")
    lj_sigma = check_positive(lj_sigma, "lj_sigma")
    n = x.shape[0]
    bonds = ChainLayout.ring(n).bond_lengths(x)
    rel = np.abs(bonds - bond_length) / bond_length
    worst = int(np.argmax(rel))
    steric = LJ_CUTOFF_FACTOR * lj_sigma
    limit = steric if min_distance is None else float(min_distance)
    dmin, pair = closest_nonbonded(x)
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
        where = (
            f"inside the steric range {limit:.3f} d (2^(1/6) lj_sigma)"
            if min_distance is None
            else f"closer than the {limit:.3f} d allowed"
        )
        report.problems.append(f"beads {pair[0]} and {pair[1]} are {dmin:.3f} d apart, {where}")
    if identify and topoly_available():
        judge_knot_type(identify_knot(x, **_TEMPLATE_IDENTIFICATION), expected_knot, report)
    elif identify:
        report.notes.append("knot type not checked: topoly not installed (pip install topoly)")
    if raise_errors and report.problems:
        raise TemplateError(report.problems[0])
    return report

