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

from knotmm.errors import ConfigError
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
    """The tables of ``replicas.toml``, checked.

    Returns
    -------
    dict
        ``replicas``: a table with ``count`` (int >= 1) and ``seeds`` (``count`` ints in
        [0, 2**32)); ``run_file``: a table (the shared run file, validated by whoever
        builds a :class:`~knotmm.config.RunConfig` from it).

    Raises
    ------
    knotmm.errors.ConfigError
        When it is missing or damaged (one line naming the file and what is wrong).
    """
    from knotmm.config import read_toml

    path = Path(root) / REPLICA_SET_FILE
    record = dict(read_toml(path, what="replica set record"))
    replicas = record.get("replicas")
    count = replicas.get("count") if isinstance(replicas, dict) else None
    seeds = replicas.get("seeds") if isinstance(replicas, dict) else None
    problem = None
    if not isinstance(replicas, dict):
        problem = f"a [replicas] table is expected, found {_shown(replicas)}"
    elif not _is_int(count) or count < 1:
        problem = f"[replicas] count = {_shown(count)}: a whole number >= 1 is expected"
    elif not isinstance(seeds, list) or not all(
            _is_int(s) and 0 <= s < 2**32 for s in seeds):
        problem = (f"[replicas] seeds = {_shown(seeds)}: a list of whole numbers in "
                   f"[0, 2**32) is expected")
    elif len(seeds) != count:
        problem = f"[replicas] count = {count} but seeds holds {len(seeds)}"
    elif not isinstance(record.get("run_file"), dict):
        problem = f"a [run_file] table is expected, found {_shown(record.get('run_file'))}"
    if problem is not None:
        raise ConfigError(
            f"replica set record {str(path)!r} is damaged: {problem}; restore it from a copy "
            f"(each replica_K/ is a run of its own: knotmm run --resume DIR/replica_K "
            f"continues one)"
        )
    return record


def _is_int(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _shown(value) -> str:
    """A value as it appears in the message: ``nothing`` when absent, else short."""
    if value is None:
        return "nothing"
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."
