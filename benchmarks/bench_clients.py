"""A closed world's Bullet client reused, reset, against a new connection for every world,
side by side in one process (`wrapenv.bullet.MAX_IDLE_CLIENTS` 0 against its default).

Blocks of the same runs alternate between the two, so a machine whose speed drifts slows both
alike; both simulate the same steps bit for bit (tests/wrapenv/test_bullet.py), so the
difference is the connections alone. Two kinds of run: the small unit's levels of
`bench_memory` (a search's cheapest), and PPO training's one-step episodes (`wrapbench train`'s
env and settings, seeded random actions). Prints CPU per run, median over the blocks, and what
is not Bullet's steps per second of them, which takes the machine's drift out (as
`bench_versions` does).

    taskset -c 0 python -m benchmarks.bench_clients [--blocks 8] [--runs 100] [--episodes 10]
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections.abc import Callable

os.environ.setdefault("OMP_NUM_THREADS", "1")

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
import pybullet as pb  # noqa: E402

import wrapenv  # noqa: E402, F401  (registers the environments)
from benchmarks.bench_memory import UNIT, WRAP, one_run  # noqa: E402
from recommender.policy import MAKE_ID, TrainSettings, env_kwargs  # noqa: E402
from wrapenv import bullet  # noqa: E402
from wrapenv.design import N_PARAMS  # noqa: E402
from wrapenv.load import LoadUnit  # noqa: E402
from wrapenv.wrap import WrapFormat  # noqa: E402

ARMS = {"a new client per world": 0, "a client reused": bullet.MAX_IDLE_CLIENTS}
#: CPU seconds inside pybullet's `stepSimulation`, counted by `_timed_step`
_bullet_s = [0.0]
_step = pb.stepSimulation


def _timed_step(*args: object, **kwargs: object) -> object:
    t0 = time.process_time()
    try:
        return _step(*args, **kwargs)
    finally:
        _bullet_s[0] += time.process_time() - t0


pb.stepSimulation = _timed_step


def small_runs(n: int) -> Callable[[], None]:
    layout = LoadUnit.from_dict(UNIT).layout()
    wrap = WrapFormat.from_dict(WRAP)

    def block() -> None:
        for k in range(n):
            one_run(k, layout, wrap)
    return block


def episodes(n: int) -> Callable[[], None]:
    env = gym.make(MAKE_ID, **env_kwargs(TrainSettings()))

    def block() -> None:
        env.reset(seed=11)
        rng = np.random.default_rng(11)
        for _ in range(n):
            env.step(rng.uniform(-1, 1, N_PARAMS).astype(np.float32))
            env.reset()
    return block


Blocks = dict[str, list[tuple[float, float]]]


def cpu_per_run(block: Callable[[], None], n: int, blocks: int) -> Blocks:
    """(CPU a run, CPU outside Bullet's steps per CPU second inside them) per block and arm."""
    block()  # warm-up: imports, allocator pools
    cpu: Blocks = {arm: [] for arm in ARMS}
    for _ in range(blocks):
        for arm, idle in ARMS.items():
            bullet.MAX_IDLE_CLIENTS = idle
            bullet.disconnect_idle_clients()
            t0, _bullet_s[0] = time.process_time(), 0.0
            block()
            total = time.process_time() - t0
            cpu[arm].append((total / n, (total - _bullet_s[0]) / _bullet_s[0]))
    return cpu


def report(name: str, cpu: Blocks) -> None:
    total = {arm: statistics.median(t for t, _ in values) for arm, values in cpu.items()}
    rest = {arm: statistics.median(r for _, r in values) for arm, values in cpu.items()}
    (new, reused), (new_rest, reused_rest) = total.values(), rest.values()
    print(f"{name}: " + ", ".join(f"{arm} {1e3 * s:.1f} ms" for arm, s in total.items())
          + f": {new / reused:.2f} x less CPU a run; the rest per Bullet second "
          f"{new_rest:.3f} and {reused_rest:.3f}: {(1 + new_rest) / (1 + reused_rest):.3f} x "
          "less CPU for the same steps")
    for arm, values in cpu.items():
        print(f"  {arm}, each block: " + " ".join(f"{1e3 * t:.1f}" for t, _ in values))


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--blocks", type=int, default=8)
    parser.add_argument("--runs", type=int, default=100, help="small-unit levels a block")
    parser.add_argument("--episodes", type=int, default=10, help="training episodes a block")
    args = parser.parse_args(argv)
    print(f"CPU a run, median of {args.blocks} blocks, the two alternated")
    report(f"the small unit's level ({args.runs} a block)",
           cpu_per_run(small_runs(args.runs), args.runs, args.blocks))
    report(f"a training episode ({args.episodes} a block, random actions)",
           cpu_per_run(episodes(args.episodes), args.episodes, args.blocks))


if __name__ == "__main__":
    main()
