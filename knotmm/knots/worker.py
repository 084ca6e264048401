"""Knot identification in a worker process of knotmm's own.

topoly must never run in a process that simulates, analyses or belongs to someone else (a
Dask worker, a notebook kernel): it closes file descriptor 0, prints from C, installs signal
handlers, and has crashed the interpreter on some inputs (segmentation faults on symmetric
projections, see :mod:`knotmm.knots.homfly`); its full import costs seconds
(the worker's light one, :mod:`knotmm.knots.topoly_import`, under half a second). So every knot
identification goes to one persistent worker process, started as its own module::

    python -P -m knotmm.knots.worker        (stdin: requests, stdout: replies)

It never imports the caller's ``__main__`` (unlike a multiprocessing "spawn" child), so a
script without an ``if __name__ == "__main__":`` guard is safe. The protocol is a pair of
pipes carrying pickled messages (:class:`multiprocessing.connection.Connection`):

* request ``(seq, positions, options)``: ``positions`` float64 (n_beads, 3), ``options`` the
  keyword arguments of :func:`knotmm.knots.homfly.identify_here`;
* reply ``(seq, name, messages)``: the knot name (or None when the worker could not
  compute it) and the warnings logged meanwhile (logged again here);
* a first reply ``(0, None, [])`` once topoly is imported: the worker is ready
  (:attr:`WorkerProcess.ready`), and a caller that must not wait for topoly's import (a run
  ending) can tell a queue of quick identifications from a worker still starting;
* end of file on the request pipe (the caller closed it, or died, even by SIGKILL): the
  worker exits.

The worker starts in the background (:meth:`WorkerProcess.start`: a fork and exec, well
under a millisecond here) and imports topoly at once, off the caller's path; requests queue
in the pipe meanwhile and are answered in order. If it dies, the identifications under way
report ``None`` (not checked), a warning is logged, and the next request starts a new
worker. The worker runs in a session of its own, at a lower priority (nice 10: the
simulation beside it comes first), and ignores SIGINT: Ctrl-C on a terminal goes to the
calling process, which decides how a run stops.
"""

from __future__ import annotations

import contextlib
import logging
import os
import subprocess
import sys
import threading
import time
from multiprocessing.connection import Connection
from pathlib import Path

import numpy as np

__all__ = ["IsolatedKnotIdentifier", "WorkerProcess", "main", "shared_worker"]

log = logging.getLogger(__name__)

#: Seconds to wait for one identification before giving up on it (and on the worker).
DEFAULT_TIMEOUT = 300.0


class WorkerProcess:
    """The client side of one worker process: send chains, collect names in order.

    Thread-safe. The process is started by :meth:`start` or by the first request, and
    started again after it died.
    """

    def __init__(self, timeout: float = DEFAULT_TIMEOUT):
        self.timeout = float(timeout)
        self._lock = threading.RLock()
        self._proc: subprocess.Popen | None = None
        self._send: Connection | None = None
        self._recv: Connection | None = None
        self._generation = 0  # bumped when a worker is given up: its requests give None
        self._seq = 0
        self._waiting: set[int] = set()
        self._results: dict[int, str | None] = {}
        self._ready = False  # the running worker has imported topoly
        self._users = 0  # identifiers sharing it (runs going on side by side in threads)
        self._pid = os.getpid()  # a forked child must not use (or kill) its parent's worker

    # -- process ----------------------------------------------------------------------------
    def _command(self) -> list[str]:
        flags = ["-P"] if sys.version_info >= (3, 11) else []  # no cwd on sys.path
        return [sys.executable, *flags, "-m", "knotmm.knots.worker"]

    def _environment(self) -> dict[str, str]:
        env = dict(os.environ)
        root = str(Path(__file__).resolve().parents[2])  # the directory that holds knotmm
        paths = [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p]
        env["PYTHONPATH"] = os.pathsep.join([root, *[p for p in paths if p != root]])
        return env

    @property
    def running(self) -> bool:
        return self._proc is not None and self._proc.poll() is None

    @property
    def ready(self) -> bool:
        """Whether the worker runs and has imported topoly (its answers then take
        milliseconds to seconds, not the seconds of its start-up). Never waits."""
        with self._lock:
            self._forget_if_forked()
            while not self._ready and self._recv is not None and self._recv.poll(0):
                self._read(0)
            return self._ready and self._recv is not None

    def _forget_if_forked(self) -> None:
        """In a child forked from the owner: drop the inherited pipes, leave the worker."""
        if os.getpid() != self._pid:
            for conn in (self._send, self._recv):
                if conn is not None:
                    conn.close()
            self._proc = self._send = self._recv = None
            self._waiting.clear()
            self._results.clear()
            self._generation += 1
            self._ready = False
            self._pid = os.getpid()

    def start(self) -> bool:
        """Start the worker in the background unless it runs; False if it cannot start."""
        with self._lock:
            self._forget_if_forked()
            if self._proc is not None:
                return True
            if not sys.executable:
                log.warning("knot identification needs a Python executable (sys.executable "
                            "is empty); knot types are not checked")
                return False
            try:
                proc = subprocess.Popen(
                    self._command(),
                    stdin=subprocess.PIPE,
                    stdout=subprocess.PIPE,
                    stderr=subprocess.DEVNULL,
                    env=self._environment(),
                    close_fds=True,
                    # terminal signals (Ctrl-C) go to the caller, which decides how to stop;
                    # the worker leaves when its request pipe closes
                    start_new_session=True,
                )
            except OSError as exc:
                log.warning("could not start the knot-identification worker (%s); knot "
                            "types are not checked", exc)
                return False
            self._send = Connection(os.dup(proc.stdin.fileno()), readable=False)
            self._recv = Connection(os.dup(proc.stdout.fileno()), writable=False)
            proc.stdin.close()
            proc.stdout.close()
            self._proc = proc
            return True

    def _give_up(self, why: str | None) -> None:
        """Drop the worker; the requests under way give None."""
        if why:
            log.warning("%s; the knot identifications under way are skipped", why)
        self._generation += 1
        self._ready = False
        self._waiting.clear()
        self._results.clear()
        for conn in (self._send, self._recv):
            if conn is not None:
                conn.close()
        self._send = self._recv = None
        proc, self._proc = self._proc, None
        if proc is not None:
            if proc.poll() is None:
                proc.kill()
            try:
                proc.wait(timeout=1.0)
            except subprocess.TimeoutExpired:  # pragma: no cover - a kill not yet effective
                pass

    def close(self) -> None:
        """Stop the worker at once (requests under way give None); restarted when needed.

        An idle worker leaves on the closed pipe by itself; a busy one is killed. Never
        waits for an identification.
        """
        with self._lock:
            self._forget_if_forked()
            if self._proc is None:
                return
            if self._waiting:
                self._give_up(None)
                return
            for conn in (self._send, self._recv):
                conn.close()
            self._send = self._recv = None
            proc, self._proc = self._proc, None
            self._generation += 1
            self._ready = False
            try:
                proc.wait(timeout=0.5)  # an idle worker exits on end of file within ms
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()

    def close_if_busy(self) -> None:
        """Stop the worker if identifications are under way (they give None), else keep it."""
        with self._lock:
            self._forget_if_forked()
            if self._waiting:
                self._give_up(None)

    def attach(self) -> None:
        """One more user shares the worker (:meth:`release` when it is done)."""
        with self._lock:
            self._users += 1

    def release(self) -> None:
        """A user is done: the last one stops the worker if it is busy
        (:meth:`close_if_busy`); while others use it (replicas of a set stepped together,
        each in a thread), their identifications under way go on."""
        with self._lock:
            self._users = max(0, self._users - 1)
            if self._users == 0:
                self.close_if_busy()

    # -- requests ---------------------------------------------------------------------------
    def submit(self, positions, timeout: float | None = None, **options) -> _Handle:
        """Send one chain; the returned handle's ``result()`` gives the name (or None).

        Parameters
        ----------
        positions : array_like, shape (n_beads, 3)
        timeout : float, optional
            Seconds ``result()`` waits before giving up (default: :attr:`timeout`).
        **options
            ``chiral``, ``max_cross``, ``minimal`` of
            :func:`knotmm.knots.identify.identify_knot`.
        """
        x = np.ascontiguousarray(positions, dtype=np.float64)
        timeout = self.timeout if timeout is None else float(timeout)
        with self._lock:
            if not self.start():
                return _Handle(self, -1, -1, timeout)
            self._seq += 1
            seq = self._seq
            try:
                self._send.send((seq, x, options))
            except OSError:
                self._give_up("the knot-identification worker is gone")
                return _Handle(self, -1, -1, timeout)
            self._waiting.add(seq)
            return _Handle(self, self._generation, seq, timeout)

    def identify(self, positions, **options) -> str | None:
        """Identify one chain and wait for the name (``None``: not identified)."""
        return self.submit(positions, **options).result()

    def _read(self, timeout: float) -> bool:
        """Read one reply if one arrives within ``timeout`` s; False on timeout."""
        try:
            if not self._recv.poll(timeout):
                return False
            seq, name, messages = self._recv.recv()
        except (EOFError, OSError):
            code = self._proc.poll() if self._proc is not None else None
            self._give_up(f"the knot-identification worker stopped (exit code {code})")
            return True
        self._ready = True  # any reply, the first being the worker's "ready"
        for message in messages:
            log.warning("%s", message)
        if seq in self._waiting:
            self._waiting.discard(seq)
            self._results[seq] = name
        return True

    def _done(self, generation: int, seq: int) -> bool:
        with self._lock:
            if generation != self._generation or seq not in self._waiting:
                return True
            while self._recv is not None and self._recv.poll(0):
                self._read(0)
                if generation != self._generation or seq not in self._waiting:
                    return True
            return False

    def _result(self, generation: int, seq: int, timeout: float) -> str | None:
        with self._lock:
            deadline = time.monotonic() + timeout
            while generation == self._generation and seq in self._waiting:
                left = deadline - time.monotonic()
                if left <= 0 or not self._read(left):
                    self._give_up(f"knot identification took over {timeout:g} s")
                    return None
            if generation != self._generation:
                return None
            return self._results.pop(seq, None)


class _Handle:
    """A request under way: ``done()`` (no waiting) and ``result()`` (waits)."""

    def __init__(self, worker: WorkerProcess, generation: int, seq: int, timeout: float):
        self._worker = worker
        self._generation = generation
        self._seq = seq
        self._timeout = timeout
        self._value: str | None = None
        self._finished = seq < 0

    def done(self) -> bool:
        return self._finished or self._worker._done(self._generation, self._seq)

    def result(self) -> str | None:
        if not self._finished:
            self._value = self._worker._result(self._generation, self._seq, self._timeout)
            self._finished = True
        return self._value


_SHARED: WorkerProcess | None = None
_SHARED_LOCK = threading.Lock()


def shared_worker() -> WorkerProcess:
    """The worker process that :func:`knotmm.knots.identify.identify_knot` uses (one per
    process, started at the first request, stopped at exit)."""
    global _SHARED
    with _SHARED_LOCK:
        if _SHARED is None:
            import atexit

            _SHARED = WorkerProcess()
            atexit.register(_SHARED.close)
        return _SHARED


class IsolatedKnotIdentifier:
    """Callable ``(positions) -> knot name or None``, evaluated in a worker process.

    Parameters
    ----------
    chiral : bool
        Name chiral knots with their handedness (``"+3_1"``).
    timeout : float
        Seconds to wait for one identification before giving up on it.
    own_process : bool
        False (default): use the process's shared worker (:func:`shared_worker`, the one
        the template checks used, so a run starts topoly once); true: a worker of its own.
    """

    def __init__(
        self, chiral: bool = True, timeout: float = DEFAULT_TIMEOUT, own_process: bool = False
    ):
        self.chiral = chiral
        self.own_process = own_process
        self.timeout = float(timeout)
        self._worker = WorkerProcess(timeout) if own_process else shared_worker()
        self._attached = not own_process
        if self._attached:
            self._worker.attach()

    def start(self) -> None:
        """Start the worker now (in the background), so that the first check is quick."""
        self._worker.start()

    @property
    def ready(self) -> bool:
        """Whether the worker has imported topoly (:attr:`WorkerProcess.ready`)."""
        return self._worker.ready

    def __call__(self, positions) -> str | None:
        return self.submit(positions).result()

    def submit(self, positions):
        """Start an identification and return a handle whose ``result()`` gives the name.

        The worker runs beside the caller (on another core), so a run does not wait for
        topoly.
        """
        return self._worker.submit(positions, timeout=self.timeout, chiral=self.chiral)

    def close(self) -> None:
        """Let go of the worker; never waits on it.

        A worker of its own is stopped; the shared one is stopped only if it is busy (a
        run being stopped must not wait for checks it will not judge) and no other
        identifier uses it (:meth:`WorkerProcess.release`), and is otherwise left for the
        next caller (it stops when the process ends).
        """
        if self.own_process:
            self._worker.close()
        elif self._attached:
            self._attached = False
            self._worker.release()

    def __del__(self):  # pragma: no cover - best effort at interpreter exit
        try:
            if self.own_process:
                self._worker.close()
            elif self._attached:  # one never closed still lets the shared worker go
                self._attached = False
                self._worker.release()
        except Exception:  # noqa: BLE001
            pass


# -- the worker process ----------------------------------------------------------------------
class _Collect(logging.Handler):
    def __init__(self):
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record):
        self.messages.append(record.getMessage())


def main() -> int:
    """Serve identifications on stdin/stdout until end of file (run as ``-m``)."""
    import gc
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    # a background helper: the simulation it checks comes first for the CPU
    with contextlib.suppress(OSError, AttributeError):
        os.nice(10)
    # the protocol moves off descriptors 0 and 1, which topoly closes and prints to
    requests = Connection(os.dup(0), writable=False)
    replies = Connection(os.dup(1), readable=False)
    null = os.open(os.devnull, os.O_RDWR)
    os.dup2(null, 0)
    os.dup2(null, 1)
    os.close(null)
    sys.stdin = open(os.devnull)  # noqa: SIM115 - for the life of the process
    sys.stdout = open(os.devnull, "w")  # noqa: SIM115

    from knotmm.knots import homfly

    collect = _Collect()
    logging.getLogger("knotmm").addHandler(collect)
    logging.getLogger("knotmm").setLevel(logging.WARNING)
    homfly.preload()
    # topoly runs a full garbage collection in every call: over the ~10^5 objects of its
    # import that took 90 % of an identification (120 of 130 ms for a 90-bead trefoil).
    # Freezing them moves them out of the collector's sight: 8 ms.
    gc.freeze()
    try:
        replies.send((0, None, []))  # ready: topoly is imported
    except OSError:
        return 0
    while True:
        try:
            seq, positions, options = requests.recv()
        except (EOFError, OSError):
            return 0
        collect.messages = []
        try:
            name = homfly.identify_here(positions, **options)
        except Exception as exc:  # noqa: BLE001 - reported to the caller, never fatal here
            name = None
            collect.messages.append(f"knot identification failed: {type(exc).__name__}: {exc}")
        try:
            replies.send((seq, name, collect.messages))
        except OSError:
            return 0


if __name__ == "__main__":
    sys.exit(main())
