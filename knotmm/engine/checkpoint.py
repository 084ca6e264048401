"""Checkpoints and exact restart.

A checkpoint (``checkpoint.npz`` in the run directory) holds everything a run needs to go on
as if it had never stopped: positions (float64, in d), time (tau_d), step, the number of
velocity evaluations, the integrator's state (step size, controller memory, random state of
a stochastic integrator) and how many frames and observables rows had been written. It is
written atomically (temporary file, fsync, rename), so a run killed at any moment, SIGKILL
included, leaves either the previous checkpoint or the new one, never a broken file.

Checkpoints are taken at frame times, right after the frame is written, and also at a fault
and at a stop asked for by a signal (:mod:`knotmm.engine.interrupt`), between two steps. To resume,
the
trajectory is cut back to the checkpoint's frame count (frames written after it, possibly a
half-written one, are dropped) and the observables table to its row count; then both are
appended to.
"""

from __future__ import annotations

import json
import os
import struct
from pathlib import Path

import numpy as np

from knotmm.errors import TrajectoryFileError
from knotmm.io.atomic import write_atomic

__all__ = [
    "CheckpointReporter",
    "load_checkpoint",
    "save_checkpoint",
    "truncate_dcd",
    "truncate_csv",
]

CHECKPOINT_NAME = "checkpoint.npz"


def save_checkpoint(path: Path, simulation, counters: dict) -> None:
    """Write the simulation's state atomically to ``path`` (an ``.npz`` file)."""
    path = Path(path)
    state = simulation.integrator.get_state()
    payload = {
        "positions": np.asarray(simulation.positions, dtype=np.float64),
        "time": np.float64(simulation.time),
        "step": np.int64(simulation.currentStep),
        "evaluations": np.int64(simulation.n_evaluations),
        "integrator": np.array(simulation.integrator.name),
        "integrator_state": np.array(json.dumps(state)),
        "counters": np.array(json.dumps(counters)),
    }
    write_atomic(path, lambda fh: np.savez(fh, **payload))


def load_checkpoint(path: Path) -> dict:
    """Read a checkpoint; raise :class:`TrajectoryFileError` with one line if unusable.

    Returns
    -------
    dict
        ``positions`` (n_beads, 3) float64, ``time``, ``step``, ``evaluations``,
        ``integrator`` (name), ``integrator_state`` (dict), ``counters`` (dict).
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
            }
    except Exception as exc:  # noqa: BLE001 - any damage means the same to the user
        raise TrajectoryFileError(
            f"checkpoint {str(path)!r} is unreadable ({type(exc).__name__}: {exc}); start the "
            f"run again with --overwrite"
        ) from None
    if out["positions"].ndim != 2 or out["positions"].shape[1] != 3:
        raise TrajectoryFileError(f"checkpoint {str(path)!r} holds positions of shape "
                                  f"{out['positions'].shape}, expected (n_beads, 3)")
    return out


class CheckpointReporter:
    """Write a checkpoint every ``interval`` tau_d (a multiple of the frame interval).

    Attach it after the trajectory and observables reporters, so that at a shared time the
    checkpoint counts the frame and row just written.

    Parameters
    ----------
    path : Path
    interval : float
        In tau_d.
    counters : callable
        ``counters(next_checkpoint)`` returns the dict of output counters to store (frames
        and rows written, ...), given the index of the next periodic checkpoint.
    first_index : int
        Index of the next checkpoint (checkpoint k is at ``k * interval``).
    """

    def __init__(self, path, interval, counters, first_index=0):
        if not interval > 0:
            raise ValueError(f"interval={interval!r}: must be > 0 (tau_d)")
        self.path = Path(path)
        self.interval = float(interval)
        self.index = int(first_index)
        self._counters = counters

    def next_report_time(self, simulation) -> float:
        return self.index * self.interval

    def report(self, simulation, state) -> None:
        save_checkpoint(self.path, simulation, self._counters(self.index + 1))
        self.index += 1

    def save_now(self, simulation) -> None:
        """Write a checkpoint of the current state, between periodic ones (at a fault, or a
        stop asked for by a signal); the periodic schedule goes on unchanged after resume."""
        save_checkpoint(self.path, simulation, self._counters(self.index))


def _dcd_layout(path: Path) -> tuple[int, int, int]:
    """``(header_bytes, frame_bytes, n_atoms)`` of a DCD file without unit cells."""
    with open(path, "rb") as fh:
        head = fh.read(8)
        if len(head) < 8 or head[4:8] != b"CORD" or struct.unpack("<i", head[:4])[0] != 84:
            raise TrajectoryFileError(f"{str(path)!r} is not a DCD file (bad header)")
        fh.seek(48, os.SEEK_SET)  # 84, 'CORD', 9 ints, the time step: then the cell flag
        has_cell = struct.unpack("<i", fh.read(4))[0]
        fh.seek(92, os.SEEK_SET)
        title_bytes = struct.unpack("<i", fh.read(4))[0]
        fh.seek(104 + title_bytes, os.SEEK_SET)
        n_atoms = struct.unpack("<i", fh.read(4))[0]
    header = 104 + title_bytes + 8
    frame = 3 * (8 + 4 * n_atoms) + (56 if has_cell else 0)
    return header, frame, n_atoms


def truncate_dcd(path: Path, n_frames: int) -> None:
    """Cut a DCD file back to its first ``n_frames`` frames and fix the header's count."""
    path = Path(path)
    if not path.exists():
        raise TrajectoryFileError(f"trajectory {str(path)!r} is missing; cannot resume")
    header, frame, _ = _dcd_layout(path)
    size = path.stat().st_size
    keep = header + n_frames * frame
    if size < keep:
        raise TrajectoryFileError(
            f"trajectory {str(path)!r} holds {(size - header) // frame} whole frames but the "
            f"checkpoint counts {n_frames}; the files do not belong together"
        )
    with open(path, "r+b") as fh:
        fh.truncate(keep)
        fh.seek(8, os.SEEK_SET)
        fh.write(struct.pack("<i", n_frames))
        fh.seek(20, os.SEEK_SET)
        fh.write(struct.pack("<i", max(n_frames - 1, 0)))
        fh.flush()
        os.fsync(fh.fileno())


def truncate_csv(path: Path, n_rows: int) -> None:
    """Keep the header and the first ``n_rows`` data rows of a CSV file."""
    path = Path(path)
    if not path.exists():
        raise TrajectoryFileError(f"observables {str(path)!r} are missing; cannot resume")
    with open(path, "rb") as fh:
        lines = fh.read().split(b"\n")
    complete = lines[: n_rows + 1]
    if len(complete) < n_rows + 1 or any(not line for line in complete):
        raise TrajectoryFileError(
            f"observables {str(path)!r} hold fewer rows than the checkpoint counts ({n_rows})"
        )
    with open(path, "wb") as fh:
        fh.write(b"\n".join(complete) + b"\n")
        fh.flush()
        os.fsync(fh.fileno())
