"""topoly's HOMFLY-PT call and the guards around it; runs only in the knot worker process.

knotmm never imports topoly in a process that simulates, analyses or serves a cluster: topoly
closes file descriptor 0, prints from C, installs signal handlers and raises the recursion
limit, and its import costs seconds. :mod:`knotmm.knots.worker` runs :func:`identify_here` in
a process of its own; everything else calls :func:`knotmm.knots.identify.identify_knot`, which
sends the chain there (``docs/architecture.md``).

:func:`quiet_output` (descriptor-level silence) is also used around mdtraj's DCD plugin,
which prints from C.
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys

import numpy as np

from knotmm.knots.chirality import UNKNOWN, normalise_knot_name

__all__ = ["identify_here", "preload", "quiet_output"]

logger = logging.getLogger(__name__)


def _generic_rotation() -> np.ndarray:
    """A fixed rotation by irrational-looking angles about three axes."""
    a, b, c = 0.4372, 1.0913, 2.3187
    rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    rx = np.array([[1, 0, 0], [0, np.cos(c), -np.sin(c)], [0, np.sin(c), np.cos(c)]])
    return rz @ ry @ rx


_GENERIC_ROTATION = _generic_rotation()


def _fd_open(fd: int) -> bool:
    try:
        os.fstat(fd)
    except OSError:
        return False
    return True


@contextlib.contextmanager
def quiet_output():
    """Send stdout and stderr, Python's and C libraries', to the null device for a while.

    Used around topoly and mdtraj's DCD plugin, which print from C. Process-wide (file
    descriptors 1 and 2), so not for use while other threads must print.
    """
    sys.stdout.flush()
    sys.stderr.flush()
    devnull = os.open(os.devnull, os.O_WRONLY)
    saved = []
    try:
        for fd in (1, 2):
            if _fd_open(fd):
                saved.append((fd, os.dup(fd)))
                os.dup2(devnull, fd)
        with open(os.devnull, "w") as sink:
            with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
                yield
    finally:
        for fd, copy in saved:
            os.dup2(copy, fd)
            os.close(copy)
        os.close(devnull)


@contextlib.contextmanager
def _topoly_guard():
    """Run topoly quietly and undo its side effects on file descriptors.

    topoly prints from Python and from C, so stdout and stderr are sent to the null device
    at the descriptor level. Its HOMFLY routine also closes descriptor 0 (stdin) on every
    call (topoly 1.2.1); a later call would then close whatever file took descriptor 0. The
    guard keeps a copy of descriptor 0 and puts it back afterwards, and makes sure that
    descriptor 0 is occupied during the call so that no file of ours can land there.
    It also raises Python's recursion limit to 10000 for good; the caller's is put back.
    """
    import signal
    import sys
    import threading

    recursion_limit = sys.getrecursionlimit()

    stdin_copy = os.dup(0) if _fd_open(0) else None
    placeholder = None
    if stdin_copy is None:
        placeholder = os.open(os.devnull, os.O_RDONLY)  # lowest free descriptor: 0
    # topoly's C code installs its own handlers for termination signals, after which
    # Python's never run again (SIGTERM then neither stops nor cleans up): keep ours.
    handlers = {}
    if threading.current_thread() is threading.main_thread():
        for name in ("SIGTERM", "SIGINT", "SIGHUP"):
            sig = getattr(signal, name, None)
            if sig is not None:
                handlers[sig] = signal.getsignal(sig)
    try:
        with quiet_output():
            yield
    finally:
        sys.setrecursionlimit(recursion_limit)
        for sig, handler in handlers.items():
            if handler is not None:
                signal.signal(sig, handler)
        if stdin_copy is not None:
            os.dup2(stdin_copy, 0)
            os.close(stdin_copy)
        elif placeholder is not None and _fd_open(placeholder):
            os.close(placeholder)


def preload() -> bool:
    """Import topoly quietly (the worker does so at start, off any caller's path).

    Returns
    -------
    bool
        Whether topoly could be imported.
    """
    from knotmm.knots.topoly_import import import_topoly  # noqa: PLC0415 - worker only

    try:
        with _topoly_guard():
            import_topoly()
    except ImportError:
        return False
    return True


def _homfly(coords: list, options: dict):
    """topoly's HOMFLY-PT name for closed chains ``coords``; a call that reaches a module the
    light import stood in for is repeated with topoly imported in full."""
    from knotmm.knots.topoly_import import (  # noqa: PLC0415 - worker only
        StandInUsed,
        import_topoly,
        import_topoly_in_full,
    )

    def call(topoly):
        return topoly.homfly(coords, closure=topoly.params.Closure.CLOSED, run_parallel=False,
                             cuda=False, **options)

    try:
        return call(import_topoly())
    except StandInUsed as exc:
        logger.debug("%s; importing topoly in full", exc)
        return call(import_topoly_in_full())


def identify_here(
    positions, chiral: bool = False, max_cross: int = 60, minimal: bool = True,
    components: list[int] | None = None,
) -> str:
    """Knot type of one closed chain, computed in this process by topoly.

    Only for the worker process (:mod:`knotmm.knots.worker`); callers use
    :func:`knotmm.knots.identify.identify_knot`, whose parameters and return values these
    are (``positions``: float64, shape (n_beads, 3), already checked). With ``components``
    (bead counts, in order) the positions are that many closed chains, and the name is
    topoly's for the link (:func:`knotmm.knots.identify.identify_link`), as topoly gives it.
    """
    x = np.asarray(positions, dtype=np.float64)
    # topoly projects the chain along a fixed axis; knotmm's templates are symmetric, and a
    # projection along their symmetry axis can give coincident crossings, on which topoly
    # 1.2.1 crashes (segmentation fault). A fixed generic rotation avoids such projections.
    coords = ((x - x.mean(axis=0)) @ _GENERIC_ROTATION.T).tolist()
    if components:  # one arc per closed chain, each bead numbered (topoly's arcs)
        starts = np.cumsum([0, *components[:-1]])
        coords = [[[int(s + i + 1), *coords[s + i]] for i in range(n)]
                  for s, n in zip(starts, components, strict=True)]
    options = {"chiral": chiral, "minimal": minimal, "max_cross": max_cross}
    with _topoly_guard():
        try:
            result = _homfly(coords, options)
        except Exception as exc:  # topoly raises a variety of errors on odd input
            logger.warning("topoly could not identify the knot: %s", exc)
            return UNKNOWN
    if isinstance(result, dict):  # probabilistic closures; not expected for CLOSED
        result = max(result, key=result.get) if result else UNKNOWN
    name = str(result).strip()
    if name in ("TMC", "Unknown", "") or name.lower().startswith("unknown"):
        logger.debug("topoly returned %r: knot type unknown", name)
        return UNKNOWN
    return name if components else normalise_knot_name(name)
