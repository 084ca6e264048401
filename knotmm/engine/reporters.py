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
import struct
import sys
import time

import numpy as np
import openmm.app

from knotmm.engine.schedule import TimeScheduled
from knotmm.io.observables import ENERGY_TERMS, OBSERVABLE_COLUMNS

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

    Frame ``k`` is the state at ``t = k * interval``. OpenMM's ``DCDFile`` writes (or, for
    resumed runs, ``append=True``, checks) the header; frames are written here, byte for byte
    what ``DCDFile.writeModel`` writes (header frame count and last step, then the x, y, z
    records in float32 Angstrom), at a tenth of its cost. ``first_index``: frames already in
    the file.

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
        # The header's time step is the frame interval (tau_d read as ps): one "step" per frame.
        openmm.app.DCDFile(self._file, topology, self.interval, firstStep=0, interval=1,
                           append=append)
        self._frames = 0
        if append:  # DCDFile checked the header; its frame count is at byte 8
            self._file.seek(8, 0)
            self._frames = struct.unpack("<i", self._file.read(4))[0]
            self._file.seek(0, 2)
        self._n_atoms = topology.getNumAtoms()
        self._marker = struct.pack("<i", 4 * self._n_atoms)

    def report(self, simulation, state) -> None:
        self._written(lambda: self._write_frame(simulation.positions))

    def _write_frame(self, positions) -> None:
        """Append one frame (positions in d, shape (n_beads, 3)) as ``DCDFile.writeModel``."""
        xyz = 10.0 * np.asarray(positions, dtype=np.float64).T  # Angstrom, float64 as OpenMM
        if xyz.shape != (3, self._n_atoms):
            raise ValueError(f"positions: expected shape ({self._n_atoms}, 3), got {xyz.T.shape}")
        if not np.all(np.isfinite(xyz)):
            raise ValueError("positions: a frame with non-finite coordinates cannot be written")
        xyz = xyz.astype("<f4")
        self._frames += 1
        f, marker = self._file, self._marker
        f.seek(8, 0)
        f.write(struct.pack("<i", self._frames))  # frame count
        f.seek(20, 0)
        f.write(struct.pack("<i", self._frames - 1))  # last step (first 0, one per frame)
        f.seek(0, 2)
        f.write(b"".join((marker, xyz[0].tobytes(), marker, marker, xyz[1].tobytes(), marker,
                          marker, xyz[2].tobytes(), marker)))


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
    """Progress over simulated time: a bar (tqdm) on a terminal, else a line now and then.

    Parameters
    ----------
    start, end : float
        Simulated time of the start and the end of the run, in tau_d.
    interval : float, optional
        How often progress is looked at, in tau_d; default (end - start) / 200.
    enabled : bool, optional
        True: always a bar; False: nothing; None (default): a bar when ``stream`` is a
        terminal, else one line (``knotmm: t = 20 / 200 tau_d (10 %), ...``) each time
        another 10 % of the run is done or 30 s have passed since the last line.
    stream : file, optional
        Default: standard error.
    """

    #: Seconds between two progress lines, at most (when no 10 % step comes sooner).
    line_seconds = 30.0

    def __init__(self, start: float, end: float, interval: float | None = None,
                 enabled: bool | None = None, stream=None):
        stream = sys.stderr if stream is None else stream
        interval = interval or max((end - start) / 200.0, 1e-12)
        super().__init__(interval, int(math.floor(start / interval + 1e-9)) + 1)
        self.start = start
        self.end = end
        self._bar = None
        self._stream = None
        terminal = hasattr(stream, "isatty") and stream.isatty()
        if enabled or (enabled is None and terminal):
            from tqdm import tqdm

            self._bar = tqdm(
                total=round(end - start, 6),
                initial=0,
                unit="tau_d",
                file=stream,
                dynamic_ncols=True,
                bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} tau_d [{elapsed}<{remaining}]",
            )
        elif enabled is None:
            self._stream = stream
            self._wall0 = self._last_line = time.monotonic()
            self._tenths = 0
        self._shown = 0.0

    def report(self, simulation, state) -> None:
        done = min(simulation.time, self.end) - self.start
        if self._bar is not None:
            self._bar.update(done - self._shown)
            self._shown = done
        elif self._stream is not None and self.end > self.start:
            self._line(done)
        self.advance()

    def _line(self, done: float) -> None:
        now = time.monotonic()
        fraction = done / (self.end - self.start)
        tenths = int(math.floor(fraction * 10 + 1e-9))
        if tenths <= self._tenths and now - self._last_line < self.line_seconds:
            return
        self._tenths = max(self._tenths, tenths)
        self._last_line = now
        elapsed = now - self._wall0
        left = f", about {elapsed * (1 - fraction) / fraction:.0f} s left" if fraction > 0 else ""
        print(
            f"knotmm: t = {self.start + done:g} / {self.end:g} tau_d ({100 * fraction:.0f} %), "
            f"{elapsed:.0f} s{left}",
            file=self._stream,
            flush=True,
        )

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None


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
