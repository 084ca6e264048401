"""The directory of a replicated run: ``replicas.toml`` and one run directory per replica.

A run file with ``[run] replicas = K`` (K > 1) writes ``DIR/replicas.toml`` (what the set
is: the count, each replica's seed, the run file the replicas share) and
``DIR/replica_0/`` ... ``DIR/replica_{K-1}/``, each a complete run directory
(:mod:`knotmm.io.rundir`) whose ``run.toml`` gives ``run.replicas = 1`` and that replica's
``run.seed``: every command reads a replica as any run. :mod:`knotmm.replicas` runs them.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from knotmm.io.rundir import OutputError, describe_os_error

__all__ = [
    "REPLICA_SET_FILE",
    "is_replica_set",
    "read_replica_set",
    "replica_directory",
    "replica_index",
    "write_replica_set",
]

#: The replica set's record, in its directory (its marker).
REPLICA_SET_FILE = "replicas.toml"
_NAME = re.compile(r"^replica_(\d+)$")


def replica_directory(root, k: int) -> Path:
    """The run directory of replica ``k`` (from 0) of the set in ``root``."""
    return Path(root) / f"replica_{int(k)}"


def replica_index(name: str) -> int | None:
    """The replica number of a directory name (``"replica_3"`` -> 3), None for another."""
    m = _NAME.match(name)
    return int(m.group(1)) if m else None


def is_replica_set(path) -> bool:
    """Whether ``path`` is the directory of a replicated run (holds ``replicas.toml``)."""
    return (Path(path) / REPLICA_SET_FILE).is_file()


def write_replica_set(root, record: dict[str, Any]) -> None:
    """Write ``replicas.toml`` atomically (``record``: its tables; None values left out)."""
    import tomli_w

    from knotmm import __version__
    from knotmm.io.atomic import write_text_atomic

    header = (f"# knotmm replica set, written by knotmm {__version__}.\n"
              "# [replicas]: the count and each replica's run.seed; [run_file]: the run file\n"
              "# the replicas share. Each replica_K/ is a run directory of its own.\n\n")

    def clean(value):
        if isinstance(value, dict):
            return {k: clean(v) for k, v in value.items() if v is not None}
        if isinstance(value, list):
            return [clean(v) for v in value]
        return value

    path = Path(root) / REPLICA_SET_FILE
    text = header + tomli_w.dumps(clean(record))
    try:
        write_text_atomic(path, text)
    except OSError as exc:
        raise OutputError(describe_os_error(path, exc)) from None


def read_replica_set(root) -> dict[str, Any]:
    """The tables of ``replicas.toml``.

    Raises
    ------
    knotmm.errors.ConfigError
        When it is missing or damaged (one line naming the file).
    """
    from knotmm.config import read_toml

    return dict(read_toml(Path(root) / REPLICA_SET_FILE, what="replica set record"))
