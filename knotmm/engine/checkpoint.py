"""Checkpoint files and the checkpoint reporter.

A checkpoint (``checkpoint.npz`` in a run directory) holds everything a simulation needs to
go on as if it had never stopped (``docs/architecture.md``):

==================== ======================================================================
``positions``        float64, shape (n_beads, 3), in d
``time``             tau_d
``step``             accepted integrator steps
``evaluations``      velocity (force + mobility) evaluations
``integrator``       the integrator's name
``integrator_state`` JSON: step size, controller memory, random state of a Brownian one
``counters``         JSON: the caller's data (a run's frames and rows written, ...)
``velocity``         optional, shape (n_beads, 3): the velocity an integrator that reuses its
                     last stage (FSAL) holds for the current positions, so that a resumed
                     run does not evaluate it again
``array_<name>``     optional: the caller's arrays (a run's knot checks still under way:
                     the positions they were sent, float64, shape (k, n_beads, 3))
==================== ======================================================================

A run keeps the record of its knot-type and linking-number checks in ``counters``
(``topology``, :func:`knotmm.engine.check_record.checks_record`), so that a resumed run's
record is the one of the state it goes on from.

:meth:`knotmm.engine.simulation.Simulation.saveCheckpoint` and ``loadCheckpoint`` write and
read it through :func:`write_checkpoint` and :func:`read_checkpoint`. It is written
atomically (temporary file, fsync, rename), so a run killed at any moment, SIGKILL
included, leaves either the previous checkpoint or the new one, never a broken file.

A run takes checkpoints at frame times, right after the frame is written
(:class:`CheckpointReporter`), and also at a fault and at a stop asked for by a signal
(:mod:`knotmm.engine.interrupt`), between two steps.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from knotmm.engine.schedule import TimeScheduled
from knotmm.errors import TrajectoryFileError
from knotmm.io.atomic import write_atomic

__all__ = [
    "CheckpointReporter",
    "read_checkpoint",
    "write_checkpoint",
]

#: The prefix of the caller's arrays in a checkpoint file (``array_<name>``).
ARRAY_PREFIX = "array_"


def write_checkpoint(path, state: dict) -> None:
    """Write a checkpoint atomically.

    Parameters
    ----------
    path : path
    state : dict
        ``positions``, ``time``, ``step``, ``evaluations``, ``integrator`` (name),
        ``integrator_state`` (dict), ``counters`` (dict), and optionally ``velocity``;
        the plugin engine adds ``engine`` (``"plugin"``) and ``openmm_checkpoint`` (the bytes
        of ``Context.createCheckpoint()``); ``arrays`` (optional dict: name -> float64 array)
        holds the caller's arrays.
    """
    payload = {
        "positions": np.asarray(state["positions"], dtype=np.float64),
        "time": np.float64(state["time"]),
        "step": np.int64(state["step"]),
        "evaluations": np.int64(state["evaluations"]),
        "integrator": np.array(state["integrator"]),
        "integrator_state": np.array(json.dumps(state["integrator_state"])),
        "counters": np.array(json.dumps(state.get("counters") or {})),
    }
    if state.get("velocity") is not None:
        payload["velocity"] = np.asarray(state["velocity"], dtype=np.float64)
    if state.get("openmm_checkpoint") is not None:
        payload["engine"] = np.array(state["engine"])
        payload["openmm_checkpoint"] = np.frombuffer(state["openmm_checkpoint"], dtype=np.uint8)
    for name, value in (state.get("arrays") or {}).items():
        payload[ARRAY_PREFIX + name] = np.asarray(value, dtype=np.float64)
    write_atomic(Path(path), lambda fh: np.savez(fh, **payload))


def read_checkpoint(path) -> dict:
    """Read a checkpoint; raise :class:`TrajectoryFileError` with one line if unusable.

    Returns
    -------
    dict
        ``positions`` (n_beads, 3) float64, ``time``, ``step``, ``evaluations``,
        ``integrator`` (name), ``integrator_state`` (dict), ``counters`` (dict) and
        ``velocity`` (n_beads, 3) or None; ``engine`` (``"python"`` when the file does not
        say), ``openmm_checkpoint`` (bytes, or None) and ``arrays`` (dict: name -> float64
        array; empty when the file holds none).
    """
    path = Path(path)
    if not path.exists():
        raise TrajectoryFileError(
            f"no checkpoint {str(path)!r}: the run stopped before its first checkpoint; start "
            f"it again with --overwrite"
        )
    try:
        with np.load(path, allow_pickle=False) as data:
            out = {
                "positions": np.array(data["positions"], dtype=np.float64),
                "time": float(data["time"]),
                "step": int(data["step"]),
                "evaluations": int(data["evaluations"]),
                "integrator": str(data["integrator"]),
                "integrator_state": json.loads(str(data["integrator_state"])),
                "counters": json.loads(str(data["counters"])),
                "velocity": (np.array(data["velocity"], dtype=np.float64)
                             if "velocity" in data.files else None),
                "engine": str(data["engine"]) if "engine" in data.files else "python",
                "openmm_checkpoint": (data["openmm_checkpoint"].tobytes()
                                      if "openmm_checkpoint" in data.files else None),
                "arrays": {name[len(ARRAY_PREFIX):]: np.array(data[name], dtype=np.float64)
                           for name in data.files if name.startswith(ARRAY_PREFIX)},
            }
    except Exception as exc:  # noqa: BLE001 - any damage means the same to the user
        raise TrajectoryFileError(
            f"checkpoint {str(path)!r} is unreadable ({type(exc).__name__}: {exc}); start the "
            f"run again with --overwrite"
        ) from None
    shape = out["positions"].shape
    if len(shape) != 2 or shape[1] != 3:
        raise TrajectoryFileError(f"checkpoint {str(path)!r} holds positions of shape "
                                  f"{shape}, expected (n_beads, 3)")
    if out["velocity"] is not None and out["velocity"].shape != shape:
        out["velocity"] = None
    return out


class CheckpointReporter(TimeScheduled):
    """Save the simulation's checkpoint every ``interval`` tau_d.

    Attach it after the trajectory and observables reporters, so that at a shared time the
    checkpoint counts the frame and row just written.

    Parameters
    ----------
    path : path
    interval : float
        In tau_d (a run makes it a multiple of the frame interval).
    counters : callable
        ``counters(next_checkpoint)`` returns the caller's data to store (frames and rows
        written, ...), given the index of the next periodic checkpoint.
    first_index : int
        Index of the next checkpoint (checkpoint k is at ``k * interval``).
    arrays : callable, optional
        ``arrays()`` returns the caller's arrays to store with the state (name -> float64
        array; a run's knot checks still under way), or None.
    """

    def __init__(self, path, interval, counters, first_index=0, arrays=None):
        super().__init__(interval, first_index)
        self.path = Path(path)
        self._counters = counters
        self._arrays = arrays

    def report(self, simulation, state) -> None:
        self._save(simulation, self.index + 1)
        self.advance()

    def save_now(self, simulation) -> None:
        """Save the current state between periodic checkpoints (at a fault, or a stop asked
        for by a signal); the periodic schedule goes on unchanged after resume."""
        self._save(simulation, self.index)

    def _save(self, simulation, next_checkpoint: int) -> None:
        arrays = self._arrays() if self._arrays is not None else None
        if arrays:
            simulation.saveCheckpoint(self.path, self._counters(next_checkpoint), arrays=arrays)
        else:
            simulation.saveCheckpoint(self.path, self._counters(next_checkpoint))
