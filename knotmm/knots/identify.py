"""Knot invariants of closed bead chains: writhe and knot type.

The chain is read as a closed polygon: bead ``i`` is joined to bead ``i + 1`` and the last
bead to the first.

* :func:`writhe` is the exact Gauss double integral of the polygon, computed segment pair by
  segment pair with the solid-angle formula of Klenin and Langowski (Biopolymers 54, 307,
  2000). Its sign is the handedness: the right-handed trefoil T(2,3) has writhe > 0.
* :func:`identify_knot` names the knot type with topoly's HOMFLY-PT polynomial (topoly is an
  optional extra, free for non-commercial use); it returns ``None`` when topoly is not
  installed.

Examples
--------
>>> import numpy as np
>>> t = np.linspace(0, 2 * np.pi, 60, endpoint=False)
>>> circle = np.c_[np.cos(t), np.sin(t), np.zeros_like(t)]
>>> round(writhe(circle), 12)
0.0
"""

from __future__ import annotations

import contextlib
import functools
import importlib.util
import logging
import os
import re
import sys

import numpy as np

try:
    import numba
except ImportError:  # pragma: no cover - numba is a dependency
    numba = None

__all__ = [
    "writhe",
    "identify_knot",
    "normalise_knot_name",
    "topoly_available",
    "quiet_output",
    "UNKNOWN",
]

logger = logging.getLogger(__name__)

#: What :func:`identify_knot` returns for a knot topoly cannot name (not in its tables, or
#: more crossings than ``max_cross`` after reduction).
UNKNOWN = "unknown"


def _generic_rotation() -> np.ndarray:
    """A fixed rotation by irrational-looking angles about three axes."""
    a, b, c = 0.4372, 1.0913, 2.3187
    rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    rx = np.array([[1, 0, 0], [0, np.cos(c), -np.sin(c)], [0, np.sin(c), np.cos(c)]])
    return rz @ ry @ rx


_GENERIC_ROTATION = _generic_rotation()

# Pairs of segments evaluated at once per chunk in writhe(); bounds the temporary memory
# (about 40 float64 arrays of this length).
_PAIR_CHUNK = 400_000


def _as_chain(positions, name: str = "positions") -> np.ndarray:
    x = np.asarray(positions, dtype=np.float64)
    if x.ndim not in (2, 3) or x.shape[-1] != 3:
        raise ValueError(
            f"{name} has shape {x.shape}: expected (n_beads, 3) or (n_frames, n_beads, 3)"
        )
    if x.shape[-2] < 3:
        raise ValueError(f"{name} has {x.shape[-2]} beads: a closed chain needs at least 3")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name} contains non-finite coordinates")
    return x


@functools.lru_cache(maxsize=32)
def _pair_indices(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Segment pairs (i < j) of a closed n-gon that share no vertex."""
    i, j = np.triu_indices(n, k=2)
    keep = ~((i == 0) & (j == n - 1))  # segment n-1 closes the ring onto segment 0
    return i[keep], j[keep]


def _unit(v: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        u = v / norm
    return np.where(norm > 0.0, u, 0.0)


def _pair_solid_angles(p1, p2, p3, p4) -> np.ndarray:
    """Signed solid angle (times 1/(4 pi): the Gauss-integral contribution) of segment pairs.

    Parameters
    ----------
    p1, p2 : ndarray, shape (m, 3)
        Start and end of the first segments.
    p3, p4 : ndarray, shape (m, 3)
        Start and end of the second segments.

    Returns
    -------
    ndarray, shape (m,)
        The contribution of each ordered pair to the writhe, ``Omega / (4 pi)``.
    """
    r13 = p3 - p1
    r14 = p4 - p1
    r23 = p3 - p2
    r24 = p4 - p2
    n1 = _unit(np.cross(r13, r14))
    n2 = _unit(np.cross(r14, r24))
    n3 = _unit(np.cross(r24, r23))
    n4 = _unit(np.cross(r23, r13))

    def _asin_dot(a, b):
        return np.arcsin(np.clip(np.einsum("...k,...k->...", a, b), -1.0, 1.0))

    omega = _asin_dot(n1, n2) + _asin_dot(n2, n3) + _asin_dot(n3, n4) + _asin_dot(n4, n1)
    sign = np.sign(np.einsum("...k,...k->...", np.cross(p4 - p3, p2 - p1), r13))
    return omega * sign / (4.0 * np.pi)


def _writhe_numpy(frames: np.ndarray) -> np.ndarray:
    """Reference kernel: ``frames`` (T, N, 3) -> writhe (T,), vectorised over pairs."""
    n = frames.shape[1]
    i, j = _pair_indices(n)
    out = np.zeros(frames.shape[0])
    if i.size == 0:
        return out
    nxt = np.roll(np.arange(n), -1)
    per_chunk = max(1, _PAIR_CHUNK // i.size)
    for start in range(0, frames.shape[0], per_chunk):
        f = frames[start : start + per_chunk]
        a, b = f, f[:, nxt]
        contrib = _pair_solid_angles(a[:, i], b[:, i], a[:, j], b[:, j])
        out[start : start + per_chunk] = 2.0 * contrib.sum(axis=1)
    return out


if numba is not None:

    @numba.njit(cache=True, inline="always")
    def _unit_cross(ax, ay, az, bx, by, bz):
        cx = ay * bz - az * by
        cy = az * bx - ax * bz
        cz = ax * by - ay * bx
        norm = np.sqrt(cx * cx + cy * cy + cz * cz)
        if norm > 0.0:
            return cx / norm, cy / norm, cz / norm
        return 0.0, 0.0, 0.0

    @numba.njit(cache=True, inline="always")
    def _asin_dot(ax, ay, az, bx, by, bz):
        d = ax * bx + ay * by + az * bz
        if d > 1.0:
            d = 1.0
        elif d < -1.0:
            d = -1.0
        return np.arcsin(d)

    @numba.njit(cache=True)
    def _writhe_kernel(frames, out):
        n_frames, n = frames.shape[0], frames.shape[1]
        for f in range(n_frames):
            x = frames[f]
            total = 0.0
            for i in range(n):
                i1 = i + 1 if i + 1 < n else 0
                p1x, p1y, p1z = x[i, 0], x[i, 1], x[i, 2]
                p2x, p2y, p2z = x[i1, 0], x[i1, 1], x[i1, 2]
                # segments j > i + 1 that share no vertex with segment i
                j_end = n if i > 0 else n - 1
                for j in range(i + 2, j_end):
                    j1 = j + 1 if j + 1 < n else 0
                    p3x, p3y, p3z = x[j, 0], x[j, 1], x[j, 2]
                    p4x, p4y, p4z = x[j1, 0], x[j1, 1], x[j1, 2]
                    r13x, r13y, r13z = p3x - p1x, p3y - p1y, p3z - p1z
                    r14x, r14y, r14z = p4x - p1x, p4y - p1y, p4z - p1z
                    r23x, r23y, r23z = p3x - p2x, p3y - p2y, p3z - p2z
                    r24x, r24y, r24z = p4x - p2x, p4y - p2y, p4z - p2z
                    n1x, n1y, n1z = _unit_cross(r13x, r13y, r13z, r14x, r14y, r14z)
                    n2x, n2y, n2z = _unit_cross(r14x, r14y, r14z, r24x, r24y, r24z)
                    n3x, n3y, n3z = _unit_cross(r24x, r24y, r24z, r23x, r23y, r23z)
                    n4x, n4y, n4z = _unit_cross(r23x, r23y, r23z, r13x, r13y, r13z)
                    omega = (
                        _asin_dot(n1x, n1y, n1z, n2x, n2y, n2z)
                        + _asin_dot(n2x, n2y, n2z, n3x, n3y, n3z)
                        + _asin_dot(n3x, n3y, n3z, n4x, n4y, n4z)
                        + _asin_dot(n4x, n4y, n4z, n1x, n1y, n1z)
                    )
                    ax, ay, az = p4x - p3x, p4y - p3y, p4z - p3z
                    bx, by, bz = p2x - p1x, p2y - p1y, p2z - p1z
                    t = (
                        (ay * bz - az * by) * r13x
                        + (az * bx - ax * bz) * r13y
                        + (ax * by - ay * bx) * r13z
                    )
                    if t > 0.0:
                        total += omega
                    elif t < 0.0:
                        total -= omega
            out[f] = 2.0 * total / (4.0 * np.pi)


def _numba_kernel():
    """The compiled writhe kernel (cached on disk by numba), or None without numba."""
    return None if numba is None else _writhe_kernel


def writhe(positions) -> float | np.ndarray:
    """Writhe of a closed polygon (exact discrete Gauss integral).

    Every pair of segments that share no vertex contributes its signed solid angle
    (Klenin-Langowski formula); adjacent segments are coplanar and contribute nothing. The
    result is exact for the polygon, not an approximation of a smooth curve.

    Parameters
    ----------
    positions : array_like, shape (n_beads, 3) or (n_frames, n_beads, 3)
        Bead coordinates (any length unit); the chain is closed from the last bead to the
        first.

    Returns
    -------
    float or ndarray, shape (n_frames,)
        The writhe (dimensionless). Positive for a right-handed knot such as the
        unmirrored T(2,3) template.

    Raises
    ------
    ValueError
        For a wrong shape, fewer than 3 beads or non-finite coordinates.

    Notes
    -----
    Cost is O(n_beads^2) per frame; a 120-bead chain takes well under a millisecond per
    frame when frames are batched.
    """
    x = _as_chain(positions)
    single = x.ndim == 2
    # one compiled signature: C-contiguous, writeable float64 (copies read-only input)
    frames = np.require(x[None] if single else x, np.float64, ["C", "W"])
    kernel = _numba_kernel()
    if kernel is None:  # pragma: no cover - numba is a dependency
        out = _writhe_numpy(frames)
    else:
        out = np.zeros(frames.shape[0])
        kernel(frames, out)
    return float(out[0]) if single else out


def normalise_knot_name(name: str) -> str:
    """Spell a knot name as the KnotInfo tables do, keeping chirality signs.

    ``'11a367'`` (topoly) -> ``'11a_367'``; ``'5.2'`` -> ``'5_2'``; composites and lists of
    candidates are handled part by part (``'+3_1#-3_1'``, ``'10_132|5_1'``).

    Parameters
    ----------
    name : str

    Returns
    -------
    str
    """

    def one(part: str) -> str:
        m = re.fullmatch(r"([+-]?)(\d+)\s*[_.]\s*(\d+)", part.strip())
        if m:
            return f"{m.group(1)}{int(m.group(2))}_{int(m.group(3))}"
        m = re.fullmatch(r"([+-]?)(\d+)\s*([anAN])\s*_?\s*(\d+)", part.strip())
        if m:
            return f"{m.group(1)}{int(m.group(2))}{m.group(3).lower()}_{int(m.group(4))}"
        return part.strip()

    return "|".join("#".join(one(p) for p in alt.split("#")) for alt in name.split("|"))


def topoly_available() -> bool:
    """Whether topoly (the optional knot-identification extra) can be imported."""
    return importlib.util.find_spec("topoly") is not None


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


def identify_knot(
    positions, chiral: bool = False, max_cross: int = 60, minimal: bool = True
) -> str | None:
    """Knot type of a closed chain, from topoly's HOMFLY-PT polynomial.

    Parameters
    ----------
    positions : array_like, shape (n_beads, 3)
        Bead coordinates; the chain is closed from the last bead to the first.
    chiral : bool, optional
        If true, prefix chiral knots with their handedness as topoly reports it
        (``'+3_1'`` right-handed, ``'-3_1'`` left-handed; amphichiral knots have no sign).
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
        diagram with too many crossings; ``None`` if topoly is not installed.
    """
    x = _as_chain(positions)
    if x.ndim != 2:
        raise ValueError(f"positions has shape {x.shape}: expected (n_beads, 3), one frame")
    if not topoly_available():
        return None
    import topoly  # noqa: PLC0415 - optional extra, imported lazily
    from topoly.params import Closure  # noqa: PLC0415

    # topoly projects the chain along a fixed axis; knotmm's templates are symmetric, and a
    # projection along their symmetry axis can give coincident crossings, on which topoly
    # 1.2.1 crashes (segmentation fault). A fixed generic rotation avoids such projections.
    coords = ((x - x.mean(axis=0)) @ _GENERIC_ROTATION.T).tolist()
    with _topoly_guard():
        try:
            result = topoly.homfly(
                coords,
                closure=Closure.CLOSED,
                chiral=chiral,
                minimal=minimal,
                max_cross=max_cross,
                run_parallel=False,
                cuda=False,
            )
        except Exception as exc:  # topoly raises a variety of errors on odd input
            logger.warning("topoly could not identify the knot: %s", exc)
            return UNKNOWN
    if isinstance(result, dict):  # probabilistic closures; not expected for CLOSED
        result = max(result, key=result.get) if result else UNKNOWN
    name = str(result).strip()
    if name in ("TMC", "Unknown", "") or name.lower().startswith("unknown"):
        logger.debug("topoly returned %r: knot type unknown", name)
        return UNKNOWN
    return normalise_knot_name(name)
