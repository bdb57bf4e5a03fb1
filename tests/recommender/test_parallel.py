"""Where simulations run: the same search gives the same answer on worker processes and on a
local Ray instance, and a missing or unknown backend is a usage error."""

from __future__ import annotations

import builtins
import dataclasses
import time

import pytest

from recommender.cli import main
from recommender.parallel import RAY_OBJECT_STORE_BYTES, RayExecutor, executor, stop
from recommender.search import Problem, RobustSearch, SearchSettings
from tests.cli import one_line
from wrapenv.config import InputError
from wrapenv.load import LoadUnit
from wrapenv.pool import ProcessPool
from wrapenv.profile import eumos_levels

#: One bundle per layer on a stopped pallet: a bench run takes a fraction of a second.
TINY = {
    "name": "tiny",
    "pallet": {"preset": "EUR"},
    "bundle": {"preset": "PET6x1.5L"},
    "stack": {"layers": 2, "pattern": "explicit", "positions": [[0.0, 0.0]]},
    "fixture": {"pallet_stopper": True},
}
SMALL_SEARCH = SearchSettings(targets=(("long", 0.5),), samples=2, popsize=3, max_candidates=3,
                              patience=9, workers=2)


def _history(backend: str) -> list[tuple]:
    problem = Problem.build(LoadUnit.from_dict(TINY),
                            dataclasses.replace(SMALL_SEARCH, backend=backend))
    search = RobustSearch(problem)
    state = search.run(search.start())
    return [(e.vector, e.margins, e.passed, e.objective) for e in state.history]


def test_ray_backend_reproduces_the_process_backend():
    pytest.importorskip("ray")
    process = _history("process")
    assert len(process) == 3
    assert _history("ray") == process


def test_a_ray_instance_started_by_the_search_is_stopped_after_it():
    ray = pytest.importorskip("ray")
    with executor("ray", 1) as pool:
        assert pool.submit(eumos_levels, 0.4).result() == [0.2, 0.3, 0.4]
        assert ray.is_initialized()
    assert not ray.is_initialized()


def test_calls_left_on_a_joined_ray_cluster_are_cancelled_when_the_search_stops():
    """A cluster joined with --ray-address runs on after the search: a search stopped early
    (`search.holding`) cancels the calls it no longer wants, which simulated for nobody."""
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False, logging_level="ERROR",
             object_store_memory=RAY_OBJECT_STORE_BYTES)   # the cluster, running here

    def nap(seconds: float) -> float:
        time.sleep(seconds)
        return seconds

    try:
        pool = RayExecutor(1, "auto")
        # a search stops a pool that has run calls: its worker is up (a call sent to a worker
        # still starting can miss its cancel, ray-project/ray#24359)
        assert pool.submit(nap, 0.0).result(timeout=120) == 0.0
        futures = [pool.submit(nap, 120.0) for _ in range(3)]   # one runs, two wait
        stop(pool)
        assert ray.is_initialized()
        for future in futures:
            with pytest.raises(ray.exceptions.TaskCancelledError):
                future.result(timeout=60)
    finally:
        ray.shutdown()


def test_unknown_backend_is_an_input_error():
    with pytest.raises(InputError, match="--backend: unknown backend 'cluster'"):
        executor("cluster", 2)


def test_ray_backend_without_ray_installed_says_how_to_install(monkeypatch, capsys, tmp_path):
    real_import = builtins.__import__

    def no_ray(name, *args, **kwargs):
        if name == "ray":
            raise ImportError("No module named 'ray'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_ray)
    with pytest.raises(InputError, match=r"pip install \.\[ray\]"):
        RayExecutor(1)
    monkeypatch.chdir(tmp_path)
    assert main(["recommend", "--backend", "ray", "--budget", "3", "--samples", "1"]) == 2
    assert "pip install .[ray]" in one_line(capsys.readouterr().err)
    assert list(tmp_path.iterdir()) == []


def test_a_ray_address_that_cannot_be_joined_is_one_line_naming_the_flag():
    pytest.importorskip("ray")
    with pytest.raises(InputError, match="--ray-address: cannot join 'ray://127.0.0.1:1'"):
        RayExecutor(1, "ray://127.0.0.1:1")


def test_the_process_backend_is_a_pool_stopped_when_interrupted():
    with executor("process", 1) as pool:
        assert isinstance(pool, ProcessPool)
