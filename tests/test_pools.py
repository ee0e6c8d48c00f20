"""Process pools stop with the run (mrfswarm.pools): Ctrl-C in the parent ends the workers' tasks too."""

from __future__ import annotations

import multiprocessing
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from mrfswarm.errors import ConfigError
from mrfswarm.pools import process_pool
from support.added_backends import registered

SLOW_S = 3.0


def _slow_then_mark(path: str) -> None:
    time.sleep(SLOW_S)
    Path(path).write_text("finished")


def _started(path: str) -> None:
    Path(path).write_text("started")


def test_workers_leave_ctrl_c_to_the_parent():
    with process_pool(1) as pool:
        assert pool.submit(signal.getsignal, signal.SIGINT).result() == signal.SIG_IGN


def _methods() -> list[str]:
    from solvers.mrf import METHODS

    return METHODS.names()


@pytest.mark.parametrize("start", ["spawn", "forkserver"])
def test_workers_know_the_backends_the_parent_registered(start):
    """A spawned or forkserver worker imports the packages afresh: without the parent's registrations it did not
    know a script's method (the window QPs and the simulation run their processes here too)."""
    with registered() as twin, process_pool(1, multiprocessing.get_context(start)) as pool:
        assert pool.submit(_methods).result()[-1] == twin.name


@pytest.mark.parametrize("start", ["spawn", "forkserver"])
def test_a_registered_backend_such_workers_cannot_import_is_refused_in_one_line(start):
    """A script's QP backend class defined in a function, and plan(cfg, workers=2) under spawn (a script's
    set_start_method, macOS's default): the window QPs' pool failed with a pickling traceback. A forked worker
    inherits the record, and is started as before."""
    from solvers.mrf import METHODS, icm
    from solvers.registry import Backend

    def local(mrf, options):
        return icm.minimize(mrf, options)

    METHODS.register(Backend(name="icm_local", entry=local, capabilities=icm.BACKEND.capabilities))
    try:
        with pytest.raises(ConfigError, match=r"^backend 'icm_local' \(solvers\.mrf\), registered in this process, "
                                              r"cannot reach the worker processes: .*or plan with workers=1$"):
            with process_pool(1, multiprocessing.get_context(start)) as pool:
                pool.submit(_methods).result()
        with process_pool(1, multiprocessing.get_context("fork")) as pool:
            assert pool.submit(_methods).result()[-1] == "icm_local"
    finally:
        METHODS.unregister("icm_local")


def test_an_interrupted_block_terminates_the_tasks_still_running(tmp_path):
    """The flight simulation runs one robot per process for tens of seconds: interrupted, the run must not wait
    for them (it hung after printing "interrupted")."""
    started, finished = tmp_path / "started", tmp_path / "finished"
    with pytest.raises(KeyboardInterrupt):
        with process_pool(1) as pool:
            pool.submit(_started, str(started)).result()  # the worker is up
            pool.submit(_slow_then_mark, str(finished))
            time.sleep(0.5)  # it has picked the slow task up
            raise KeyboardInterrupt
    time.sleep(SLOW_S + 1.0)  # longer than the task: had it been left running, it would have finished by now
    assert started.exists() and not finished.exists()


def test_a_block_that_ends_normally_waits_for_its_tasks(tmp_path):
    finished = tmp_path / "finished"
    with process_pool(1) as pool:
        pool.submit(_slow_then_mark, str(finished))
    assert finished.exists()


def test_a_stopped_pool_has_no_manager_thread_left_for_the_exit_to_wake(tmp_path):
    """concurrent.futures' exit hook wakes each pool's manager thread through a pipe the thread closes as it ends
    (Python 3.11 checks the pipe, then writes): a SIGTERM while workers solved printed "OSError: [Errno 9] Bad file
    descriptor" after "mrfswarm: terminated" in 2 of 48 loaded runs. stop() waits for the thread, so it is gone."""
    from mrfswarm.pools import stop

    started = tmp_path / "started"
    with process_pool(2) as pool:
        pool.submit(_started, str(started)).result()
        pool.submit(_slow_then_mark, str(tmp_path / "a"))
        pool.submit(_slow_then_mark, str(tmp_path / "b"))
        time.sleep(0.3)  # both workers busy
        manager = pool._executor_manager_thread
        assert manager is not None and manager.is_alive()
        stop(pool)
        assert not manager.is_alive()


def test_a_stopped_worker_leaves_no_semaphore_to_the_resource_tracker(tmp_path):
    """A sweep's worker plans with a progress bar (disabled); tqdm's default lock is a named multiprocessing
    semaphore, which a worker stop() terminates never unlinks: Ctrl-C on `mrfswarm sweep --workers 2` printed
    "resource_tracker: There appear to be 2 leaked semaphore objects" after "mrfswarm: interrupted"."""
    script = tmp_path / "stopped.py"
    script.write_text(
        "import multiprocessing, time\n"
        "from mrfswarm.pools import process_pool\n"
        "def bar_then_sleep():\n"
        "    from tqdm import tqdm\n"
        "    tqdm(total=1, disable=True)\n"
        "    time.sleep(30)\n"
        "if __name__ == '__main__':\n"
        "    try:\n"
        "        with process_pool(1, multiprocessing.get_context('spawn')) as pool:\n"
        "            pool.submit(bar_then_sleep)\n"
        "            time.sleep(3)\n"
        "            raise KeyboardInterrupt\n"
        "    except KeyboardInterrupt:\n"
        "        print('interrupted')\n")
    root = Path(__file__).resolve().parents[1]
    proc = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=60,
                          env={**os.environ, "PYTHONPATH": str(root)})
    assert proc.stdout.strip() == "interrupted"
    assert "leaked" not in proc.stderr, proc.stderr


def _alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie its new parent has not reaped yet has ended)."""
    try:
        state = Path(f"/proc/{pid}/status").read_text()
    except FileNotFoundError:
        return False
    return "\nState:\tZ" not in state


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads /proc")
@pytest.mark.parametrize("start", ["fork", "spawn", "forkserver"])
def test_workers_end_when_their_parent_is_killed_outright(tmp_path, start):
    """SIGKILL stops nothing in the parent: `mrfswarm sweep --workers 2` killed so left its two workers waiting
    for a next task for ever (90 MB each, asleep until the machine restarted)."""
    script = tmp_path / "killed.py"
    script.write_text(
        "import multiprocessing, os, sys, time\n"
        "from mrfswarm.pools import process_pool\n"
        "def pid():\n"
        "    time.sleep(0.3)\n"
        "    return os.getpid()\n"
        "if __name__ == '__main__':\n"
        f"    with process_pool(2, multiprocessing.get_context({start!r})) as pool:\n"
        "        [f.result() for f in [pool.submit(pid) for _ in range(4)]]\n"
        "        print(' '.join(str(p) for p in pool._processes), flush=True)\n"
        "        time.sleep(60)\n")
    root = Path(__file__).resolve().parents[1]
    proc = subprocess.Popen([sys.executable, str(script)], cwd=tmp_path, stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, text=True, env={**os.environ, "PYTHONPATH": str(root)})
    try:
        workers = [int(p) for p in proc.stdout.readline().split()]
        assert len(workers) == 2 and all(_alive(p) for p in workers)
    finally:
        proc.kill()
        proc.wait()
    deadline = time.monotonic() + 10.0
    while any(_alive(p) for p in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    left = [p for p in workers if _alive(p)]
    for p in left:  # not to leave them to the machine when the test fails
        os.kill(p, signal.SIGKILL)
    assert not left
