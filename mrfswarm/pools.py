"""Process pools that stop with the run.

:func:`process_pool` is a :class:`concurrent.futures.ProcessPoolExecutor` whose workers
ignore Ctrl-C and leave it to the parent (one message, no traceback per worker), and which,
when the block it serves ends in an exception (Ctrl-C included), cancels the tasks still
queued and terminates the workers still running instead of waiting for them: an
interrupted flight simulation of one robot per process (tens of seconds each) otherwise
kept the run hanging after it had said "interrupted". Its workers also end when the parent is
gone, killed outright (:func:`_exit_with_parent`). The sweeps, the window QPs and the
flight simulation run their processes through it.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import logging
import multiprocessing
import os
import signal
import sys
import threading
from collections.abc import Iterator
from multiprocessing.context import BaseContext
from typing import Any

from mrfswarm.errors import ConfigError
from solvers.registry import Backend, added, restore

#: Seconds :func:`stop` waits for the pool's manager thread to end after terminating the workers.
STOP_JOIN_S = 5.0

log = logging.getLogger(__name__)


def usable_workers(workers: int) -> int:
    """``workers``, or 1 in a daemonic process, which may not start processes of its own: a Dask worker's (its
    nanny starts it so) planned the window QPs or flew the robots in a pool and failed with "daemonic processes are
    not allowed to have children"."""
    if workers > 1 and multiprocessing.current_process().daemon:
        log.info("in a daemonic process (a Dask worker's): %d workers -> 1, in this process", workers)
        return 1
    return workers


def ignore_sigint() -> None:
    """Pool workers leave Ctrl-C to the parent, which stops them; SIGTERM (the parent's :func:`stop`) ends them at
    once, whatever handler the parent had (the command's turns it into an exception)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _exit_with_parent() -> None:
    """End this worker when its parent process is gone.

    A parent killed outright (SIGKILL, the kernel's out-of-memory killer) stops nothing, and concurrent.futures'
    workers wait for their next task for ever: `mrfswarm sweep --workers 2` killed so left its two workers (90 MB
    each) asleep until the machine restarted. The parent's sentinel becomes ready when it ends."""
    parent = multiprocessing.parent_process()
    if parent is None:
        return
    parent.join()
    os._exit(1)


def _start_worker(backends: dict[str, tuple[Backend[Any], ...]]) -> None:
    """A worker's start: :func:`ignore_sigint`, a thread that ends it with its parent (:func:`_exit_with_parent`),
    the backends the parent registered (``solvers.registry.added``; a spawned or forkserver worker does not run the
    parent's ``register`` calls), and a thread lock for tqdm."""
    ignore_sigint()
    threading.Thread(target=_exit_with_parent, name="exit-with-parent", daemon=True).start()
    restore(backends)
    # a progress bar, even a disabled one (a sweep's point plans with one), takes tqdm's lock, by default a named
    # multiprocessing semaphore that only the process's exit unlinks: a worker stop() terminates never does, and
    # Ctrl-C on a sweep of 2 workers printed "resource_tracker: There appear to be 2 leaked semaphore objects"
    from tqdm import tqdm

    tqdm.set_lock(threading.RLock())


def stop(pool: cf.ProcessPoolExecutor) -> None:
    """Cancel ``pool``'s queued tasks and terminate its running workers; returns once they have ended and the pool's
    manager thread has seen them go (at most :data:`STOP_JOIN_S` each).

    Without that wait the interpreter's exit could race the manager thread: concurrent.futures' exit hook wakes
    it through a pipe the thread closes as it ends (Python 3.11 checks the pipe, then writes), and printed
    "OSError: [Errno 9] Bad file descriptor" after the command's last line (2 of 48 runs of a SIGTERM while
    two workers solved, on a loaded machine)."""
    running = list((getattr(pool, "_processes", None) or {}).values())
    manager = getattr(pool, "_executor_manager_thread", None)  # shutdown() forgets it
    pool.shutdown(wait=False, cancel_futures=True)
    for proc in running:
        proc.terminate()
    for proc in running:  # gone, so nothing they were writing changes after this returns
        proc.join(STOP_JOIN_S)
    if manager is not None:
        manager.join(STOP_JOIN_S)


def check_shippable(backends: dict[str, tuple[Backend[Any], ...]], where: str, advice: str) -> None:
    """The backends this process registered, which workers started by spawn or forkserver repeat
    (:func:`_start_worker`), must pickle.

    Raises
    ------
    ConfigError
        Naming the first record that does not pickle, ``where`` it cannot go, and ``advice``.
    """
    import pickle

    # a main module without a file (a notebook, python -c): what it defines pickles by reference, "__main__.f", and a
    # worker, which does not run it, has no such name (the workers died, "Can't get attribute 'f' on <module
    # '__main__'>", and the sweep said it was killed or lacked `if __name__ == "__main__":`)
    interactive = not os.path.isfile(getattr(sys.modules.get("__main__"), "__file__", None) or "")
    for group, records in backends.items():
        for record in records:
            try:
                if interactive and getattr(record.entry, "__module__", None) == "__main__":
                    raise ValueError(f"{record.entry.__qualname__} is defined in an interactive session (a notebook "
                                     "cell, python -c), which worker processes do not run")
                pickle.dumps(record)
            except Exception as e:
                raise ConfigError(f"backend {record.name!r} ({group}), registered in this process, cannot reach "
                                  f"{where}: its entry is not importable by reference ({e}); define it at a module's "
                                  f"top level, or {advice}") from None


@contextlib.contextmanager
def process_pool(workers: int, mp_context: BaseContext | None = None) -> Iterator[cf.ProcessPoolExecutor]:
    """A process pool for a ``with`` block: shut down normally at its end, stopped
    (:func:`stop`) when the block raises.

    Raises
    ------
    ConfigError
        Workers that are not forked (spawn, forkserver: a script's ``set_start_method``, macOS's default) and a
        registered backend they cannot import (:func:`check_shippable`): the pool's start failed with a pickling
        traceback (a tour's ``plan(cfg, qp=..., workers=2)``, a QP backend's class defined in a function).
    """
    backends = added()
    if (mp_context or multiprocessing.get_context()).get_start_method() != "fork":
        check_shippable(backends, "the worker processes", "plan with workers=1")
    pool = cf.ProcessPoolExecutor(max_workers=workers, mp_context=mp_context, initializer=_start_worker,
                                  initargs=(backends,))
    try:
        yield pool
    except BaseException:
        stop(pool)
        raise
    pool.shutdown(wait=True)
