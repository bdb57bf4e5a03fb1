"""Worker processes for simulations, stopped rather than waited for when the caller is
interrupted: searches and fits queue many simulations at once, and `ProcessPoolExecutor`
leaving a `with` block by an exception runs every one of them first."""

from __future__ import annotations

import signal
import threading
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from multiprocessing.process import BaseProcess
from types import TracebackType


def _worker_signals() -> None:
    """A worker's signals: it leaves interrupts to its parent (a Ctrl-C reaches the whole
    process group) and dies of SIGTERM. Forked workers inherit the CLI's handler, which turns
    SIGTERM into an exception; `ProcessPoolExecutor`'s worker loop returns that exception as the
    simulation's result and goes on to the next queued call, so `terminate()` did not stop it."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


#: Seconds a terminated process has to end before it is killed.
GRACE_S = 1.0


def stop(processes: Sequence[BaseProcess]) -> None:
    """Terminate `processes`, then kill any still alive after `GRACE_S`. Python joins every
    child at exit, so one that outlives its SIGTERM keeps its parent waiting forever: once in the
    test suite (2026-11-27) an idle worker outlived an interrupted search so. One way it happens
    (seen in tests/recommender/test_cli.py's interrupted command): a worker signalled before its
    initializer ran still has its parent's SIGTERM handler, whose exception can be raised where
    Python drops it."""
    for process in processes:
        process.terminate()
    for process in processes:
        process.join(timeout=GRACE_S)
        if process.is_alive():
            process.kill()
            process.join()


class ProcessPool(ProcessPoolExecutor):
    """Worker processes that are stopped, not waited for, when the caller is interrupted.

    `ProcessPoolExecutor` leaving a `with` block by an exception still waits for every queued
    simulation (minutes, and a Ctrl-C seemed to hang); here the queue is cancelled and the
    workers terminated at once, with further Ctrl-C ignored while they go.
    """

    def __init__(self, max_workers: int) -> None:
        super().__init__(max_workers=max_workers, initializer=_worker_signals)

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
