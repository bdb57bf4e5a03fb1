"""Where a search's simulations run: worker processes on this machine, or a Ray cluster.

Both backends are `concurrent.futures.Executor`s, so the search submits the same picklable calls
and reads the same futures whichever one runs them; results do not depend on the backend (each
simulation is seeded by its arguments alone). Ray is an optional extra (`pip install .[ray]`):
it is imported only when asked for.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Executor, Future
from typing import Any

from wrapenv.config import InputError
from wrapenv.pool import ProcessPool

BACKENDS = ("process", "ray")
#: Object store of a Ray instance started here: the calls carry a load unit and a wrap format,
#: kilobytes, so Ray's default (30 % of RAM in /dev/shm, often small in containers) is not needed.
RAY_OBJECT_STORE_BYTES = 100 * 1024**2


class RayExecutor(Executor):
    """Runs submitted calls as Ray tasks. With `address=None` it starts a local Ray instance of
    `workers` CPUs and stops it on shutdown; with an address ("auto", "ray://host:10001") it
    joins that cluster, whose nodes need wrapbench installed, and leaves it running."""

    def __init__(self, workers: int, address: str | None = None) -> None:
        try:
            import ray
        except ImportError:
            raise InputError("arguments", "--backend",
                             "Ray is not installed (pip install .[ray])") from None
        self._ray = ray
        self._remote: dict[Callable, Any] = {}
        self._pending: dict[Future, Any] = {}   # a call's future -> its Ray object ref
        self._owns_instance = not ray.is_initialized() and address is None
        if not ray.is_initialized():
            options: dict[str, Any] = {"address": address, "include_dashboard": False,
                                       "log_to_driver": False, "logging_level": "ERROR"}
            if address is None:
                options.update(num_cpus=workers, object_store_memory=RAY_OBJECT_STORE_BYTES)
            try:
                ray.init(**options)
            except (ConnectionError, RuntimeError, ValueError, ImportError) as exc:
                # ray:// needs the client extra (pip install "ray[client]"); a wrong address
                # fails to connect: either way one line, not Ray's traceback
                reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc)
                raise InputError("arguments", "--ray-address",
                                 f"cannot join {address!r} ({reason})") from None

    def submit(self, fn: Callable, /, *args: Any, **kwargs: Any) -> Future:
        if fn not in self._remote:
            self._remote[fn] = self._ray.remote(fn)
        ref = self._remote[fn].remote(*args, **kwargs)
        future = ref.future()
        self._pending[future] = ref
        future.add_done_callback(lambda done: self._pending.pop(done, None))
        return future

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        """Stops the Ray instance this executor started; on a cluster it joined, which runs on,
        `cancel_futures` cancels the calls not yet done (a search stopped early would leave
        them simulating for nobody). A running call's worker is killed (`force`): Ray's
        interrupt may leave a call running (ray-project/ray#32954), as the test's sleeping call
        was once, in a fresh clone's test run (2026-12-04)."""
        if cancel_futures and self._ray.is_initialized():
            for ref in list(self._pending.values()):
                self._ray.cancel(ref, force=True)
        self._pending.clear()
        if self._owns_instance and self._ray.is_initialized():
            self._ray.shutdown()
        self._owns_instance = False


def stop(pool: Executor) -> None:
    """Stop `pool`'s simulations once their results are no longer wanted: worker processes
    are killed (`ProcessPoolExecutor` hands them up to twice their number of calls ahead,
    which waiting would run); any other executor is shut down, its calls not yet done
    cancelled."""
    if isinstance(pool, ProcessPool):
        pool.terminate()
    else:
        pool.shutdown(wait=True, cancel_futures=True)


def executor(backend: str, workers: int, address: str | None = None) -> Executor:
    """An executor of `workers` parallel simulations on the named backend."""
    if backend == "process":
        return ProcessPool(workers)
    if backend == "ray":
        return RayExecutor(workers, address)
    raise InputError("arguments", "--backend",
                     f"unknown backend {backend!r} (one of {', '.join(BACKENDS)})")
