"""Atomic file writes: a file is either its old content or its new one, never half of each.

The content goes to a temporary file in the same directory, is flushed to disk (fsync) and
then renamed over the target, so a process killed at any moment (SIGKILL included) leaves
a whole file behind. An ``OSError`` (a full disk, a read-only directory) names the target
file, not the temporary one. A temporary file that a killed writer left behind is removed
the next time its target is written.
"""

from __future__ import annotations

import contextlib
import os
import re
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO

__all__ = ["remove_temporaries", "replacing", "write_atomic", "write_text_atomic"]


def write_atomic(path: str | os.PathLike, write: Callable[[IO[bytes]], None]) -> None:
    """Call ``write(binary_file)`` on a temporary file, then rename it to ``path``."""
    path = Path(path)
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    except OSError as exc:
        exc.filename = str(path)  # name the file meant, not a temporary one
        raise
    try:
        os.chmod(tmp, 0o644)
        with os.fdopen(fd, "wb") as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        if os.path.exists(tmp):
            os.unlink(tmp)
        if isinstance(exc, OSError) and exc.filename in (None, tmp):
            exc.filename = str(path)
        raise
    _remove_stale(path)


#: A temporary file of :func:`write_atomic` or :func:`replacing`: ``.NAME.XXXXXXXX.tmp`` or
#: ``.NAME.XXXXXXXX.tmp.SUFFIX`` (XXXXXXXX: tempfile's random characters).
_TEMPORARY = re.compile(r"\..+\.[a-z0-9_]{8}\.tmp(\.[^.]+)?")


def _remove_stale(path: Path) -> None:
    """Remove temporary files of ``path`` that a killed writer left (SIGKILL cannot clean up).

    Called once ``path`` was replaced: the commands that write a file hold its directory's
    lock, so no other writer of ``path`` is under way.
    """
    prefix = f".{path.name}."
    remove_temporaries(path.parent, lambda name: name.startswith(prefix))


def remove_temporaries(directory, keep=None) -> None:
    """Remove the temporary files that killed atomic writers left in ``directory``.

    For a command that has just taken the directory's lock (no writer of its own is under
    way there); ``keep``, if given, is a predicate on a file name: only the names it accepts
    are removed.
    """
    with contextlib.suppress(OSError):
        for entry in os.scandir(directory):
            if (_TEMPORARY.fullmatch(entry.name) and (keep is None or keep(entry.name))
                    and entry.is_file(follow_symlinks=False)):
                with contextlib.suppress(OSError):
                    os.unlink(entry.path)


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    write_atomic(path, lambda fh: fh.write(text.encode("utf-8")))


@contextlib.contextmanager
def replacing(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``path`` for a writer that wants a file name.

    For writers that open the file themselves (mdtraj, Pillow, ffmpeg): the temporary name
    ends with ``path``'s suffix (``.m.gif.k2x9.tmp.gif``), so a writer that picks its format
    from the name still does. When the block ends without an exception the file is flushed
    to disk and renamed to ``path``; otherwise it is removed and ``path`` is left as it was
    (absent, or its old content). The temporary file exists (empty) when the block starts.
    """
    path = Path(path)
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.",
                                   suffix=".tmp" + path.suffix)
    except OSError as exc:
        exc.filename = str(path)  # name the file meant, not a temporary one
        raise
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o644)
        with open(tmp, "rb") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
        _remove_stale(path)
    except BaseException as exc:
        if os.path.exists(tmp):
            os.unlink(tmp)
        if (isinstance(exc, OSError) and exc.errno is not None  # (not a knotmm error)
                and exc.filename in (None, tmp)):
            exc.filename = str(path)
        raise
