"""Output writers scheduled by simulated time.

A knotmm reporter has ``next_report_time(simulation) -> float`` (tau_d) and
``report(simulation, state)``; :class:`knotmm.engine.simulation.Simulation` lands its steps exactly
on those times. Report ``k`` of a reporter with interval ``dt`` is at ``k * dt`` (computed
from ``k``, never accumulated, so times do not drift). OpenMM's own step-scheduled reporters
(``describeNextReport``) can be attached to the same simulation.

Every writer flushes after each report, so a killed run keeps every finished frame and row.
"""

from __future__ import annotations

import csv
import math
import sys

import numpy as np
import openmm.app
from openmm import unit

__all__ = ["DCDReporter", "ObservablesReporter", "ProgressReporter", "OBSERVABLE_COLUMNS"]

#: Columns of ``observables.csv`` (times in tau_d, lengths in d, energies in F0 d).
OBSERVABLE_COLUMNS = (
    "time",
    "step",
    "com_x",
    "com_y",
    "com_z",
    "e_bond",
    "e_bend",
    "e_steric",
    "e_gravity",
    "e_total",
    "max_bond",
    "timestep",
    "evaluations",
)


class _TimeScheduled:
    """Reports at ``(first_index + k) * interval`` for ``k = 0, 1, ...``."""

    def __init__(self, interval: float, first_index: int = 0):
        if not interval > 0:
            raise ValueError(f"interval={interval!r}: must be > 0 (tau_d)")
        self.interval = float(interval)
        self.index = int(first_index)

    def next_report_time(self, simulation) -> float:
        return self.index * self.interval

    def _advance(self) -> None:
        self.index += 1


class DCDReporter(_TimeScheduled):
    """Write frames to a DCD file in Angstrom (1 d = 10 A), without a unit cell.

    Frame ``k`` is the state at ``t = k * interval``. Uses OpenMM's ``DCDFile``, which can
    append to an existing file (for resumed runs, ``append=True``, ``first_index`` = frames
    already in the file).

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
        self.path = str(path)
        self._file = open(self.path, "r+b" if append else "wb")
        if append:
            self._file.seek(0, 2)
        # The header's time step is the frame interval (tau_d read as ps): one "step" per frame.
        self._dcd = openmm.app.DCDFile(
            self._file, topology, self.interval, firstStep=0, interval=1, append=append
        )

    def report(self, simulation, state) -> None:
        self._dcd.writeModel(simulation.positions * unit.nanometer)
        self._file.flush()
        self._advance()

    def close(self) -> None:
        if not self._file.closed:
            self._file.close()


class ObservablesReporter(_TimeScheduled):
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
        timestep = getattr(simulation.integrator, "timestep", math.nan)
        row = [
            f"{simulation.time:.10g}",
            simulation.currentStep,
            f"{com[0]:.10g}",
            f"{com[1]:.10g}",
            f"{com[2]:.10g}",
            f"{energies['bond']:.10g}",
            f"{energies['bend']:.10g}",
            f"{energies['steric']:.10g}",
            f"{energies['gravity']:.10g}",
            f"{energies['total']:.10g}",
            f"{float(np.max(simulation.bond_lengths())):.10g}",
            f"{timestep:.6g}",
            simulation.n_evaluations,
        ]
        self._writer.writerow(row)
        self._file.flush()
        self._advance()

    def close(self) -> None:
        if not self._file.closed:
            self._file.close()


class ProgressReporter(_TimeScheduled):
    """A progress bar (tqdm) over simulated time; by default only drawn on a terminal."""

    def __init__(self, start: float, end: float, interval: float | None = None,
                 enabled: bool | None = None, stream=None):
        stream = sys.stderr if stream is None else stream
        interval = interval or max((end - start) / 200.0, 1e-12)
        super().__init__(interval, int(math.floor(start / interval + 1e-9)) + 1)
        self.start = start
        self.end = end
        self._bar = None
        if enabled is None:
            enabled = hasattr(stream, "isatty") and stream.isatty()
        if enabled:
            from tqdm import tqdm

            self._bar = tqdm(
                total=round(end - start, 6),
                initial=0,
                unit="tau_d",
                file=stream,
                dynamic_ncols=True,
                bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} tau_d [{elapsed}<{remaining}]",
            )
        self._shown = 0.0

    def report(self, simulation, state) -> None:
        if self._bar is not None:
            done = min(simulation.time, self.end) - self.start
            self._bar.update(done - self._shown)
            self._shown = done
        self._advance()

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None


class KnotTypeWatch(_TimeScheduled):
    """Check the knot type every ``interval`` tau_d (topoly) and react to a change.

    A bead model can let one strand pass through another when the strands are pressed
    together (model.md): this reporter notices it. With the default identifier, topoly runs
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
        ``chiral=True`` names it (``"+3_1"``); None: taken from the first check. Chirality
        counts: strand passages that turn a right-handed trefoil into a left-handed one are
        reported.
    on_change : {"warn", "stop"}
    first_index : int
    identify : callable, optional
        ``positions -> name``; default: a :class:`knotmm.knots.worker.IsolatedKnotIdentifier`
        (topoly in a worker process, so that a crash in it cannot end the run).
    """

    def __init__(self, interval, expected=None, on_change="warn", first_index=0,
                 identify=None):
        super().__init__(interval, first_index)
        if identify is None:
            from knotmm.knots.worker import IsolatedKnotIdentifier

            identify = IsolatedKnotIdentifier(chiral=True)
        self._identify = identify
        self._pending: list = []
        self.current = expected
        self.on_change = on_change
        self.changes: list[tuple[float, str | None, str | None]] = []
        self.checks = 0
        self.dropped = 0

    def report(self, simulation, state) -> None:
        self._advance()
        self.collect(wait=False)
        submit = getattr(self._identify, "submit", None)
        if submit is None:  # a plain callable: check now
            self._judge(simulation.time, simulation.currentStep,
                        self._identify(simulation.positions))
        else:  # the worker identifies beside the run; judged at a later report
            self._pending.append((simulation.time, simulation.currentStep,
                                  submit(simulation.positions)))

    def collect(self, wait: bool = True) -> None:
        """Judge finished identifications in order (all of them with ``wait``)."""
        while self._pending and (wait or self._pending[0][2].done()):
            when, step, handle = self._pending.pop(0)
            self._judge(when, step, handle.result())

    def _judge(self, when: float, step: int, found: str | None) -> None:
        from knotmm.errors import KnotTypeChanged

        self.checks += 1
        if found is None or found == "unknown":
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
        checks already finished and drops the others; :attr:`dropped` counts them.
        """
        from knotmm.errors import KnotTypeChanged

        try:
            self.collect(wait=wait)
        except KnotTypeChanged:
            pass  # recorded in self.changes; the run is ending anyway
        finally:
            self.dropped += len(self._pending)
            self._pending.clear()
            closer = getattr(self._identify, "close", None)
            if closer is not None:
                closer()
