"""The Dask executor: sweep points on an existing Dask distributed cluster.

Dask is the optional extra ``knotmm[cluster]``. The cluster's workers must have knotmm
installed and see the sweep directory at the same path. See ``docs/architecture.md``.
"""

from __future__ import annotations

import uuid
from pathlib import Path

from knotmm.errors import ConfigError
from knotmm.sweep.point import error_text, lost_result

__all__ = ["dask_client", "run_dask"]


def dask_client(scheduler):
    """A ``distributed.Client`` for ``scheduler`` (address, scheduler file or a Client).

    Returns
    -------
    (client, owned) : (distributed.Client, bool)
        ``owned``: the client was made here, and the caller closes it.

    Raises
    ------
    ConfigError
        Dask is not installed, or the scheduler cannot be reached (one line).
    """
    try:
        import distributed
    except ImportError:
        raise ConfigError(
            f"--scheduler {scheduler}: Dask is not installed; install the cluster extra: "
            f"pip install 'knotmm[cluster]'"
        ) from None
    if isinstance(scheduler, distributed.Client):
        return scheduler, False
    text = str(scheduler)
    try:
        if text.endswith(".json") and Path(text).is_file():
            client = distributed.Client(scheduler_file=text, timeout="20s")
        else:
            client = distributed.Client(text, timeout="20s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise ConfigError(
            f"--scheduler {text}: cannot connect to a Dask scheduler ({error_text(exc)}); "
            f"start one with `dask scheduler` and give its tcp://host:port"
        ) from None
    return client, True


def run_dask(tasks, scheduler, on_result, func) -> None:
    """Run ``func(task)`` for every task on the cluster; ``on_result`` as each one ends.

    A task whose worker is lost is run again by Dask elsewhere; one that cannot be run
    (``KilledWorker``, ...) gives a point with ``status = "error"``. Ctrl-C cancels the
    tasks not yet finished.
    """
    import distributed

    client, owned = dask_client(scheduler)
    token = uuid.uuid4().hex[:8]
    futures = []
    try:
        futures = [
            client.submit(func, task, key=f"knotmm-point-{token}-{i}", pure=False)
            for i, task in enumerate(tasks)
        ]
        by_key = {f.key: t for f, t in zip(futures, tasks, strict=True)}
        for fut in distributed.as_completed(futures):
            task = by_key[fut.key]
            try:
                result = fut.result()
            except Exception as exc:  # KilledWorker, lost worker, ...
                result = lost_result(task["name"], error_text(exc))
            on_result(result)
    except BaseException:
        if futures:
            client.cancel(futures)
        raise
    finally:
        if owned:
            client.close()
