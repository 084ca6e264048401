"""Output writers scheduled by simulated time.

Every reporter here is a :class:`knotmm.engine.schedule.TimeScheduled`: report ``k`` at
``k * interval`` tau_d, and :class:`knotmm.engine.simulation.Simulation` lands its steps
exactly on those times. OpenMM's own step-scheduled reporters (``describeNextReport``) can
be attached to the same simulation. The checkpoint reporter is in
:mod:`knotmm.engine.checkpoint`; the file formats are :mod:`knotmm.io`'s.

Every writer flushes after each report, so a killed run keeps every finished frame and row.
"""

from __future__ import annotations

import csv
import math

import numpy as np

from knotmm.engine.schedule import TimeScheduled
from knotmm.io.dcd import DCDWriter
from knotmm.io.observables import ENERGY_TERMS, OBSERVABLE_COLUMNS
from knotmm.progress import Progress

__all__ = [
    "DCDReporter",
    "KnotTypeWatch",
    "ObservablesReporter",
    "ProgressReporter",
    "OBSERVABLE_COLUMNS",
]


class _FileReporter(TimeScheduled):
    """A reporter appending to one file (``self._file``, ``self.path``), flushed per report."""

    def _written(self, write) -> None:
        """Call ``write()``, flush, and advance; an OSError (a full disk) names the file."""
        try:
            write()
            self._file.flush()
        except OSError as exc:
            exc.filename = exc.filename or self.path
            raise
        self.advance()

    def close(self) -> None:
        if not self._file.closed:
            self._file.close()


class DCDReporter(_FileReporter):
    """Write frames to a DCD file in Angstrom (1 d = 10 A), without a unit cell.

    Frame ``k`` is the state at ``t = k * interval``, written by
    :class:`knotmm.io.dcd.DCDWriter` (the one DCD writer: OpenMM's ``DCDFile`` header, or for
    resumed runs, ``append=True``, its check; frames byte for byte what
    ``DCDFile.writeModel`` writes). ``first_index``: frames already in the file.

    Parameters
    ----------
    path : str or Path
    interval : float
        Time between frames, in tau_d.
    topology : openmm.app.Topology
        Topology of the chain (no periodic box).
    append : bool
    first_index : int
        Index of the next frame to write.
    """

    def __init__(self, path, interval, topology, append=False, first_index=0):
        super().__init__(interval, first_index)
        if topology.getUnitCellDimensions() is not None:
            raise ValueError("topology: has a periodic box; DCDReporter writes frames without "
                             "a unit cell (knotmm's chains are not periodic)")
        self.path = str(path)
        self._file = open(self.path, "r+b" if append else "wb")
        if append:
            self._file.seek(0, 2)
        self._dcd = DCDWriter(self._file, topology, self.interval, append=append)

    def report(self, simulation, state) -> None:
        self._written(lambda: self._write_frame(simulation.positions))

    def _write_frame(self, positions) -> None:
        """Append one frame (positions in d, shape (n_beads, 3))."""
        self._dcd.write(positions)


class ObservablesReporter(_FileReporter):
    """Append a row of :data:`OBSERVABLE_COLUMNS` to a CSV file at every report time."""

    def __init__(self, path, interval, append=False, first_index=0):
        super().__init__(interval, first_index)
        self.path = str(path)
        self._file = open(self.path, "a" if append else "w", newline="")
        self._writer = csv.writer(self._file)
        if not append:
            self._writer.writerow(OBSERVABLE_COLUMNS)
            self._file.flush()

    def report(self, simulation, state) -> None:
        pos = simulation.positions
        com = pos.mean(axis=0)
        energies = simulation.energies()
        timestep = getattr(simulation, "timestep", math.nan)
        row = [
            f"{simulation.time:.10g}",
            simulation.currentStep,
            f"{com[0]:.10g}",
            f"{com[1]:.10g}",
            f"{com[2]:.10g}",
            *(f"{energies[term]:.10g}" for term in ENERGY_TERMS),
            f"{float(np.max(simulation.bond_lengths())):.10g}",
            f"{timestep:.6g}",
            simulation.n_evaluations,
        ]
        self._written(lambda: self._writer.writerow(row))


class ProgressReporter(TimeScheduled):
    """Progress over simulated time, shown by :class:`knotmm.progress.Progress`.

    A bar (tqdm) on a terminal, else one line (``knotmm: t = 20 / 200 tau_d (10 %), ...``)
    each time another 10 % of the run is done or :attr:`Progress.line_seconds
    <knotmm.progress.Progress.line_seconds>` have passed since the last line: the display of
    every long command; this reporter only tells it the simulated time.

    Parameters
    ----------
    start, end : float
        Simulated time of the start and the end of the run, in tau_d.
    interval : float, optional
        How often progress is looked at, in tau_d; default (end - start) / 200.
    enabled : bool, optional
        True: always a bar; False: nothing; None (default): a bar when ``stream`` is a
        terminal, else lines.
    stream : file, optional
        Default: standard error.
    """

    def __init__(self, start: float, end: float, interval: float | None = None,
                 enabled: bool | None = None, stream=None):
        interval = interval or max((end - start) / 200.0, 1e-12)
        super().__init__(interval, int(math.floor(start / interval + 1e-9)) + 1)
        self.start = start
        self.end = end
        self.progress = Progress(
            end - start, "", "tau_d", enabled=enabled, stream=stream, label="t = ",
            origin=start,
            bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} tau_d [{elapsed}<{remaining}]",
        )

    def report(self, simulation, state) -> None:
        self.progress.update_to(min(simulation.time, self.end) - self.start)
        self.advance()

    def close(self) -> None:
        self.progress.close()


class KnotTypeWatch(TimeScheduled):
    """Check the knot type every ``interval`` tau_d (topoly) and react to a change.

    A bead model can let one strand pass through another when the strands are pressed
    together (docs/model.md): this reporter notices it. With the default identifier, topoly runs
    in a worker process beside the simulation: a check is judged at a later report (or when
    the run ends), so ``on_change="stop"`` stops the run one check interval after the frame
    where the change was seen, and the message names that frame's time. Every change is recorded in
    :attr:`changes` as ``(time, old_type, new_type)``; with ``on_change="stop"`` the run stops
    with :class:`knotmm.errors.KnotTypeChanged`, otherwise a warning is logged.

    Parameters
    ----------
    interval : float
        In tau_d.
    expected : str or None
        Chiral knot type at the start, as :func:`knotmm.knots.identify.identify_knot` with
        ``chiral=True`` names it (``"+3_1"``, :mod:`knotmm.knots.chirality`); None: taken
        from :meth:`identify_start` or else the first check. Chirality counts: strand
        passages that turn a right-handed trefoil into a left-handed one are reported.
    on_change : {"warn", "stop"}
    first_index : int
    identify : callable, optional
        ``positions -> name``; default: a :class:`knotmm.knots.worker.IsolatedKnotIdentifier`
        (topoly in a worker process, so that a crash in it cannot end the run), started
        at once in the background.

    Attributes
    ----------
    checks : int
        Checks that ran (an identification that gave no answer, its worker having crashed
        or timed out, is not counted).
    skipped : int
        Checks that gave no answer.
    dropped : int
        Checks still under way when an interrupted run closed the watch.
    start_type : str or None
        The starting shape's type, once :meth:`identify_start`'s identification is back.
    """

    def __init__(self, interval, expected=None, on_change="warn", first_index=0,
                 identify=None):
        super().__init__(interval, first_index)
        if identify is None:
            from knotmm.knots.worker import IsolatedKnotIdentifier

            identify = IsolatedKnotIdentifier(chiral=True)
            identify.start()  # off the run's path: the worker imports topoly meanwhile
        self._identify = identify
        self._start = None
        self.start_type: str | None = None
        self._pending: list = []
        self.current = expected
        self.on_change = on_change
        self.changes: list[tuple[float, str | None, str | None]] = []
        self.checks = 0
        self.skipped = 0
        self.dropped = 0

    def identify_start(self, positions) -> None:
        """Identify the starting shape beside the run (not counted as a check).

        Its result is :attr:`start_type` and, unless ``expected`` was given, the type that
        later checks are compared with.
        """
        submit = getattr(self._identify, "submit", None)
        if submit is None:
            self._start_found(self._identify(positions))
        else:
            self._start = submit(positions)

    def _start_found(self, found: str | None) -> None:
        self._start = None
        self.start_type = found
        if self.current is None and found != "unknown":
            self.current = found

    def report(self, simulation, state) -> None:
        self.advance()
        self.collect(wait=False)
        submit = getattr(self._identify, "submit", None)
        if submit is None:  # a plain callable: check now
            self._judge(simulation.time, simulation.currentStep,
                        self._identify(simulation.positions))
        else:  # the worker identifies beside the run; judged at a later report
            self._pending.append((simulation.time, simulation.currentStep,
                                  submit(simulation.positions)))

    def _worker_ready(self) -> bool:
        """Whether waiting is quick: the identifier has no worker, or its worker has
        imported topoly (a worker still starting would hold the caller for seconds)."""
        return bool(getattr(self._identify, "ready", True))

    def finish(self, wait: bool = False) -> None:
        """At the end of a run: judge what is back, and wait for the rest when ``wait`` or
        when the worker is up (a short run does not wait for topoly's start-up;
        :meth:`close` counts what is left as dropped)."""
        self.collect(wait=wait or self._worker_ready())

    def collect(self, wait: bool = True) -> None:
        """Judge finished identifications in order (all of them with ``wait``)."""
        if self._start is not None:
            if not (wait or self._start.done()):
                return  # the start's type comes first
            self._start_found(self._start.result())
        while self._pending and (wait or self._pending[0][2].done()):
            when, step, handle = self._pending.pop(0)
            self._judge(when, step, handle.result())

    def _judge(self, when: float, step: int, found: str | None) -> None:
        from knotmm.errors import KnotTypeChanged

        if found is None:  # not identified (the worker crashed or timed out)
            self.skipped += 1
            return
        self.checks += 1
        if found == "unknown":
            return
        if self.current is None:
            self.current = found
            return
        if found != self.current:
            self.changes.append((when, self.current, found))
            message = (
                f"the knot type changed from {self.current} to {found} by t = {when:.6g} tau_d "
                f"(step {step}): strands passed through each other"
            )
            self.current = found
            if self.on_change == "stop":
                self._pending.clear()
                raise KnotTypeChanged(message + "; run.on_topology_change = \"stop\"")
            import logging

            logging.getLogger(__name__).warning(message)

    def close(self, wait: bool = True) -> None:
        """Judge the checks still under way and stop the worker.

        ``wait=False`` (a run being interrupted, which must end promptly) judges only the
        checks already finished and drops the others; :attr:`dropped` counts them. A worker
        still starting (importing topoly) is not waited for either.
        """
        from knotmm.errors import KnotTypeChanged

        try:
            self.collect(wait=wait and self._worker_ready())
        except KnotTypeChanged:
            pass  # recorded in self.changes; the run is ending anyway
        finally:
            self.dropped += len(self._pending)
            self._pending.clear()
            self._start = None
            closer = getattr(self._identify, "close", None)
            if closer is not None:
                closer()
