"""Worker processes for simulations, stopped rather than waited for when the caller is
interrupted: searches and fits queue many simulations at once, and `ProcessPoolExecutor`
leaving a `with` block by an exception runs every one of them first."""

from __future__ import annotations

import ctypes
import os
import signal
import sys
import threading
from collections.abc import Sequence
from concurrent.futures import InvalidStateError, ProcessPoolExecutor
from multiprocessing.process import BaseProcess
from types import TracebackType

#: More worker processes than this many per core only queue for the same cores.
MAX_WORKERS_PER_CORE = 4


def most_workers() -> int:
    """The most worker processes a command takes here: `MAX_WORKERS_PER_CORE` a core."""
    return MAX_WORKERS_PER_CORE * (os.cpu_count() or 1)


def _worker_signals(parent_pid: int) -> None:
    """A worker's signals: it leaves interrupts to its parent (a Ctrl-C reaches the whole
    process group), dies of SIGTERM, and dies with its parent. Forked workers inherit the CLI's
    handler, which turns SIGTERM into an exception; `ProcessPoolExecutor`'s worker loop returns
    that exception as the simulation's result and goes on to the next queued call, so
    `terminate()` did not stop it."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    _die_with(parent_pid)


#: prctl(2)'s option: a signal the kernel sends this process when the thread that forked it ends.
_PR_SET_PDEATHSIG = 1


def _die_with(parent_pid: int) -> None:
    """Killed by the kernel when its parent ends, however it ends. An idle worker outlived an
    interrupted search once in the test suite (2026-11-27), and a worker left so holds the
    command's stderr open: whoever reads it waits forever (CI's run of e24a2f0 stopped in an
    interrupt test whose only waits without a timeout were such reads, until its 90 minutes
    ran out). The parent's `stop` cannot reach a worker it never registered (a signal between
    `fork` and the pool's bookkeeping). Linux only; elsewhere `stop` is all there is. The
    signal follows the forking thread: pools are used by the thread that made them."""
    if sys.platform.startswith("linux"):
        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
    if os.getppid() != parent_pid:   # the parent ended before the request was made
        os._exit(1)


#: Seconds a terminated process has to end before it is killed.
GRACE_S = 1.0


def stop(processes: Sequence[BaseProcess]) -> None:
    """Terminate `processes`, then kill any still alive after `GRACE_S`. Python joins every
    child at exit, so one that outlives its SIGTERM keeps its parent waiting forever: once in the
    test suite (2026-11-27) an idle worker outlived an interrupted search so. The way seen then, a
    worker signalled before its initializer ran, the CLI's handlers now close
    (`recommender.cli._in_a_new_worker`); this stays the backstop for any other."""
    for process in processes:
        process.terminate()
    for process in processes:
        process.join(timeout=GRACE_S)
        if process.is_alive():
            process.kill()
            process.join()


if sys.version_info < (3, 12):
    # the pool's private thread class, imported only where the fix is needed
    from concurrent.futures.process import _ExecutorManagerThread

    _previous_excepthook = threading.excepthook

    def _quiet_cancelled_race(args: threading.ExceptHookArgs) -> None:
        """CPython 3.11's pool, broken by a dead worker, sets its error on every pending call,
        one the caller cancelled included, and its manager thread dies of that with a traceback
        on stderr (gh-107219, ignored there since 3.12). A SIGTERM to the whole process group
        (`timeout`, a batch system, `kill -- -PGID`) makes exactly that: the workers die of it
        while the interrupted caller cancels its queue. `wrapbench train` printed it on 3 of 4
        such stops (2026-12-01). Other exceptions go to the hook that was there before."""
        if (args.exc_type is InvalidStateError
                and isinstance(args.thread, _ExecutorManagerThread)):
            return
        _previous_excepthook(args)

    threading.excepthook = _quiet_cancelled_race


class ProcessPool(ProcessPoolExecutor):
    """Worker processes that are stopped, not waited for, when the caller is interrupted.

    `ProcessPoolExecutor` leaving a `with` block by an exception still waits for every queued
    simulation (minutes, and a Ctrl-C seemed to hang); here the queue is cancelled and the
    workers terminated at once, with further Ctrl-C ignored while they go.
    """

    def __init__(self, max_workers: int) -> None:
        super().__init__(max_workers=max_workers, initializer=_worker_signals,
                         initargs=(os.getpid(),))

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if exc_type is None:
            self.shutdown(wait=True)
        else:
            self.terminate()

    def terminate(self) -> None:
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            # Python 3.11 has no public way to stop the workers (3.14 adds terminate_workers)
            workers = list((self._processes or {}).values())
            # The manager thread closes its wake-up pipe as it ends; at interpreter exit Python
            # 3.11 writes to that pipe without a lock (`_python_exit`), so a thread still ending
            # then printed "OSError: Bad file descriptor" after an interrupt: it is waited for.
            # (shutdown forgets it; typeshed types the attribute as the pipe, hence getattr)
            manager: threading.Thread | None = getattr(self, "_executor_manager_thread", None)
            self.shutdown(wait=False, cancel_futures=True)
            stop(workers)
            if manager is not None:
                manager.join(timeout=5)
        finally:
            signal.signal(signal.SIGINT, previous)
