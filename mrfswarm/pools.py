"""Process pools that stop with the run.

:func:`process_pool` is a :class:`concurrent.futures.ProcessPoolExecutor` whose workers
ignore Ctrl-C and leave it to the parent (one message, no traceback per worker), and which,
when the block it serves ends in an exception (Ctrl-C included), cancels the tasks still
queued and terminates the workers still running instead of waiting for them: an
interrupted flight simulation of one robot per process (tens of seconds each) otherwise
kept the run hanging after it had said "interrupted". The sweeps, the window QPs and the
flight simulation run their processes through it.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import signal
from collections.abc import Iterator
from multiprocessing.context import BaseContext


def ignore_sigint() -> None:
    """Pool workers leave Ctrl-C to the parent, which stops them; SIGTERM (the parent's :func:`stop`) ends them at
    once, whatever handler the parent had (the command's turns it into an exception)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def stop(pool: cf.ProcessPoolExecutor) -> None:
    """Cancel ``pool``'s queued tasks and terminate its running workers; returns at once."""
    running = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for proc in running:
        proc.terminate()


@contextlib.contextmanager
def process_pool(workers: int, mp_context: BaseContext | None = None) -> Iterator[cf.ProcessPoolExecutor]:
    """A process pool for a ``with`` block: shut down normally at its end, stopped
    (:func:`stop`) when the block raises."""
    pool = cf.ProcessPoolExecutor(max_workers=workers, mp_context=mp_context, initializer=ignore_sigint)
    try:
        yield pool
    except BaseException:
        stop(pool)
        raise
    pool.shutdown(wait=True)
