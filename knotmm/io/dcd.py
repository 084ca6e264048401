"""DCD files: their layout, frame counts, truncation, and reading them quietly.

A DCD file (CHARMM/NAMD layout, as OpenMM's ``DCDFile`` and mdtraj write it) is a header
followed by equally sized frames. The header holds the number of frames its writer
counted; a process killed while writing leaves fewer whole frames in the file than that, or
a partial frame at its end. :func:`dcd_layout` is the one place where that is measured:
resuming a run (:func:`truncate_dcd`), loading one (:func:`read_dcd`) and reading a start
frame from a file (:mod:`knotmm.io.structure`) all use it.

Coordinates in a knotmm DCD are in Angstrom (1 d = 10 A). :class:`DCDWriter` is the one
writer of knotmm DCD files (a run's :class:`knotmm.engine.reporters.DCDReporter`,
:func:`write_dcd` for the orbit's files): it converts from d, once, as it writes a frame.

Every DCD opened through mdtraj is opened here, by :func:`c_path`: mdtraj's
``DCDTrajectoryFile`` takes its file name as a C ``char*`` and converts a ``str`` with the
ASCII codec, so a path with spaces is fine but one with ``ü`` or ``☃`` fails with
``UnicodeEncodeError``, whatever the locale. The path is therefore handed over as the bytes
the operating system uses for it (:func:`os.fsencode`), which a ``char*`` takes as they are
and the C library passes to ``fopen``.
"""

from __future__ import annotations

import contextlib
import os
import struct
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from knotmm.errors import TrajectoryFileError
from knotmm.units import d_to_angstrom

__all__ = [
    "AKMA_PS",
    "DCDLayout",
    "DCDWriter",
    "c_path",
    "dcd_layout",
    "quiet_c_stdout",
    "read_dcd",
    "truncate_dcd",
    "write_dcd",
]

#: Bytes of one unit-cell record (4-byte marker, six float64, 4-byte marker).
_CELL_BYTES = 56
#: The AKMA unit of time of CHARMM's DCD header, in ps (OpenMM's ``DCDFile`` divides its step
#: by it).
AKMA_PS = 0.04888821


@dataclass(frozen=True)
class DCDLayout:
    """Sizes and counts of a DCD file.

    Attributes
    ----------
    header_bytes : int
        Bytes before the first frame.
    frame_bytes : int
        Bytes of one frame (three coordinate records, plus a unit cell if present).
    n_atoms : int
    claimed_frames : int
        The frame count in the header (what the writer counted).
    complete_frames : int
        Whole frames in the file.
    partial_bytes : int
        Bytes after the last whole frame (a frame cut short).
    byteorder : {"<", ">"}
    frame_interval : float or None
        Time between frames from the header, in ps (= tau_d): the steps between frames
        (``NSAVC``) times the step (``DELTA``, in AKMA time units of :data:`AKMA_PS` ps), as
        OpenMM's ``DCDFile`` writes them and MDAnalysis reads them, to the 7 digits of the
        float32 step; None when either is not positive.
    """

    header_bytes: int
    frame_bytes: int
    n_atoms: int
    claimed_frames: int
    complete_frames: int
    partial_bytes: int
    byteorder: str = "<"
    frame_interval: float | None = None

    @property
    def truncated(self) -> bool:
        """Whether the file holds fewer whole frames than its header claims, or a partial one."""
        return self.complete_frames < self.claimed_frames or self.partial_bytes > 0


def dcd_layout(path) -> DCDLayout:
    """Measure a DCD file's layout from its header and its size.

    Raises
    ------
    TrajectoryFileError
        The file is missing, not a DCD, or cut inside its header.
    """
    path = Path(path)
    try:
        size = path.stat().st_size
        with open(path, "rb") as fh:
            head = fh.read(8)
            order = None
            for candidate in ("<", ">"):
                if len(head) == 8 and head[4:8] == b"CORD" and struct.unpack(
                        candidate + "i", head[:4])[0] == 84:
                    order = candidate
                    break
            if order is None:
                raise TrajectoryFileError(f"{str(path)!r} is not a DCD file (bad header)")
            fields = fh.read(84)  # the rest of the first record and its end marker
            if len(fields) < 84:
                raise TrajectoryFileError(f"{str(path)!r} is cut inside its DCD header")
            claimed = struct.unpack(order + "i", fields[0:4])[0]
            # after 84, 'CORD': nine ints (claimed at 8), the time step (44), then at 48
            # the unit-cell flag
            has_cell = struct.unpack(order + "i", fields[40:44])[0]
            steps_between = struct.unpack(order + "i", fields[8:12])[0]  # NSAVC, at 16
            delta = struct.unpack(order + "f", fields[36:40])[0]  # DELTA, float32 at 44
            title = fh.read(4)
            if len(title) < 4:
                raise TrajectoryFileError(f"{str(path)!r} is cut inside its DCD header")
            title_bytes = struct.unpack(order + "i", title)[0]
            fh.seek(104 + title_bytes, os.SEEK_SET)
            atoms = fh.read(4)
            if len(atoms) < 4:
                raise TrajectoryFileError(f"{str(path)!r} is cut inside its DCD header")
            n_atoms = struct.unpack(order + "i", atoms)[0]
    except OSError as exc:
        raise TrajectoryFileError(f"{str(path)!r} cannot be read ({exc.strerror or exc})") \
            from None
    header = 104 + title_bytes + 8
    if n_atoms <= 0 or header > size:
        raise TrajectoryFileError(f"{str(path)!r} is cut inside its DCD header")
    frame = 3 * (8 + 4 * n_atoms) + (_CELL_BYTES if has_cell else 0)
    complete, partial = divmod(size - header, frame)
    # DELTA is a float32: the interval to its 7 significant digits (0.5, not 0.50000002)
    interval = float(f"{steps_between * float(delta) * AKMA_PS:.7g}")
    return DCDLayout(header, frame, n_atoms, max(0, claimed), complete, partial, order,
                     interval if steps_between > 0 and interval > 0 else None)


def truncate_dcd(path, n_frames: int) -> None:
    """Cut a DCD file back to its first ``n_frames`` frames and fix the header's count.

    Raises
    ------
    TrajectoryFileError
        The file is missing, damaged, or holds fewer than ``n_frames`` whole frames.
    """
    path = Path(path)
    if not path.exists():
        raise TrajectoryFileError(f"trajectory {str(path)!r} is missing; cannot resume")
    layout = dcd_layout(path)
    if layout.complete_frames < n_frames:
        raise TrajectoryFileError(
            f"trajectory {str(path)!r} holds {layout.complete_frames} whole frames but the "
            f"checkpoint counts {n_frames}; the files do not belong together"
        )
    order = layout.byteorder
    with open(path, "r+b") as fh:
        fh.truncate(layout.header_bytes + n_frames * layout.frame_bytes)
        fh.seek(8, os.SEEK_SET)
        fh.write(struct.pack(order + "i", n_frames))
        fh.seek(20, os.SEEK_SET)  # the last step: the header's time step is one frame
        fh.write(struct.pack(order + "i", max(n_frames - 1, 0)))
        fh.flush()
        os.fsync(fh.fileno())


def c_path(path) -> bytes:
    """A file name for C code that opens files (mdtraj's DCD plugin): the path's OS bytes.

    mdtraj's ``DCDTrajectoryFile(filename)`` declares ``filename`` a ``char*``: a ``str`` is
    encoded as ASCII (``UnicodeEncodeError`` for ``"ünïcødé ☃ run"``), ``bytes`` are taken as
    they are. :func:`os.fsencode` gives the bytes the kernel knows the file by, for any path
    and any locale (LANG=C.UTF-8, C, or none; undecodable names round-trip through Python's
    ``surrogateescape``). Preferred over a temporary ASCII-named link, which needs a
    writable temporary directory on the same file system (a hard link) or leaves a link
    behind when the process is killed, and over a ``chdir`` and a relative name, which
    changes the whole process's working directory under its other threads.

    The path is made absolute, so that it does not depend on the working directory later.
    """
    return os.fsencode(os.path.abspath(os.fspath(path)))


@contextlib.contextmanager
def quiet_c_stdout():
    """Keep what C code prints to descriptor 1 (mdtraj's DCD plugin) off the terminal."""
    try:
        sys.stdout.flush()
        saved = os.dup(1)
    except (OSError, ValueError):  # no usable descriptor 1: nothing to silence
        yield
        return
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        os.dup2(tmp.fileno(), 1)
        try:
            yield
        finally:
            with contextlib.suppress(OSError, ValueError):
                sys.stdout.flush()
            os.dup2(saved, 1)
            os.close(saved)


def read_dcd(path) -> tuple[np.ndarray, list[str]]:
    """Read a DCD's whole frames (Angstrom, float32) and notes on what was dropped.

    Returns
    -------
    xyz : ndarray, shape (n_frames, n_atoms, 3), float32, in Angstrom
    notes : list of str
        A note when the file holds fewer whole frames than its header claims.

    Raises
    ------
    TrajectoryFileError
        The file cannot be read as a DCD (empty, cut inside its header, not a DCD).
    """
    from mdtraj.formats import DCDTrajectoryFile

    path = Path(path)
    notes: list[str] = []
    try:
        layout = dcd_layout(path)
    except TrajectoryFileError:
        layout = None  # mdtraj's own message below says what is wrong
    try:
        with quiet_c_stdout(), DCDTrajectoryFile(c_path(path)) as fh:
            xyz, _, _ = fh.read()
    except (OSError, UnicodeError) as exc:
        # for a non-ASCII name mdtraj cannot even make its message (UnicodeDecodeError)
        why = "mdtraj cannot open it" if isinstance(exc, UnicodeError) else exc
        raise TrajectoryFileError(
            f"{path}: cannot be read as a DCD trajectory ({why}); the file is empty, "
            "truncated inside its header or not a DCD: re-run or give the right file"
        ) from None
    if layout is not None and layout.complete_frames < layout.claimed_frames:
        notes.append(
            f"{path.name}: the header claims {layout.claimed_frames} frames but only "
            f"{layout.complete_frames} are complete (the run was probably interrupted); "
            "the partial frame was dropped"
        )
    return np.asarray(xyz), notes


class DCDWriter:
    """Frames appended to a DCD file in Angstrom (1 d = 10 A), without a unit cell.

    OpenMM's ``DCDFile`` writes (or, with ``append=True``, checks) the header; frames are
    written here, byte for byte what ``DCDFile.writeModel`` writes (header frame count and
    last step, then the x, y, z records in float32 Angstrom), at a tenth of its cost.

    Parameters
    ----------
    file : binary file
        Opened ``"wb"``, or ``"r+b"`` and positioned at its end with ``append=True``; the
        caller closes it.
    topology : openmm.app.Topology
        Topology of the beads (no periodic box).
    interval : float
        Time between frames, in tau_d: the header's time step (tau_d read as ps), one
        "step" per frame.
    append : bool
        Add frames to a file that has some already (its header is checked).
    """

    def __init__(self, file, topology, interval: float, append: bool = False):
        import openmm.app  # noqa: PLC0415 - heavy import kept out of module import

        if topology.getUnitCellDimensions() is not None:
            raise ValueError("topology: has a periodic box; knotmm writes DCD frames without "
                             "a unit cell (knotmm's chains are not periodic)")
        self.file = file
        openmm.app.DCDFile(file, topology, interval, firstStep=0, interval=1, append=append)
        self.frames = 0
        if append:  # DCDFile checked the header; its frame count is at byte 8
            file.seek(8, 0)
            self.frames = struct.unpack("<i", file.read(4))[0]
            file.seek(0, 2)
        self.n_atoms = topology.getNumAtoms()
        self._marker = struct.pack("<i", 4 * self.n_atoms)

    def write(self, positions) -> None:
        """Append one frame (positions in d, shape (n_atoms, 3)) as ``DCDFile.writeModel``."""
        xyz = d_to_angstrom(np.asarray(positions, dtype=np.float64).T)  # float64 as OpenMM
        if xyz.shape != (3, self.n_atoms):
            raise ValueError(f"positions: expected shape ({self.n_atoms}, 3), got {xyz.T.shape}")
        if not np.all(np.isfinite(xyz)):
            raise ValueError("positions: a frame with non-finite coordinates cannot be written")
        xyz = xyz.astype("<f4")
        self.frames += 1
        f, marker = self.file, self._marker
        f.seek(8, 0)
        f.write(struct.pack("<i", self.frames))  # frame count
        f.seek(20, 0)
        f.write(struct.pack("<i", self.frames - 1))  # last step (first 0, one per frame)
        f.seek(0, 2)
        f.write(b"".join((marker, xyz[0].tobytes(), marker, marker, xyz[1].tobytes(), marker,
                          marker, xyz[2].tobytes(), marker)))


def write_dcd(path, positions, interval: float = 1.0) -> None:
    """Write frames to a new DCD file with :class:`DCDWriter`, as a run writes its own.

    Parameters
    ----------
    path : str or Path
        File to write (replaced atomically).
    positions : array_like, shape (n_frames, n_beads, 3), in d
    interval : float
        Time between frames, in tau_d (the header's time step).

    Raises
    ------
    OSError
        If the file cannot be written.
    """
    from knotmm.model.topology import bead_topology  # noqa: PLC0415

    path = Path(path)
    x = np.asarray(positions, dtype=np.float64)
    if x.ndim != 3 or x.shape[-1] != 3:
        raise ValueError(f"positions: expected shape (n_frames, n_beads, 3), got {x.shape}")
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".dcd")
    try:
        with os.fdopen(fd, "wb") as fh:
            # only the atom count of the Topology enters a DCD file
            writer = DCDWriter(fh, bead_topology(x.shape[1], closed=False), interval)
            for frame in x:
                writer.write(frame)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
