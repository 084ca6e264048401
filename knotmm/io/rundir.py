"""The run directory: its file names, ``run.toml``, the run status, preparing and locking it.

A run directory is a contract other tools rely on (``docs/architecture.md``):

=================== =========================================================================
``trajectory.dcd``  frames in Angstrom (1 d = 10 A), no unit cell; frame 0 is the start and
                    frame k the state at ``k * output.frame_interval`` tau_d
``topology.pdb``    the starting positions, one residue ``BEA`` per bead, CONECT records for
                    every bond including the ring closure
``run.toml``        every resolved parameter (a valid run file) plus a ``[knotmm]`` table:
                    version, status (:data:`STATUSES`), template facts, and the run's summary
``observables.csv`` time (tau_d), step, centre of mass (d), energy per term (F0 d), longest
                    bond (d), current step size, velocity evaluations
``checkpoint.npz``  the simulation state to resume from (:mod:`knotmm.engine.checkpoint`)
``analysis.json``   what ``knotmm analyze`` found (:mod:`knotmm.analysis.core`)
``view.vmd``        a VMD script (:mod:`knotmm.io.vmd`): ``vmd -e RUN_DIR/view.vmd`` (from any
                    directory) loads the pair, draws the ring and centres the view on it
=================== =========================================================================

Every module that names one of these files imports the name from here. While a process
writes a run directory it holds :data:`LOCK_FILE` locked (:class:`RunLock`), so that a
second run, an ``--overwrite`` or a ``--resume`` of the same directory is refused.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
from pathlib import Path
from typing import Any

from knotmm.errors import ConfigError, KnotmmError, RunDirectoryError
from knotmm.io.atomic import remove_temporaries

__all__ = [
    "ANALYSIS_FILE",
    "SHAPE_FILE",
    "ANALYSIS_RUNNING_KEY",
    "CHECKPOINT_FILE",
    "LOCK_FILE",
    "OBSERVABLES_FILE",
    "RUN_FILE",
    "RUN_FILES",
    "STATUSES",
    "STATUS_FAULT",
    "STATUS_FINISHED",
    "STATUS_INTERRUPTED",
    "STATUS_RUNNING",
    "START_FILES",
    "TOPOLOGY_FILE",
    "TRAJECTORY_FILE",
    "VMD_FILE",
    "OutputError",
    "RunLock",
    "WriteFault",
    "check_output_directory",
    "check_output_file",
    "describe_os_error",
    "disk_full",
    "lock_owner",
    "prepare_directory",
    "read_facts",
    "retire_stale_analysis",
    "run_file_header",
    "run_status",
    "starting",
    "write_run_toml",
    "writing",
    "writing_output",
]

#: Frames (Angstrom, DCD).
TRAJECTORY_FILE = "trajectory.dcd"
#: Starting positions and bonds (PDB).
TOPOLOGY_FILE = "topology.pdb"
#: The resolved run file and the ``[knotmm]`` facts table.
RUN_FILE = "run.toml"
#: One row of observables per report time (CSV).
OBSERVABLES_FILE = "observables.csv"
#: The simulation state to resume from.
CHECKPOINT_FILE = "checkpoint.npz"
#: The analysis of the run.
ANALYSIS_FILE = "analysis.json"
#: The analysis's per-frame shape series (Rg, asphericity, ACN, writhe), beside it.
SHAPE_FILE = "analysis_shape.csv"
#: VMD script loading the topology and the trajectory.
VMD_FILE = "view.vmd"
#: Held locked (``flock``) by the process writing the directory; holds its process id.
LOCK_FILE = ".knotmm.lock"

#: Files knotmm writes into a run directory (and may replace with ``overwrite``).
RUN_FILES = (
    TRAJECTORY_FILE,
    TOPOLOGY_FILE,
    RUN_FILE,
    OBSERVABLES_FILE,
    VMD_FILE,
    CHECKPOINT_FILE,
    ANALYSIS_FILE,
    SHAPE_FILE,
)

#: ``[knotmm] status`` values: a process is writing the run (or was killed doing so).
STATUS_RUNNING = "running"
#: The run reached ``run.duration``.
STATUS_FINISHED = "finished"
#: The dynamics broke down or a file could not be written; ``message`` says why.
STATUS_FAULT = "fault"
#: Stopped by a signal (Ctrl-C, SIGTERM); ``message`` names it.
STATUS_INTERRUPTED = "interrupted"
STATUSES = (STATUS_RUNNING, STATUS_FINISHED, STATUS_FAULT, STATUS_INTERRUPTED)

class OutputError(KnotmmError, OSError):
    """A file of a run directory cannot be written (read-only, full disk, no permission).

    Exit code 2 (nothing written yet); :class:`knotmm.errors.SimulationFault` and exit code
    3 when it happens during a run.
    """


def describe_os_error(path, exc: OSError) -> str:
    """One line naming ``path`` and the cause of ``exc`` (``"...: disk full (ENOSPC)"``)."""
    causes = {
        errno.ENOSPC: "no space left on the device",
        errno.EDQUOT: "disk quota exceeded",
        errno.EROFS: "read-only file system",
        errno.EACCES: "permission denied",
        errno.EPERM: "operation not permitted",
    }
    cause = causes.get(exc.errno) or (exc.strerror or str(exc)).lower()
    code = errno.errorcode.get(exc.errno or 0)
    where = exc.filename if getattr(exc, "filename", None) else path
    return f"cannot write {str(where)!r}: {cause}" + (f" ({code})" if code else "")


@contextlib.contextmanager
def writing(path):
    """Turn an ``OSError`` raised inside the block into an :class:`OutputError` naming ``path``."""
    try:
        yield
    except KnotmmError:
        raise
    except OSError as exc:
        raise OutputError(describe_os_error(path, exc)) from None


# -- run.toml -------------------------------------------------------------------------------
def run_file_header(version: str) -> str:
    """The comment lines at the top of a run directory's ``run.toml``."""
    return (
        f"# knotmm run file, written by knotmm {version}.\n"
        f"# Every resolved parameter; use it again with `knotmm run run.toml`.\n"
        f"# Units: lengths in d, forces in F0, times in tau_d.\n\n"
    )


def write_run_toml(directory, cfg, facts: dict[str, Any]) -> None:
    """Write ``run.toml`` atomically: the resolved run file plus the ``[knotmm]`` facts table.

    Parameters
    ----------
    directory : path
    cfg : knotmm.config.RunConfig or dict
        The run file, or its tables as :meth:`~knotmm.config.RunConfig.to_dict` gives them
        (a run's plan holds them: :attr:`knotmm.plan.RunPlan.record`).
    facts : dict
        The ``[knotmm]`` table; None values are left out.

    Raises
    ------
    OutputError
        If it cannot be written (a full disk has no room for the temporary copy): the file
        is then as it was (its former content, or absent), never empty or cut short. A run
        that cannot record its end this way keeps ``status = "running"`` with no live lock,
        as a killed run does, and ``knotmm run --resume`` goes on from its checkpoint.
    """
    import tomli_w

    from knotmm import __version__
    from knotmm.io.atomic import write_text_atomic

    data = cfg.to_dict() if hasattr(cfg, "to_dict") else dict(cfg)
    data["knotmm"] = {k: v for k, v in facts.items() if v is not None}
    text = run_file_header(__version__) + tomli_w.dumps(data)
    path = Path(directory) / RUN_FILE
    try:
        write_text_atomic(path, text)
    except OSError as exc:
        raise OutputError(describe_os_error(path, exc)) from None


def read_facts(directory) -> dict[str, Any]:
    """The ``[knotmm]`` table of a run directory's ``run.toml`` (``{}`` if it has none)."""
    from knotmm.config import read_toml

    return dict(read_toml(Path(directory) / RUN_FILE).get("knotmm", {}))


def run_status(directory) -> str | None:
    """The ``[knotmm] status`` of a run directory, or None if it has no readable run.toml."""
    path = Path(directory) / RUN_FILE
    if not path.exists():
        return None
    try:
        return str(read_facts(directory).get("status", "unknown"))
    except ConfigError:
        return "unreadable"


# -- preparing and owning a directory -------------------------------------------------------
def prepare_directory(directory, overwrite: bool) -> None:
    """Check that ``directory`` may be written; with ``overwrite``, remove knotmm's files.

    Only the files of :data:`RUN_FILES` and knotmm's plots are removed, never anything else.
    The lock file (:data:`LOCK_FILE`) does not count as content.

    Raises
    ------
    RunDirectoryError
        If the directory holds a run (or other files) and ``overwrite`` is false.
    """
    directory = Path(directory)
    if directory.exists() and not directory.is_dir():
        raise RunDirectoryError(
            f"output directory {str(directory)!r} is a file; choose another --out"
        )
    if not directory.exists() or not any(p.name != LOCK_FILE for p in directory.iterdir()):
        return
    status = run_status(directory)
    if not overwrite:
        if status is None:
            raise RunDirectoryError(
                f"output directory {str(directory)!r} is not empty and holds no knotmm run; "
                f"choose another --out (or pass --overwrite to write knotmm's files there)"
            )
        raise RunDirectoryError(
            f"output directory {str(directory)!r} already holds a {status} run; pass "
            f"--overwrite to replace it, or choose another --out"
        )
    with writing(directory):
        for name in RUN_FILES:
            p = directory / name
            if p.exists():
                p.unlink()
        for p in directory.glob("*.png"):
            p.unlink()


#: The files a new run writes before its first step (:func:`starting`).
START_FILES = (TOPOLOGY_FILE, VMD_FILE, RUN_FILE)


@contextlib.contextmanager
def starting(lock: RunLock, overwrite: bool):
    """Prepare a locked directory for a new run and write its first files in the block.

    :func:`prepare_directory` checks (and with ``overwrite`` clears) ``lock.directory``
    first; after it none of :data:`START_FILES` is there. When the block fails (a full disk,
    no permission, an interruption), the files of :data:`START_FILES` it wrote are removed,
    the lock is released and a directory the lock created is removed, so that the same
    command works again once the cause is gone (the directory does not hold a half-made
    run). A refusal of :func:`prepare_directory` removes nothing.

    Parameters
    ----------
    lock : RunLock
        The lock of the run's directory, held.
    overwrite : bool
        As for :func:`prepare_directory`.
    """
    prepare_directory(lock.directory, overwrite)
    try:
        yield
    except BaseException:
        for name in START_FILES:
            with contextlib.suppress(OSError):
                (lock.directory / name).unlink()
        lock.release()
        if lock.created:
            with contextlib.suppress(OSError):
                lock.directory.rmdir()
        raise


class RunLock:
    """Exclusive ownership of a run directory for a process's run (``fcntl.flock``).

    :data:`LOCK_FILE` in the directory is locked and holds the owner's process id. The
    kernel drops the lock when its process ends, however it ends (SIGKILL included), so a
    lock file left by a dead process is stale and simply taken over. The file is removed on
    :meth:`release`.

    Parameters
    ----------
    directory : path
        Created if missing.
    what : str
        What is refused, for the message (``"run"``, ``"--resume"``).

    Raises
    ------
    RunDirectoryError
        Another live process owns the directory (the message names its process id).
    OutputError
        The directory or the lock file cannot be created.
    """

    def __init__(self, directory, what: str = "run"):
        self.directory = Path(directory)
        self.path = self.directory / LOCK_FILE
        self._fd: int | None = None
        #: Whether taking the lock created the directory (:func:`starting` removes it again).
        self.created = not self.directory.exists()
        with writing(self.directory):
            self.directory.mkdir(parents=True, exist_ok=True)
        while self._fd is None:
            try:
                with writing(self.path):
                    fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            except OutputError:
                if self.created:  # no lock, no empty directory left behind
                    with contextlib.suppress(OSError):
                        self.directory.rmdir()
                raise
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as exc:
                owner = _read_pid(fd)
                os.close(fd)
                if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                    raise OutputError(describe_os_error(self.path, exc)) from None
                who = f"process {owner}" if owner else "another process"
                raise RunDirectoryError(
                    f"{what} refused: run directory {str(self.directory)!r} is in use by "
                    f"{who} (lock {LOCK_FILE}); wait for it to end or stop it first"
                ) from None
            try:
                same = os.fstat(fd).st_ino == os.stat(self.path).st_ino
            except FileNotFoundError:
                same = False
            if not same:  # removed by its last owner between our open and our lock
                os.close(fd)
                continue
            self._fd = fd
        try:
            os.ftruncate(self._fd, 0)
            os.pwrite(self._fd, f"{os.getpid()}\n".encode(), 0)
        except OSError:
            pass  # a full disk: the lock holds even without the pid written
        remove_temporaries(self.directory)  # of writers killed in this directory before

    def release(self) -> None:
        """Remove the lock file and unlock (idempotent)."""
        if self._fd is None:
            return
        with contextlib.suppress(OSError):
            self.path.unlink()
        with contextlib.suppress(OSError):
            os.close(self._fd)
        self._fd = None

    @property
    def held(self) -> bool:
        """Whether this object still holds the lock."""
        return self._fd is not None

    def __enter__(self) -> RunLock:
        return self

    def __exit__(self, *exc) -> None:
        self.release()


def _read_pid(fd: int) -> int | None:
    try:
        text = os.pread(fd, 32, 0).decode("ascii", "replace").strip()
        return int(text) if text else None
    except (OSError, ValueError):
        return None


# -- outputs of the other commands (orbit, movie) --------------------------------------------
class WriteFault(OutputError):
    """A file could not be written part way through a command's output (exit code 3).

    The files written before it are kept; the one that failed is not left under its name.
    """

    exit_code = 3


#: Free space (bytes) under which a failed write is taken for a full disk.
FULL_DISK_BYTES = 1 << 20


def disk_full(directory, needed: int = 0) -> bool:
    """Whether the file system of ``directory`` has less room than ``needed`` (or 1 MiB)."""
    try:
        st = os.statvfs(directory)
    except OSError:
        return False
    return st.f_bavail * st.f_frsize < max(int(needed), FULL_DISK_BYTES)


@contextlib.contextmanager
def writing_output(path, needed: int = 0, kept: str = ""):
    """Turn a failure to write ``path`` inside the block into a :class:`WriteFault` (exit 3).

    Writers outside Python report a full disk in their own way (mdtraj's DCD writer as a
    ``TypeError``, ffmpeg as a broken pipe): for those, when the file system holds less than
    ``needed`` bytes (or 1 MiB), the cause is named as a full disk; an ``OSError`` with its
    own cause (EROFS, ENOSPC, ...) keeps it, and any other failure is named with its type.
    ``kept`` is added to the message (what was written before).
    """
    try:
        yield
    except KnotmmError:
        raise
    except Exception as error:  # noqa: BLE001 - one line naming the file, whatever was raised
        cause = error
        own = isinstance(error, OSError) and error.errno not in (None, errno.EPIPE)
        if not own and disk_full(Path(path).parent, needed):
            cause = OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
        if isinstance(cause, OSError):
            line = describe_os_error(path, cause)
        else:
            line = f"cannot write {str(path)!r}: {type(cause).__name__}: {cause}"
        raise WriteFault(" ".join(line.split()) + (f"; {kept}" if kept else "")) from None


def check_output_directory(directory, option: str = "--out") -> None:
    """Check, before a computation, that ``directory`` can take its output files (exit 2).

    It may exist (a directory) or not (then it is created, with its parents); a probe file
    is created and removed in it. :class:`RunDirectoryError` for a file in the way,
    :class:`OutputError` for a read-only or otherwise unwritable place.
    """
    import tempfile

    directory = Path(directory)
    if directory.exists() and not directory.is_dir():
        raise RunDirectoryError(
            f"{option} {str(directory)!r} is a file, not a directory; choose another {option}"
        )
    with writing(directory):
        directory.mkdir(parents=True, exist_ok=True)
        try:
            fd, probe = tempfile.mkstemp(dir=directory, prefix=".knotmm-probe.")
        except OSError as exc:
            exc.filename = str(directory)  # the directory, not the probe's name
            raise
        os.close(fd)
        os.unlink(probe)


def check_output_file(path, option: str = "--out") -> None:
    """Check, before a computation, that the file ``path`` can be written (exit 2).

    Its directory is created if missing; :class:`RunDirectoryError` if ``path`` is a
    directory, :class:`OutputError` if the place is read-only or otherwise unwritable.
    """
    path = Path(path)
    if path.is_dir():
        raise RunDirectoryError(
            f"{option} {str(path)!r} is a directory; give a file name (e.g. "
            f"{str(path / 'movie.gif')!r})"
        )
    check_output_directory(path.parent, option)


# -- who holds a directory's lock (analyze on a live run, a second sweep) -------------------
def lock_owner(directory) -> int | None:
    """The process id of the live process holding ``directory``'s :data:`LOCK_FILE`.

    Returns None when no live process holds it (no lock file, or one left by a process that
    has ended: the kernel dropped its ``flock``), and 0 when a live process holds it but its
    id cannot be read (a full disk when the lock was taken). Never raises.

    The question is asked by taking a shared ``flock`` for an instant (and giving it back):
    the owner's exclusive lock refuses it exactly while the owner lives. A process taking
    the lock in that same instant is refused as by any owner (:class:`RunLock`).
    """
    path = Path(directory) / LOCK_FILE
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return None  # no lock file (or none we may read): nobody is known to hold it
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except OSError as exc:
            if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                return _read_pid(fd) or 0
            return None
        with contextlib.suppress(OSError):
            fcntl.flock(fd, fcntl.LOCK_UN)
        return None
    finally:
        os.close(fd)


#: The key of ``analysis.json`` that ``knotmm analyze`` writes for a run still running: the
#: time reached and the process id of the run (:func:`retire_stale_analysis` reads it).
ANALYSIS_RUNNING_KEY = "run_still_running"


def retire_stale_analysis(directory) -> bool:
    """Remove ``directory``'s :data:`ANALYSIS_FILE` (and its :data:`SHAPE_FILE`) if it does not
    describe the run as it ended.

    A run calls this when it records its final status (finished, interrupted or fault),
    while it still holds its lock. The analysis is stale when ``knotmm analyze`` made it
    while the run was running (it holds :data:`ANALYSIS_RUNNING_KEY`) or when it is older
    than the run's last frame (its modification time is before the trajectory's); the
    run's plots are left, ``knotmm analyze`` rewrites them. Returns whether the file was
    removed; never raises (a run's end must not fail for it).
    """
    import json
    import logging

    directory = Path(directory)
    path = directory / ANALYSIS_FILE
    try:
        made = path.stat().st_mtime_ns
    except OSError:
        return False
    try:
        stale = made < (directory / TRAJECTORY_FILE).stat().st_mtime_ns
    except OSError:
        stale = False
    if not stale:
        try:
            data = json.loads(path.read_bytes())
            stale = isinstance(data, dict) and bool(data.get(ANALYSIS_RUNNING_KEY))
        except (OSError, ValueError):  # unreadable, or not JSON: not knotmm's live analysis
            stale = False
    if not stale:
        return False
    try:
        path.unlink()
    except OSError:
        return False
    try:  # the shape series of the same analysis goes with it
        (directory / SHAPE_FILE).unlink()
    except OSError:
        pass
    logging.getLogger(__name__).info(
        "removed %s: it was made before the run's last frame; run knotmm analyze again", path)
    return True
