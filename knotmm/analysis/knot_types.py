"""Handedness, rotation sense and knot type along a trajectory.

* Handedness is the sign of the writhe (``"right"``: positive), averaged over frames of
  the window, in the words of :mod:`knotmm.knots.chirality`. Writhe comes from
  :func:`knotmm.knots.writhe.writhe`.
* Rotation sense is read from the signed rotation frequency about the vertical axis
  through the centre of mass, as seen from above with gravity pointing down (towards the
  viewer's back): a positive frequency (alpha increasing, x towards y) is
  ``"counterclockwise"``.
* Knot type uses :func:`knotmm.knots.identify.identify_knot` (topoly, in knotmm's worker
  process), signed with its handedness (``"+3_1"``, ``"-5_1"``). Changes are found by
  sampling the trajectory evenly and bisecting between two samples of different types, as
  often as it takes to account for every change between them (``+5_2 -> -8_20 -> +9_24``
  gives two changes); a change that reverts between two samples can be missed.
* :func:`run_knot` names the knot of a run from what it recorded (run.toml) and says whether
  it is a torus knot T(p, q), for which the torus formulas of the study apply.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np

from knotmm.io.rundir import RUN_FILE
from knotmm.knots import chirality
from knotmm.knots.identify import identify_knot

__all__ = [
    "KnotTypes",
    "RunKnot",
    "run_knot",
    "torus_link",
    "handedness",
    "identify_signed",
    "rotation_sense",
    "knot_types",
]

logger = logging.getLogger(__name__)

#: |writhe| below this is too small to call a handedness.
WRITHE_THRESHOLD = 0.1


def handedness(writhe: float, threshold: float = WRITHE_THRESHOLD) -> str | None:
    """``"right"`` for positive writhe, ``"left"`` for negative, None if ``|writhe|`` is tiny.

    :func:`knotmm.knots.chirality.handedness` with the analysis's threshold.
    """
    if not np.isfinite(writhe) or abs(writhe) < threshold:
        return None
    return chirality.handedness(writhe)


def rotation_sense(rotation_frequency: float) -> str | None:
    """Sense of rotation seen from above (gravity pointing down), from a signed frequency.

    Parameters
    ----------
    rotation_frequency : float
        ``d alpha / dt / (2 pi)``, in 1/tau_d; alpha counted from x towards y.

    Returns
    -------
    str or None
        ``"counterclockwise"`` (positive), ``"clockwise"`` (negative), None for zero.
    """
    if not np.isfinite(rotation_frequency) or rotation_frequency == 0:
        return None
    return "counterclockwise" if rotation_frequency > 0 else "clockwise"


@dataclass
class KnotTypes:
    """Knot type along the trajectory.

    Attributes
    ----------
    initial, start, end : str or None
        Type at frame 0, at the window start and at the window end, signed (``"+3_1"``;
        None: topoly missing).
    changed_at : float or None
        Time of the first frame whose type differs from frame 0's, in tau_d; None if no
        change was found.
    changed_frame : int or None
        Its frame index.
    changes : list of dict
        Every change found, in time order: ``{"time", "frame", "from", "to"}`` (tau_d, frame
        index, signed types); the first is ``changed_at``.
    checked_frames : int
        How many frames were identified.
    notes : list of str
    """

    initial: str | None
    start: str | None
    end: str | None
    changed_at: float | None = None
    changed_frame: int | None = None
    checked_frames: int = 0
    notes: list = field(default_factory=list)
    changes: list = field(default_factory=list)

    def describe_changes(self) -> str:
        """``"+5_2 -> -8_20 at t = 30, -8_20 -> +9_24 at t = 100 tau_d"`` ('' if none)."""
        return describe_changes(self.changes)


def describe_changes(changes) -> str:
    """Knot-type changes (dicts with ``time``, ``from``, ``to``) as one phrase, in order."""
    parts = [f"{c['from']} -> {c['to']} at t = {float(c['time']):g}" for c in changes]
    return ", ".join(parts) + " tau_d" if parts else ""


def identify_signed(positions: np.ndarray) -> str | None:
    """Knot type of one frame signed with its handedness (``"-5_1"``), or None without topoly.

    :func:`knotmm.knots.identify.identify_knot` with ``chiral=True``: the spelling that
    run.toml's ``knot_type`` uses too.
    """
    return identify_knot(positions, chiral=True)


def knot_types(
    times: np.ndarray,
    positions: np.ndarray,
    start: int,
    stop: int,
    samples: int = 40,
    identify=None,
) -> KnotTypes:
    """Knot type at frame 0, at the window's ends, and the first frame where it changes.

    Parameters
    ----------
    times : ndarray, shape (n_frames,)
        In tau_d.
    positions : ndarray, shape (n_frames, n_beads, 3)
        In d.
    start, stop : int
        The window's first and last frame.
    samples : int
        Evenly spaced frames checked over the whole trajectory before bisecting.
    identify : callable, optional
        ``positions (n_beads, 3) -> str | None``; default :func:`identify_signed`.

    Returns
    -------
    KnotTypes
    """
    identify = identify or identify_signed
    cache: dict[int, str | None] = {}

    def kind(i: int) -> str | None:
        if i not in cache:
            cache[i] = identify(positions[i])
        return cache[i]

    n = len(positions)
    initial = kind(0)
    if initial is None:
        return KnotTypes(
            None,
            None,
            None,
            notes=["topoly is not installed: knot types not identified (pip install topoly)"],
        )
    grid = np.unique(np.r_[np.linspace(0, n - 1, min(samples, n)).round().astype(int), start, stop])
    changes = []
    for a, b in zip(grid[:-1], grid[1:], strict=True):
        lo, hi = int(a), int(b)
        while kind(lo) != kind(hi):  # bisect for the first frame after lo of another type
            left, right = lo, hi
            while right - left > 1:
                mid = (left + right) // 2
                if kind(mid) == kind(lo):
                    left = mid
                else:
                    right = mid
            changes.append({"time": float(times[right]), "frame": right,
                            "from": kind(left), "to": kind(right)})
            lo = right
    changed = changes[0]["frame"] if changes else None
    notes = []
    if chirality.UNKNOWN in (initial, kind(start), kind(stop)):
        notes.append("topoly could not name the knot in some frames ('unknown')")
    return KnotTypes(
        initial=initial,
        start=kind(start),
        end=kind(stop),
        changed_at=None if changed is None else float(times[changed]),
        changed_frame=changed,
        checked_frames=len(cache),
        notes=notes,
        changes=changes,
    )


@dataclass(frozen=True)
class RunKnot:
    """The knot of a run, as the run recorded it, and whether it is a torus knot.

    Attributes
    ----------
    knot_type : str or None
        Signed type (``"+5_2"``): run.toml's ``[knotmm] template_knot_type`` (else
        ``knot_type_start``), else topoly's type of frame 0, else None.
    source : str or None
        ``"run.toml"`` or ``"topoly"``: where ``knot_type`` comes from.
    description : str
        ``"T(2,3)"``, ``"5_2"``, ``"open chain"``, ``"2-component link L4a1"``, ...
    torus : tuple of int or None
        ``(p, q)`` of a torus knot T(p, q) (p the windings about the vertical axis), None
        for any other knot, a link or an open chain. ``(None, None)``: a torus knot assumed
        (no run file says otherwise), p taken from the data.
    torus_source : str or None
        ``"run file"`` (``knot.kind = "torus"`` or a torus knot's table name) or
        ``"knot type"`` (its type is a torus knot's).
    """

    knot_type: str | None
    source: str | None
    description: str
    torus: tuple | None
    torus_source: str | None = None

    @property
    def is_torus(self) -> bool:
        return self.torus is not None


def torus_link(data, chains) -> tuple[int, int] | None:
    """``(p, q)`` when the run's ``[knot]`` table is the torus link T(p, q) its rings are.

    ``kind = "torus"`` with ``gcd(p, q)`` equal to the number of chains (all closed), or a
    link name drawn as a torus link (``"hopf"``: T(2,2), ``"solomon"``: T(2,4)); None for any
    other system (``[[chains]]``, braid links, open components).
    """
    from knotmm.shapes.links import COMMON_LINKS

    if data.get("chains") or not all(closed for _, closed in chains) or len(chains) < 2:
        return None
    kind, p, q = data.get("knot.kind"), data.get("knot.p"), data.get("knot.q")
    if kind == "knotinfo":
        drawn = COMMON_LINKS.get(str(data.get("knot.name", "")).strip().lower())
        if drawn is None or drawn[0] != "torus":
            return None
        p, q = drawn[1]
    elif kind != "torus" or p is None or q is None:
        return None
    p, q = int(p), int(q)
    return (p, q) if math.gcd(p, q) == len(chains) else None


def run_knot(data, chains, initial: str | None = None) -> RunKnot:
    """Name a run's knot and decide whether the torus formulas apply (module docstring).

    Parameters
    ----------
    data : knotmm.io.run_data.RunData
    chains : list of (slice, bool)
        :func:`knotmm.analysis.shape.chains_of`.
    initial : str or None
        topoly's signed type of frame 0, if identified.

    Returns
    -------
    RunKnot
    """
    from knotmm.shapes.knotinfo import TORUS_NAMES, resolve_name

    torus_of_name = {name: pq for pq, name in TORUS_NAMES.items()}
    facts = data.get("knotmm", {}) or {}
    recorded = facts.get("template_knot_type") or facts.get("knot_type_start")
    if recorded:
        knot_type, source = str(recorded), RUN_FILE
    elif initial is not None:
        knot_type, source = initial, "topoly"
    else:
        knot_type, source = None, None
    kind = data.get("knot.kind")
    name = data.get("knot.name")
    by_type = torus_of_name.get(chirality.unsigned_knot_type(knot_type) or "")
    if len(chains) > 1:
        link = torus_link(data, chains)
        if link is not None:
            return RunKnot(knot_type, source, f"T({link[0]},{link[1]}) torus link", link,
                           "run file")
        what = f"{len(chains)}-chain system" if name is None else f"{len(chains)}-chain {name}"
        return RunKnot(knot_type, source, what, None)
    if not chains[0][1]:
        return RunKnot(knot_type, source, "open chain", None)
    if kind == "torus" or (kind is None and data.get("knot.p") is not None):
        p, q = data.get("knot.p"), data.get("knot.q")
        p, q = (int(p) if p is not None else None), (int(q) if q is not None else None)
        return RunKnot(knot_type, source, f"T({p},{q if q is not None else '?'})",
                       (p, q), "run file")
    if kind == "knotinfo" and name is not None:
        table = resolve_name(str(name))
        pq = torus_of_name.get(table)
        if pq is not None:
            return RunKnot(knot_type, source, f"T({pq[0]},{pq[1]}) = {table}", pq, "run file")
        return RunKnot(knot_type, source, table, None)
    if by_type is not None:
        p, q = by_type
        return RunKnot(knot_type, source, f"T({p},{q})", by_type, "knot type")
    if kind is None and knot_type is None:
        return RunKnot(None, None, "a torus knot (assumed)", (None, None), None)
    what = chirality.unsigned_knot_type(knot_type) if knot_type else f"knot.kind = {kind}"
    return RunKnot(knot_type, source, what or "unknown knot", None)
