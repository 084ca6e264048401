"""The local executor: sweep points in spawned worker processes, with crash recovery.

A worker process that dies (a crash in native code, killed for memory) fails only the point
that crashed it: the points that were running or queued beside it are run again, one at a
time, each in a fresh process. Ctrl-C (SIGINT) reaches every worker: each interrupts its
point (whose ``run.toml`` then records ``interrupted``, resumable) and ends; the sweep then
raises ``KeyboardInterrupt``. See ``docs/architecture.md``.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import time

from knotmm.sweep.point import INTERRUPT_EXIT, WorkerState, error_text, leave, lost_result

__all__ = ["default_workers", "run_local"]

_DIED = (
    "the worker process died while running this point (a crash in native code, or killed "
    "for memory)"
)


def run_local(tasks, workers: int, on_result, func) -> None:
    """Run tasks in ``workers`` spawned processes; a crashed worker fails only its point.

    A process that dies takes down the points running or queued beside it; those are run
    again one at a time, each in a fresh process, so only the point that crashes it fails.
    A worker that ended because of Ctrl-C stops the whole sweep (KeyboardInterrupt).
    """
    import gc

    executors: list = []
    try:
        lost = _run_pool(tasks, workers, on_result, func, executors)
        for task in lost:
            if _run_pool([task], 1, on_result, func, executors):
                on_result(lost_result(task["name"], _DIED))
    except BaseException as exc:
        for executor in executors:
            _abort_executor(executor)
        if isinstance(exc, KeyboardInterrupt):
            exc.__traceback__ = None  # it would keep the pools' frames alive; it needs none
        raise
    finally:
        # A sweep stopped later exits at once (os._exit in knotmm.cli.main): free the pools
        # now, so that their semaphores are unlinked, rather than left for multiprocessing's
        # resource tracker to warn about ("leaked semaphore objects") on the terminal.
        executors.clear()
        gc.collect()


def _run_pool(tasks, workers: int, on_result, func, executors: list) -> list[dict]:
    """One process pool over ``tasks``; returns the tasks lost to a dead worker process."""
    from concurrent.futures import ProcessPoolExecutor, as_completed
    from concurrent.futures.process import BrokenProcessPool

    lost: list[dict] = []
    executor = ProcessPoolExecutor(
        max_workers=max(1, min(workers, len(tasks))),
        mp_context=multiprocessing.get_context("spawn"),
        initializer=_worker_init,
        initargs=(os.getpid(),),
    )
    executors.append(executor)
    with _children_ignore_sigint():  # submit starts the worker processes
        futures = {executor.submit(func, t): t for t in tasks}
    processes = list(getattr(executor, "_processes", {}).values())
    for fut in as_completed(futures):
        task = futures[fut]
        try:
            result = fut.result()
        except BrokenProcessPool:
            lost.append(task)
            continue
        except Exception as exc:  # e.g. a result that cannot be sent back
            result = lost_result(task["name"], error_text(exc))
        on_result(result)
    executor.shutdown(wait=True)
    if lost and any(p.exitcode == INTERRUPT_EXIT for p in processes):
        raise KeyboardInterrupt  # Ctrl-C reached the workers before this process
    return lost


@contextlib.contextmanager
def _children_ignore_sigint():
    """Start worker processes with SIGINT ignored until their initializer handles it.

    A spawned worker imports for a second before :func:`_worker_init` installs its handler;
    a SIGINT then (Ctrl-C on the terminal, or the parent stopping the sweep) would end it
    with Python's KeyboardInterrupt traceback. An ignored signal stays ignored across
    ``exec``, so SIGINT is ignored in this process while it starts them (a few
    milliseconds; a Ctrl-C in that instant is lost, the next one stops the sweep). Only
    from the main thread (the only one that may change a handler).
    """
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT,
                      previous if previous is not None else signal.default_int_handler)


def _abort_executor(executor) -> None:
    """Cancel queued points and stop this executor's own worker processes.

    Each worker gets SIGINT (again every second: a signal that lands on one of its other
    threads while its main thread waits is only seen late), interrupts its point
    (``run.toml`` then says ``interrupted``) and exits with the processes it started. A
    worker still alive after a few seconds is killed, with its descendants.
    """
    import signal

    processes = list(getattr(executor, "_processes", {}).values())
    # shutdown(wait=False) forgets the manager thread, which holds the pool's queues (and
    # their semaphores) until it ends: kept here, to be waited for below
    manager = getattr(executor, "_executor_manager_thread", None)
    executor.shutdown(wait=False, cancel_futures=True)
    deadline = time.monotonic() + 8.0
    while time.monotonic() < deadline:
        alive = [p for p in processes if p.is_alive() and p.pid is not None]
        if not alive:
            break
        for proc in alive:
            try:
                os.kill(proc.pid, signal.SIGINT)
            except ProcessLookupError:
                pass
        for proc in alive:
            proc.join(timeout=1.0 / len(alive))
    for proc in processes:
        if proc.is_alive() and proc.pid is not None:
            for pid in _descendants(proc.pid):
                try:
                    os.kill(pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
            proc.kill()
            proc.join(timeout=2.0)
    if manager is not None:
        manager.join(timeout=30.0)  # it ends once it has seen its workers gone
    executor.shutdown(wait=True)  # release its queues


def _descendants(pid: int) -> list[int]:
    """Processes below ``pid`` (Linux ``/proc``; empty elsewhere)."""
    found: list[int] = []
    todo = [pid]
    while todo:
        current = todo.pop()
        try:
            tasks = os.listdir(f"/proc/{current}/task")
        except OSError:
            continue
        for tid in tasks:
            try:
                with open(f"/proc/{current}/task/{tid}/children") as fh:
                    children = [int(c) for c in fh.read().split()]
            except (OSError, ValueError):
                continue
            found += children
            todo += children
    return found


def _on_stop(signum, frame):  # pragma: no cover - runs in the worker processes
    """SIGINT in a local worker: interrupt the point (its run records ``interrupted``) and
    leave; an idle worker leaves at once.

    The first SIGINT lets a running simulation finish its step and checkpoint that state
    (:mod:`knotmm.engine.interrupt`); the parent repeats the signal every second, and a repeat
    interrupts at once (a point being analysed, or a step that takes that long).
    """
    from knotmm.engine.interrupt import request_stop

    first = not WorkerState.stopping
    WorkerState.stopping = True
    if not WorkerState.running:
        leave()
    if first:
        request_stop()
        return
    raise KeyboardInterrupt


def _worker_init(parent: int | None = None) -> None:  # pragma: no cover - in the workers
    """Initialise a local worker process: quiet logging, Agg backend, one thread each.

    SIGINT (Ctrl-C on the terminal, or sent by the parent when the sweep is stopped)
    interrupts the running point, so that its ``run.toml`` records ``interrupted``, and ends
    the worker. SIGINT is used rather than SIGTERM because topoly's C code replaces the
    SIGTERM handler once it has been called.
    """
    import signal
    import threading

    os.environ.setdefault("OMP_NUM_THREADS", "1")
    os.environ.setdefault("MPLBACKEND", "Agg")
    signal.signal(signal.SIGINT, _on_stop)
    # a worker whose parent died (killed) would wait for work forever: leave instead
    # (``parent`` is the sweep's pid, passed in: one killed while this worker was starting
    # has already left it to init, and os.getppid() here would name init)
    parent = os.getppid() if parent is None else parent
    if os.getppid() != parent:
        os._exit(1)
    threading.Thread(target=_watch_parent, args=(parent,), daemon=True).start()


def _watch_parent(parent: int) -> None:  # pragma: no cover - runs in the worker processes
    while True:
        time.sleep(1.0)
        if os.getppid() != parent:
            os._exit(1)


def default_workers(threads: int) -> int:
    """Worker processes that fill this machine's cores with ``threads`` threads each."""
    from knotmm.engine.affinity import usable_cores

    return max(1, usable_cores() // max(1, int(threads)))
