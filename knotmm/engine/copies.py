"""Replicas stepped together: K runs' states as K copies of one system in one OpenMM Context.

A replicated run (:mod:`knotmm.replicas`) runs each replica as a complete run of its own
(:func:`knotmm.workflow.run`: its directory, reporters, knot checks, checkpoints and faults),
each in a thread of this process. With a :class:`CopyGroup` the replicas' plugin engines do
not step alone: each stretch up to a report time is handed to the group, and once every
replica still running waits for one, the group steps all of them together with one
:class:`knotmm.plugin.RPYIntegrator` bound to a Context that holds K copies of the system
(``RPYIntegrator.setNumCopies``): one force evaluation for all copies, each copy with its own
step control, time and noise stream, a copy that reached its report time waiting while the
others go on. The state each replica hands over, and takes back, is its own Context's:
positions, time, and the integrator's state (``getIntegratorState``: step size, cached
velocity, step-control memory, noise stream, counters). So everything else a run does reads
and writes the replica's own Context as if it had taken the steps itself, its checkpoints are
those of a single run (``knotmm run --resume DIR/replica_k`` continues one replica alone), and
a set that was killed resumes from its replicas' checkpoints.

Where a copy fails (a fault of its step, non-finite positions, a bond beyond
``run.max_bond_length``), its replica takes that stretch again alone from its start, with the
single engine's checks (:meth:`knotmm.engine.plugin_engine.PluginEngine.advance_to`): the fault
is then found and reported as in a single run, and the others go on. A stop asked for by a
signal ends every replica's stretch at a whole step, and each replica writes its checkpoint.

The copies live on any platform the plugin has a kernel on: on the Reference and CPU
platforms the copies are evaluated on the host, on OpenCL and CUDA on the device
(``plugin/platforms/common``, ``CommonRPYBatch``).

The copies share one place: each is evaluated at its own centre of mass, as a run alone is,
and the System's steric term acts within each copy only
(:func:`knotmm.model.system.copies_system`: one interaction group per copy). So a copy's
forces are those of the copy alone whatever the others do, bit for bit, and a set that was
stopped resumes to the trajectories of the set never stopped. They agree with single runs to
rounding, not bit for bit, on the host: the grouped steric term (a ``CustomNonbondedForce``)
rounds otherwise than a single run's ``NonbondedForce``; on a device in double precision they
write the same trajectory file (its forces are summed in fixed point, in any order)
(``tests/plugin/test_copies.py``, ``tests/workflow/test_replica_runs.py``).
"""

from __future__ import annotations

import contextlib
import logging
import threading

import numpy as np

from knotmm.engine.affinity import usable_cores
from knotmm.engine.interrupt import (
    StopRequested,
    request_stop,
    stop_requested,
    stop_signal,
    take_stop_request,
)

__all__ = ["COPY_PLATFORMS", "HOST_PLATFORMS", "MAX_TOGETHER", "TOGETHER_MAX_BEADS",
           "TOGETHER_MAX_BEADS_AT_ONCE", "CopyGroup",
           "copies_refusal", "enter_group", "leave_group", "replicas_at_once", "run_side_by_side",
           "run_together", "OneAfterAnother"]

log = logging.getLogger(__name__)

#: Platforms where the plugin holds copies of a system in one Context.
COPY_PLATFORMS = ("Reference", "CPU", "OpenCL", "CUDA")
#: Those of them where the copies are evaluated on the host (``TOGETHER_MAX_BEADS`` applies).
HOST_PLATFORMS = ("Reference", "CPU")


#: Largest replica (in beads) stepped together by default on a host platform, Brownian and
#: deterministic: above, the copies' interleaved work (Cholesky factors and mobility matrices
#: of 8 copies in turn, the grouped steric term's pairs) costs more than one OpenMM call per
#: copy saves (``benchmarks/README.md``, ``replicas``; 8 replicas, 10 tau_d at Pe = 2: 0.80x,
#: 0.87x, 1.08x, 1.20x the wall time of one after another at N = 40, 60, 90, 120; 40 tau_d
#: at Pe = inf: 0.94x, 0.99x, 1.53x at N = 90, 120, 240). On a device platform the copies'
#: launches replace as many force calls, and together is the default at every size.
TOGETHER_MAX_BEADS = {"brownian": 79, "deterministic": 120}
#: The same where several replicas (or groups of copies) step at once (``run.replicas_at_once``
#: > 1): 8 replicas on 2 cores, Brownian together 0.79-0.83x, 0.85-1.12x, 1.07x, 1.3x the
#: wall time of one after another at N = 40, 60, 90, 120; deterministic 1.16-1.2x, 1.1-1.17x,
#: 1.32x, 1.35-1.6x (2026-12-06 night, ``benchmarks/README.md``).
TOGETHER_MAX_BEADS_AT_ONCE = {"brownian": 79, "deterministic": 0}


#: Most runs stepped together in one Context: a larger set runs in groups of at most this
#: many, as equal as can be, one group after another (each run holds a thread, a Context of
#: its own and its open files while its group runs).
MAX_TOGETHER = 64


def copies_refusal(engine: str, platform: str, count: int, stepping: str = "auto",
                   n_beads: int = 0, brownian: bool = False, at_once: int = 1) -> str | None:
    """Why ``count`` replicas are not stepped as copies of one Context, or None if they are.

    Parameters
    ----------
    engine : str
        The replicas' engine (``"plugin"`` or ``"python"``).
    platform : str
        Their OpenMM platform's name.
    count : int
    stepping : str
        ``run.replica_stepping``: ``"auto"``, ``"together"`` or ``"one_after_another"``.
    n_beads : int
        Beads of one replica.
    brownian : bool
        Finite ``run.peclet``.
    at_once : int
        Replicas (or groups) stepping at the same time (:func:`replicas_at_once`).
    """
    if count < 2:
        return "a single run"
    if stepping == "one_after_another":
        return ('run.replica_stepping = "one_after_another" (each equals its single run bit '
                'for bit)')
    if engine != "plugin":
        return "the Python engine steps one system at a time"
    if platform not in COPY_PLATFORMS:
        return (f"the plugin holds copies on the {' and '.join(COPY_PLATFORMS)} platforms, "
                f"not on {platform}")
    kind = "brownian" if brownian else "deterministic"
    largest = (TOGETHER_MAX_BEADS if at_once < 2 else TOGETHER_MAX_BEADS_AT_ONCE)[kind]
    # on a device platform (OpenCL, CUDA) together is the faster way at every size measured
    if stepping == "auto" and platform in HOST_PLATFORMS and n_beads > largest:
        several = f", {at_once} at once," if at_once > 1 else ""
        return (f"measured faster one after another{several} for {kind} replicas of more "
                f"than {largest} beads (benchmarks/README.md, replicas); "
                f'run.replica_stepping = "together" steps them together')
    return None


def replicas_at_once(requested: int, count: int, engine: str, platform: str,
                     threads: int) -> tuple[int, str]:
    """How many of a set's ``count`` replicas (or groups of copies) step at the same time,
    each in a thread, and why.

    Parameters
    ----------
    requested : int
        ``run.replicas_at_once``: 0 for the automatic choice.
    count : int
        Replicas to run.
    engine, platform : str
        The replicas' engine and OpenMM platform.
    threads : int
        Threads one replica uses (``run.threads`` x ``run.mobility_threads``).

    Returns
    -------
    (int, str)
        At least 1, at most ``count``; the reason, for ``replicas.toml``.
    """
    count = max(1, int(count))
    if requested >= 1:
        return min(int(requested), count), f"run.replicas_at_once = {int(requested)}"
    if engine != "plugin":
        return 1, "the Python engine holds Python's interpreter lock while it steps"
    if platform not in HOST_PLATFORMS:
        return 1, f"the {platform} device steps the whole set"
    cores, threads = usable_cores(), max(1, int(threads))
    at_once = max(1, min(count, cores // threads))
    return at_once, (f"auto: {cores} CPU cores for this process, {threads} thread"
                     f"{'s' if threads > 1 else ''} a replica")


@contextlib.contextmanager
def _blas_on_one_thread():
    """BLAS on one thread for the whole set: each run limits it while it steps and puts the
    former limit back when it ends, which, with runs ending at their own times, would let
    the others factorise with more threads (and round otherwise) from then on. The limit
    holds only for the libraries loaded now, and only this (the main) thread may change it
    (threadpoolctl: the runs' own limits, in their threads, do nothing): LAPACK's library,
    which a Brownian run loads with its integrator, is loaded first. Loaded later, it
    factorised on every core in a resumed set (1.6x slower on idle cores, 4x beside other
    work, and rounding otherwise than the uninterrupted set, whose process happened to
    have loaded it before)."""
    from threadpoolctl import threadpool_limits

    import knotmm.plugin as kp

    if kp._cython_lapack() is None:  # no plugin: scipy's package import loads the library
        import scipy.linalg  # noqa: F401
    with threadpool_limits(limits=1, user_api="blas"):
        yield


def _failed(k: int, exc: BaseException, failures: dict) -> None:
    """Record run ``k``'s failure; an interruption of one run stops the others at their
    next step (each run takes the request as it stops, so it is asked for again)."""
    failures[k] = exc
    if isinstance(exc, KeyboardInterrupt):
        request_stop()


def run_together(count: int, body, max_together: int | None = None,
                 at_once: int = 1) -> dict[int, BaseException]:
    """Run ``body(k, (group, copy))`` for ``k`` in ``range(count)``, each in a thread of its
    own, the runs stepped as the copies of a :class:`CopyGroup`: groups of at most
    ``max_together`` (default :data:`MAX_TOGETHER`) runs each, at least ``at_once`` groups
    where each can have two runs, of sizes that differ by one at most, ``at_once`` groups
    stepping at the same time (each by a thread of its own: the plugin steps without
    Python's interpreter lock), then the next ones. A run that ends, however it ends, leaves
    its group. A stop asked for by a signal (or a :class:`StopRequested` of one run) stops
    every run at a whole step, and no later group starts.

    Returns
    -------
    dict
        ``{k: exception}`` for each run whose ``body`` raised (the others' return values are
        the caller's to keep); key -1: an interruption of the waiting thread, waited out.
    """
    limit = int(max_together or MAX_TOGETHER)
    at_once = max(1, min(int(at_once), count))
    failures: dict[int, BaseException] = {}

    def one(k, group, copy, ended):
        try:
            body(k, (group, copy))
        except BaseException as exc:  # noqa: BLE001 - handed back to the caller's thread
            _failed(k, exc, failures)
        finally:
            group.leave(copy)
            ended.release()

    with _blas_on_one_thread():
        groups = max(-(-count // limit), min(at_once, count // 2))  # two copies a group at least
        bounds = [count * g // groups for g in range(groups + 1)]
        for first in range(0, groups, at_once):
            ended = threading.Semaphore(0)
            threads = []
            for g in range(first, min(first + at_once, groups)):
                group = CopyGroup(bounds[g + 1] - bounds[g])
                threads += [threading.Thread(target=one, args=(k, group, k - bounds[g], ended),
                                             daemon=True, name=f"knotmm-copy-{k}")
                            for k in range(bounds[g], bounds[g + 1])]
            for t in threads:
                t.start()
            _wait(threads, ended, failures)
            take_stop_request()  # asked for by a run for the others; all have stopped
            if failures:
                break
    return failures


def run_side_by_side(count: int, body, at_once: int) -> dict[int, BaseException]:
    """Run ``body(k, lane)`` for ``k`` in ``range(count)``, each a run of its own (its own
    Context), at most ``at_once`` at the same time, each in a thread (the plugin steps
    without Python's interpreter lock), in the order of ``k``; ``lane`` (0 ... ``at_once`` -
    1) is the thread's, whose runs follow one another (lane 0's may show progress). After a
    failure, or a stop asked for by a signal (which stops the runs under way at a whole
    step), no further run starts.

    Returns
    -------
    dict
        As :func:`run_together`'s.
    """
    failures: dict[int, BaseException] = {}
    taking = threading.Lock()
    order = iter(range(count))

    def worker(lane, ended):
        try:
            while True:
                with taking:
                    k = None if failures or stop_requested() else next(order, None)
                if k is None:
                    return
                try:
                    body(k, lane)
                except BaseException as exc:  # noqa: BLE001 - handed back to the caller
                    _failed(k, exc, failures)
        finally:
            ended.release()

    with _blas_on_one_thread():
        ended = threading.Semaphore(0)
        threads = [threading.Thread(target=worker, args=(i, ended), daemon=True,
                                    name=f"knotmm-replicas-{i}")
                   for i in range(max(1, min(int(at_once), count)))]
        for t in threads:
            t.start()
        _wait(threads, ended, failures)
        take_stop_request()
    return failures


def _wait(threads, ended: threading.Semaphore, failures: dict) -> None:
    """Wait for the threads (each releases ``ended`` once), the main thread free to take
    signals: a first interruption raised here asks every run to stop at its next whole step
    (they then write their checkpoints) and is waited out; a second one is raised at once.

    Never ``Thread.join`` with a timeout here: an exception raised by a signal handler inside
    it can leave a running thread marked as ended (CPython 3.11's ``_wait_for_tstate_lock``
    releases the thread's own lock), and the runs would be cut off mid-step."""
    interrupted = None
    left = len(threads)
    while left:
        try:
            if ended.acquire(timeout=0.2):
                left -= 1
        except KeyboardInterrupt as exc:
            if interrupted is not None:
                raise
            interrupted = exc
            request_stop()
    for t in threads:  # each has ended its work; only its exit is left
        t.join()
    if interrupted is not None:
        failures.setdefault(-1, interrupted)


class OneAfterAnother:
    """A replica of a set that is not stepped together, with the reason
    (:func:`copies_refusal`): what its run.toml's ``replica_stepping`` says."""

    def __init__(self, reason: str):
        self.reason = reason


def enter_group(copies, sim, facts: dict) -> None:
    """A run as replica ``k`` of ``copies = (group, k)`` (None: a run alone; a
    :class:`OneAfterAnother`: a replica run on its own): it joins the group, and ``facts``
    (its run.toml's) record how it is stepped."""
    if isinstance(copies, OneAfterAnother):
        facts["replica_stepping"] = f"one after another: {copies.reason}"
    elif copies is not None:
        group, k = copies
        facts["replica_stepping"] = (f"together: copy {k} of {group.count} in one Context"
                                     if group.join(k, sim, facts) else "alone")


def leave_group(copies) -> None:
    """The run of :func:`enter_group` ended (however it ended)."""
    if copies is not None and not isinstance(copies, OneAfterAnother):
        copies[0].leave(copies[1])


class _Stretch:
    """What a replica hands to the group: where it is, where it must get to."""

    def __init__(self, target, positions, time, state):
        self.target = float(target)
        self.positions = positions
        self.time = float(time)
        self.state = state
        self.outcome = None  # set by the round: (positions, time, state, fault) or "stop"


class CopyGroup:
    """K replicas of one run stepped as copies of one Context (module docstring).

    Parameters
    ----------
    count : int
        The replicas; replica k is copy k.
    chunk_seconds : float
        Wall-clock seconds of one ``stepCopiesTo`` call: how soon a signal, or a copy
        whose bonds grew too long, is seen.

    Attributes
    ----------
    rounds : int
        Rounds of stepping so far (each takes every waiting replica to its report time).
    """

    def __init__(self, count: int, chunk_seconds: float = 0.25):
        self.count = int(count)
        self.chunk_seconds = float(chunk_seconds)
        self.rounds = 0
        self._cond = threading.Condition()
        self._live = set(range(self.count))
        self._members: dict[int, object] = {}  # copy -> the replica's Simulation
        self._pending: dict[int, _Stretch] = {}
        self._stepping = False
        self._signature = None
        self._rpy = None
        self._context = None
        self._pin = None
        self._facts: dict[int, dict] = {}  # copy -> its run's run.toml facts
        self._broken: str | None = None  # why the copies can no longer be stepped

    # -- membership ---------------------------------------------------------------------
    def join(self, k: int, sim, facts: dict | None = None) -> bool:
        """Step replica ``k``'s Simulation with the group from now on; False (and replica
        ``k`` steps alone) where it cannot be a copy of the others. ``facts`` (its run.toml's)
        are told if the group breaks down later."""
        from knotmm.engine.plugin_engine import PluginEngine

        engine = sim._engine
        signature = (type(engine).__name__, sim.platform_name, sim.n_beads,
                     sim.layout.to_record() if hasattr(sim.layout, "to_record") else None,
                     repr(sim.model), engine.integrator.name)
        with self._cond:
            refusal = (copies_refusal("plugin", sim.platform_name, self.count, "together")
                       if isinstance(engine, PluginEngine) else "its engine is not the plugin's")
            if refusal is None and self._signature not in (None, signature):
                refusal = "its system or integrator differs from the other replicas'"
            if refusal is None and self._rpy is not None:
                refusal = "the copies were built before it joined"
            if refusal is None:
                refusal = self._broken
            if refusal is not None:
                log.info("replica %d steps alone: %s", k, refusal)
                self._leave(k)
                return False
            self._signature = signature
            self._members[k] = sim
            self._facts[k] = facts if facts is not None else {}
            engine.group = self
            engine.copy_index = k
            return True

    def leave(self, k: int) -> None:
        """Replica ``k`` takes no more steps with the group (it ended, or never joined)."""
        with self._cond:
            self._leave(k)

    def _leave(self, k: int) -> None:
        self._live.discard(k)
        sim = self._members.pop(k, None)
        self._facts.pop(k, None)
        if sim is not None:
            sim._engine.group = None
        self._cond.notify_all()

    # -- stepping -----------------------------------------------------------------------
    def advance(self, k: int, sim, target: float):
        """Hand replica ``k``'s stretch up to ``target`` (tau_d) to the group; wait for it.

        Returns
        -------
        tuple or None
            ``(positions, time, state)`` reached, or None where the copy failed (the replica
            then takes the stretch alone).

        Raises
        ------
        StopRequested
            A stop asked for by a signal ended the round; the replica holds a whole step.
        """
        rpy = sim._engine.rpy
        stretch = _Stretch(target, sim.positions.copy(), sim.time, rpy.getIntegratorState())
        with self._cond:
            self._pending[k] = stretch
            self._cond.notify_all()
            while stretch.outcome is None:
                if not self._stepping and self._pending and set(self._pending) >= self._live:
                    self._stepping = True
                    try:
                        self._round()
                    finally:
                        self._stepping = False
                        self._cond.notify_all()
                else:
                    self._cond.wait(0.5)
        if stretch.outcome == "stop":
            raise StopRequested(stop_signal())
        return stretch.outcome

    def _build(self) -> None:
        """The Context of K copies, from the first member (all members are alike)."""
        import openmm

        from knotmm.engine.affinity import CorePin
        from knotmm.model.layout import ChainLayout
        from knotmm.model.system import copies_system, site_positions
        from knotmm.plugin import from_python_integrator

        sim = self._members[min(self._members)]
        engine = sim._engine
        layout = ChainLayout(tuple(sim.layout.lengths) * self.count,
                             tuple(sim.layout.closed) * self.count)
        positions = np.vstack([sim.positions] * self.count)
        system = copies_system(sim.positions, sim.model, sim.layout, self.count)
        # the replicas' RPY threads (run.mobility_threads) share out the copies' mobility
        # products and noise factorisations (each copy's numbers whatever the threads)
        rpy = from_python_integrator(engine.integrator, threads=engine.rpy.getNumThreads(),
                                     n_beads=sim.n_beads)
        rpy.setNumCopies(self.count)
        rpy.setCopiesApart(False)  # each copy where it is alone; the System's groups part them
        platform = sim.context.getPlatform()
        properties = {name: platform.getPropertyValue(sim.context, name)
                      for name in platform.getPropertyNames()}
        self._pin = CorePin(sim.core_pin.enabled)  # as the replica's own: OpenMM's pool beside
        with self._pin.creating():
            self._context = openmm.Context(system, rpy, platform, properties)
        # OpenMM wants positions before it evaluates; the copies' own come with each round
        self._context.setPositions(site_positions(positions, sim.model, layout))
        self._rpy = rpy
        log.info("%d replicas step as copies of one Context (%s platform)", self.count,
                 platform.getName())

    def _round(self) -> None:
        """Take every waiting replica to its target (the caller holds the lock). Where the
        copies cannot be built or stepped at all (an OpenMM error, memory), every replica
        takes its stretch, and the rest of its run, alone."""
        try:
            self._step_round()
        except Exception as exc:  # noqa: BLE001 - each replica then runs alone, as a run
            self._broken = (f"the copies could not be stepped ({type(exc).__name__}: "
                            f"{' '.join(str(exc).split())})")
            log.warning("replicas %s step alone from here: %s",
                        ", ".join(map(str, sorted(self._pending))), self._broken)
            for k, stretch in list(self._pending.items()):
                stretch.outcome = (None, None, None)
                self._facts.get(k, {})["replica_stepping"] = f"alone: {self._broken}"
                sim = self._members.get(k)
                if sim is not None:
                    sim._engine.group = None
            self._pending.clear()

    def _step_round(self) -> None:
        if self._rpy is None:
            self._build()
        rpy = self._rpy
        pending = dict(self._pending)
        targets = []
        for k in range(self.count):
            stretch = pending.get(k)
            if stretch is None:
                targets.append(rpy.getCopyTime(k))  # an ended replica's copy stays put
                continue
            rpy.clearCopyFault(k)
            rpy.setCopyPositions(k, stretch.positions.ravel().tolist())
            rpy.setCopyTime(k, stretch.time)
            rpy.setCopyState(k, stretch.state)
            targets.append(stretch.target)
        stopped = False
        while True:
            with self._pin.stepping():
                reached = rpy.stepCopiesTo(targets, self.chunk_seconds)
            if reached:
                break
            for k in pending:  # a copy running away stops at once
                if rpy.getCopyFaultKind(k):
                    continue
                y = np.asarray(rpy.getCopyPositions(k)).reshape(-1, 3)
                if not self._members[k]._engine._fine(self._members[k], y):
                    targets[k] = rpy.getCopyTime(k)
            if take_stop_request():
                stopped = True
                break
        self.rounds += 1
        for k, stretch in pending.items():
            del self._pending[k]
            if stopped:
                stretch.outcome = "stop"
                continue
            if rpy.getCopyFaultKind(k) or abs(rpy.getCopyTime(k) - stretch.target) > 0.0:
                log.info("replica %d: its copy stopped at t = %g (%s); it takes the stretch "
                         "alone", k, rpy.getCopyTime(k),
                         rpy.getCopyFaultMessage(k) or "bonds beyond run.max_bond_length")
                stretch.outcome = (None, None, None)
                continue
            stretch.outcome = (np.asarray(rpy.getCopyPositions(k)).reshape(-1, 3),
                               rpy.getCopyTime(k), rpy.getCopyState(k))
