"""Keep OpenMM's CPU-platform worker thread on the core of the thread that asks for forces.

OpenMM's CPU platform hands every force kernel to its thread pool and waits for it, even with
one thread (``Threads = 1``): a force evaluation of knotmm's System makes four hand-offs, six
when the neighbour list is rebuilt, each a wake-up of the pool's thread and one of the caller.
When the two threads sit on different cores, each wake-up is a cross-core one, and on a
virtual machine whose other core is idle it costs tens of microseconds
(``benchmarks/README.md``, ``bench_forces.py layouts``). :class:`CorePin` puts the pool's
threads and the calling thread on one core for the span of a stretch of steps, so the
hand-offs become switches on one core. Only where threads run changes: results are the same
bit for bit. Linux only; elsewhere, or if the affinity calls fail, it does nothing; the
environment variable ``KNOTMM_NO_PIN=1`` turns it off (to compare).

Runs that step at the same time in threads of one process (a replica set's,
``run.replicas_at_once``) each take a core of their own: a stretch that starts while another
holds the core it is on moves to a core that no stretch holds, where there is one.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import threading

__all__ = ["CorePin", "usable_cores"]

try:
    _sched_getcpu = ctypes.CDLL(None, use_errno=True).sched_getcpu
except (OSError, AttributeError):
    _sched_getcpu = None


_held: dict[int, int] = {}  # core -> stretches pinned to it now
_holding = threading.Lock()
_creating = threading.Lock()  # one Context created at a time: its new threads are its own


def _take_core(allowed: set[int]) -> int:
    """The core this thread runs on, or, if a stretch holds it, one of ``allowed`` that none
    holds; counted as held until :func:`_give_core`."""
    with _holding:
        core = _sched_getcpu()
        if _held.get(core):
            core = next((c for c in sorted(allowed) if not _held.get(c)), core)
        _held[core] = _held.get(core, 0) + 1
        return core


def _give_core(core: int) -> None:
    with _holding:
        _held[core] -= 1


def usable_cores() -> int:
    """CPU cores this process may run on (its affinity where the system tells it)."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not on Linux
        return os.cpu_count() or 1


def _supported() -> bool:
    return (_sched_getcpu is not None and hasattr(os, "sched_setaffinity")
            and os.path.isdir("/proc/self/task"))


def _thread_ids() -> set[int]:
    return {int(t) for t in os.listdir("/proc/self/task")}


class CorePin:
    """The threads an OpenMM Context starts, and the caller, on one core while stepping.

    Parameters
    ----------
    enabled : bool
        Pin at all (knotmm: the CPU platform with one thread, and a one-thread RPY loop; a
        pool of several threads, or the plugin's own pair-loop threads, must not share a core).
    """

    def __init__(self, enabled: bool = True):
        self.enabled = (bool(enabled) and _supported()
                        and os.environ.get("KNOTMM_NO_PIN", "") != "1")
        self.pool: set[int] = set()

    @contextlib.contextmanager
    def creating(self):
        """Around ``openmm.Context(...)``: remember the threads it starts (OpenMM's pool).

        One Context at a time in the process is created inside this block, so that threads
        that start meanwhile are this Context's and not another's being created beside it
        (replicas that start at the same time in threads of one process)."""
        if not self.enabled:
            yield
            return
        with _creating:
            before = _thread_ids()
            yield
            self.pool = _thread_ids() - before

    @contextlib.contextmanager
    def stepping(self):
        """The calling thread and the pool on the core the caller runs on now; afterwards the
        caller gets its own affinity back (processes it starts later are not pinned)."""
        if not (self.enabled and self.pool):
            yield
            return
        try:
            saved = os.sched_getaffinity(0)
        except OSError:
            yield
            return
        taken = _take_core(saved)
        try:
            core = {taken}
            os.sched_setaffinity(0, core)
        except OSError:
            _give_core(taken)
            yield
            return
        try:
            for tid in self.pool:
                try:
                    os.sched_setaffinity(tid, core)
                except OSError:  # the thread has gone (Context deleted)
                    pass
            yield
        finally:
            os.sched_setaffinity(0, saved)
            _give_core(taken)
