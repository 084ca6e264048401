"""Handedness, rotation sense and knot type along a trajectory.

* Handedness is the sign of the writhe (``"right"``: positive), averaged over frames of
  the window, in the words of :mod:`knotmm.knots.chirality`. Writhe comes from
  :func:`knotmm.knots.writhe.writhe`.
* Rotation sense is read from the signed rotation frequency about the vertical axis
  through the centre of mass, as seen from above with gravity pointing down (towards the
  viewer's back): a positive frequency (alpha increasing, x towards y) is
  ``"counterclockwise"``.
* Knot type uses :func:`knotmm.knots.identify.identify_knot` (topoly, in knotmm's worker
  process), signed with its handedness (``"+3_1"``, ``"-5_1"``). The first change is found
  by sampling the trajectory evenly and bisecting between the last sample with the
  initial type and the first without it; a change that reverts between two samples can be
  missed.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from knotmm.knots import chirality
from knotmm.knots.identify import identify_knot
from knotmm.knots.writhe import writhe as _writhe

__all__ = [
    "KnotTypes",
    "handedness",
    "identify_signed",
    "rotation_sense",
    "mean_writhe",
    "knot_types",
]

logger = logging.getLogger(__name__)

#: |writhe| below this is too small to call a handedness.
WRITHE_THRESHOLD = 0.1


def mean_writhe(positions: np.ndarray, max_frames: int = 20) -> tuple[float, float]:
    """Writhe averaged over up to ``max_frames`` evenly spaced frames.

    Parameters
    ----------
    positions : ndarray, shape (n_frames, n_beads, 3)
        Bead positions (any length unit); bead order is chain order, closed.
    max_frames : int
        Frames sampled.

    Returns
    -------
    mean, std : float
        Mean and standard deviation of the writhe over the sampled frames.
    """
    x = np.asarray(positions)
    idx = np.unique(np.linspace(0, len(x) - 1, min(max_frames, len(x))).round().astype(int))
    values = np.atleast_1d(_writhe(x[idx]))
    return float(values.mean()), float(values.std())


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
    changed = None
    previous = 0
    for i in grid:
        if kind(int(i)) != initial:
            lo, hi = previous, int(i)
            while hi - lo > 1:
                mid = (lo + hi) // 2
                if kind(mid) == initial:
                    lo = mid
                else:
                    hi = mid
            changed = hi
            break
        previous = int(i)
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
    )
