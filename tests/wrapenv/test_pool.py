"""Worker processes for simulations (wrapenv/pool.py): they die of SIGTERM and leave Ctrl-C to
their parent, and an interrupted caller stops them at once instead of running its queue."""

from __future__ import annotations

import os
import signal
import threading
import time

from wrapenv.pool import ProcessPool


def _worker_handlers() -> tuple[object, object]:
    return signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGINT)


def _raise(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def test_process_workers_die_of_sigterm_and_leave_ctrl_c_to_their_parent():
    """The CLI turns SIGTERM into an exception; forked workers inherited that handler, so
    `ProcessPool.terminate()`'s SIGTERM only interrupted a simulation (the pool's worker loop
    returns the exception as its result and takes the next call), and an interrupted search
    could wait for its queued simulations or hang (issue 17's interrupt test, once)."""
    previous = signal.signal(signal.SIGTERM, _raise)
    try:
        with ProcessPool(1) as pool:
            term, interrupt = pool.submit(_worker_handlers).result()
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert term == signal.SIG_DFL and interrupt == signal.SIG_IGN


def test_a_terminated_pool_leaves_no_thread_behind():
    """An interrupted search terminates its pool; the pool's manager thread closes a pipe as it
    ends, which Python 3.11 writes to without a lock at interpreter exit. Left running, it made
    an interrupted `recommend` print "OSError: Bad file descriptor" once (`.ci/run`). Whether
    it was still running varied from run to run, hence a few pools."""
    before = set(threading.enumerate())
    for _ in range(4):
        pool = ProcessPool(2)
        for _ in range(4):
            pool.submit(time.sleep, 2.0)
        time.sleep(0.3)  # the workers have started
        pool.terminate()
        assert [t for t in threading.enumerate() if t not in before and t.is_alive()] == []


def _mark_after(seconds: float, path: str) -> None:
    time.sleep(seconds)
    open(path, "w").close()


def test_leaving_by_an_exception_runs_none_of_the_queue(tmp_path):
    """A fit or search interrupted with simulations queued: `ProcessPoolExecutor` would run
    every one of them before the exception got out (a SIGTERM'd `calibrate` took 23 s to
    exit); the pool ends its workers and cancels the rest."""
    try:
        with ProcessPool(2) as pool:
            for k in range(8):
                pool.submit(_mark_after, 0.5, str(tmp_path / f"{k}.done"))
            time.sleep(0.2)  # two have started
            raise KeyboardInterrupt
    except KeyboardInterrupt:
        pass
    time.sleep(1.0)  # what a worker still alive would have finished by now
    assert list(tmp_path.iterdir()) == []


def _deaf_to_sigterm(ready) -> None:
    """A worker whose SIGTERM went astray: raised inside the fork's hooks, where Python drops
    the exception, before its initializer gave it the default action."""
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    ready.set()
    while True:
        time.sleep(1)


def test_a_process_that_outlives_its_sigterm_is_killed():
    """Python joins every child at exit: one that survived `terminate()` kept an interrupted
    search waiting at its exit forever (once in the test suite, 2026-11-27)."""
    import multiprocessing

    from wrapenv.pool import stop

    context = multiprocessing.get_context("fork")
    ready = context.Event()
    deaf = context.Process(target=_deaf_to_sigterm, args=(ready,))
    deaf.start()
    assert ready.wait(timeout=30)
    stop([deaf])
    assert not deaf.is_alive() and deaf.exitcode == -signal.SIGKILL


def _pool_then_sudden_death(pids) -> None:
    """A parent that dies without stopping its pool (SIGKILL, a crash, `os._exit`)."""
    pool = ProcessPool(1)
    pids.put(pool.submit(os.getpid).result())
    os._exit(0)


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def test_a_worker_dies_with_its_parent():
    """However its parent ends, a worker goes too: an idle one that outlived an interrupted
    search held the command's stderr open, and the test reading it waited until CI's 90 minutes
    ran out (2026-11-27). Here the parent ends by `os._exit`, stopping nothing."""
    import multiprocessing

    context = multiprocessing.get_context("fork")
    pids = context.SimpleQueue()   # written at once: the parent ends without flushing a Queue
    parent = context.Process(target=_pool_then_sudden_death, args=(pids,))
    parent.start()
    parent.join(timeout=60)
    assert parent.exitcode == 0
    worker = pids.get()
    deadline = time.monotonic() + 10
    while _alive(worker) and time.monotonic() < deadline:
        time.sleep(0.1)
    alive = _alive(worker)
    if alive:
        os.kill(worker, signal.SIGKILL)
    assert not alive


#: A pool whose worker dies while calls the caller cancelled still wait in its queue: what a
#: SIGTERM to the whole process group leaves (the workers die of it as the caller, interrupted,
#: cancels its queue).
_CANCELLED_THEN_KILLED = """
import os, signal, time
from wrapenv.pool import ProcessPool
pool = ProcessPool(1)
calls = [pool.submit(time.sleep, 3) for _ in range(8)]
time.sleep(1.0)                       # the first few run or wait in the workers' queue
assert sum(call.cancel() for call in calls) >= 4
for worker in list(pool._processes.values()):
    os.kill(worker.pid, signal.SIGKILL)
time.sleep(1.0)                       # the pool finds itself broken
pool.terminate()
print("stopped")
"""


def test_a_pool_broken_with_cancelled_calls_queued_prints_no_traceback():
    """Python 3.11's pool set its error on the cancelled calls too, and its thread died of that
    with a traceback on stderr (gh-107219, ignored since 3.12): `wrapbench train` stopped by a
    SIGTERM to its process group printed one on 3 runs of 4 (2026-12-01)."""
    import subprocess
    import sys

    run = subprocess.run([sys.executable, "-c", _CANCELLED_THEN_KILLED], capture_output=True,
                         text=True, timeout=60)
    assert (run.returncode, run.stdout, run.stderr) == (0, "stopped\n", "")
