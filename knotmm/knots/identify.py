"""Knot type of a closed chain, named by topoly in knotmm's own worker process.

:func:`identify_knot` is the one entry point for knot identification (template checks,
run-time checks, analysis): it checks the chain here and sends it to the worker process of
:mod:`knotmm.knots.worker`, where :func:`knotmm.knots.homfly.identify_here` calls topoly's
HOMFLY-PT polynomial. This process never imports topoly (topoly is an optional extra, free
for non-commercial use); without it :func:`identify_knot` returns ``None``. Names follow
:mod:`knotmm.knots.chirality`.
"""

from __future__ import annotations

import importlib.util

from knotmm.knots.chirality import UNKNOWN
from knotmm.knots.writhe import as_chain

__all__ = [
    "UNKNOWN",
    "identify_knot",
    "identify_link",
    "start_worker",
    "submit_identification",
    "topoly_available",
    "worker_ready",
]


def topoly_available() -> bool:
    """Whether topoly (the optional knot-identification extra) is installed (not imported)."""
    return importlib.util.find_spec("topoly") is not None


def start_worker() -> bool:
    """Start the identification worker in the background, if topoly is installed.

    Its start-up (a Python interpreter importing topoly: seconds) then overlaps whatever
    the caller does next (a run builds its template and OpenMM system meanwhile), and the
    first :func:`identify_knot` does not wait for all of it. Returns whether one runs.
    """
    if not topoly_available():
        return False
    from knotmm.knots.worker import shared_worker

    return shared_worker().start()


def worker_ready() -> bool:
    """Whether the identification worker runs and has imported topoly (never waits).

    Until then an identification waits for topoly's import (seconds); a caller that must
    not wait (a run that is ending) judges only what is back.
    """
    if not topoly_available():
        return False
    from knotmm.knots.worker import shared_worker

    return shared_worker().ready


def submit_identification(
    positions, chiral: bool = False, max_cross: int = 60, minimal: bool = True
):
    """Start :func:`identify_knot` in the worker and return at once.

    Parameters are those of :func:`identify_knot`.

    Returns
    -------
    handle or None
        ``None`` without topoly; else a handle whose ``done()`` says (without waiting)
        whether the name is back and whose ``result()`` waits for it (the value
        :func:`identify_knot` returns).
    """
    x = as_chain(positions)
    if x.ndim != 2:
        raise ValueError(f"positions has shape {x.shape}: expected (n_beads, 3), one frame")
    if not topoly_available():
        return None
    from knotmm.knots.worker import shared_worker

    return shared_worker().submit(x, chiral=chiral, max_cross=max_cross, minimal=minimal)


def identify_knot(
    positions, chiral: bool = False, max_cross: int = 60, minimal: bool = True
) -> str | None:
    """Knot type of a closed chain, from topoly's HOMFLY-PT polynomial (in the worker).

    Parameters
    ----------
    positions : array_like, shape (n_beads, 3)
        Bead coordinates; the chain is closed from the last bead to the first.
    chiral : bool, optional
        If true, sign chiral knots with their handedness as topoly reports it (``'+3_1'``
        right-handed, ``'-3_1'`` left-handed; amphichiral knots have no sign).
    max_cross : int, optional
        Largest number of crossings, after topoly's KMT reduction, for which the polynomial
        is computed; more gives :data:`UNKNOWN`.
    minimal : bool, optional
        If true (default), of the knots sharing the polynomial keep those with the fewest
        crossings (``'5_1'``); if false, list them all (``'10_132|5_1'``): the HOMFLY-PT
        polynomial does not tell 5_1 from 10_132, nor some knots from their mirror images.

    Returns
    -------
    str or None
        A name from the knot tables, ``'0_1'`` (unknot), ``'3_1'``, ``'4_1'``, ``'5_2'``,
        ``'11a_367'`` (spelled as in KnotInfo), composites such as ``'3_1#3_1'``; several
        names joined by ``'|'`` where the polynomial does not tell them apart;
        :data:`UNKNOWN` (``'unknown'``) for a polynomial outside topoly's tables or a
        diagram with too many crossings; ``None`` if topoly is not installed or the worker
        process could not identify it (crashed, timed out, could not start; logged).

    Raises
    ------
    ValueError
        For a wrong shape, fewer than 3 beads or non-finite coordinates.
    """
    handle = submit_identification(positions, chiral, max_cross, minimal)
    return None if handle is None else handle.result()


def identify_link(rings, max_cross: int = 60) -> str | None:
    """topoly's name for the link of several closed chains, from its HOMFLY-PT polynomial.

    Parameters
    ----------
    rings : sequence of array_like, each shape (n_beads, 3)
        The closed chains (each closed from its last bead to its first).
    max_cross : int, optional
        As in :func:`identify_knot`.

    Returns
    -------
    str or None
        topoly's name as it gives it: a link table name (``'L2a1'``: the Hopf link,
        ``'L5a1'``: the Whitehead link, signed where chiral), or the split union of knots
        (``'0_1U0_1'``) when the polynomial is a split link's (which does not prove the
        chains apart: some non-split links share the unlink's polynomial);
        :data:`UNKNOWN` for too many crossings or a polynomial outside topoly's tables;
        ``None`` without topoly or when the worker could not answer.

    Raises
    ------
    ValueError
        For fewer than two chains, a chain of fewer than 3 beads, a wrong shape or
        non-finite coordinates.
    """
    chains = [as_chain(r) for r in rings]
    if len(chains) < 2 or any(c.ndim != 2 for c in chains):
        raise ValueError("identify_link needs two or more chains, each of shape (n_beads, 3)")
    if not topoly_available():
        return None
    import numpy as np

    from knotmm.knots.worker import shared_worker

    return shared_worker().submit(np.concatenate(chains), chiral=True, max_cross=max_cross,
                                  components=[len(c) for c in chains]).result()
