"""Where a PPO training episode's CPU goes: Bullet's steps, the wrap model, the state reads,
building the world, and the rest of the loop.

One env as `wrapbench train` builds it (`wrapenv/WrapBenchRandom-v3`, target level only, at
`TrainSettings.sim`), seeded random units, actions uniformly random or sampled from a trained
policy (`--policy RUN/policy.zip`) as its rollouts sample them. Each part is timed with
`time.process_time` around the public call that does it; with both cores busy (a training
run) every figure is a little higher.

    python -m benchmarks.bench_episode [--episodes 60] [--policy FILE] [--seed 11]
"""

from __future__ import annotations

import argparse
import time
from collections import defaultdict
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any
from unittest import mock

import gymnasium as gym
import numpy as np
import torch

import wrapenv  # noqa: F401  (registers the environments)
from recommender.policy import MAKE_ID, TrainSettings, env_kwargs, load_policy
from wrapenv.bench import BenchUnit
from wrapenv.bullet import BulletWorld
from wrapenv.design import N_PARAMS
from wrapenv.wrap_physics import WrapNet

#: The parts timed: name, the class and the method that does it. None overlaps another.
PARTS: list[tuple[str, type, str]] = [
    ("Bullet's steps (BulletWorld.step)", BulletWorld, "step"),
    ("wrap model (WrapNet.forces)", WrapNet, "forces"),
    ("state reads (BulletWorld.state)", BulletWorld, "state"),
    ("building the unit (BenchUnit.__init__)", BenchUnit, "__init__"),
]


@contextmanager
def timing(cpu_s: dict[str, float], calls: dict[str, int]) -> Iterator[None]:
    """Every `PARTS` method timed into `cpu_s` and counted into `calls` while inside."""
    with ExitStack() as stack:
        for name, cls, method in PARTS:
            stack.enter_context(mock.patch.object(cls, method,
                                                  _timed(getattr(cls, method), name, cpu_s,
                                                         calls)))
        yield


def _timed(function: Callable[..., Any], name: str, cpu_s: dict[str, float],
           calls: dict[str, int]) -> Callable[..., Any]:
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        t0 = time.process_time()
        try:
            return function(*args, **kwargs)
        finally:
            cpu_s[name] += time.process_time() - t0
            calls[name] += 1
    return wrapper


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--episodes", type=int, default=60)
    parser.add_argument("--policy", type=Path, help="a trained policy.zip to take actions from")
    parser.add_argument("--seed", type=int, default=11)
    args = parser.parse_args(argv)
    settings = TrainSettings()
    policy = load_policy(args.policy) if args.policy else None
    env = gym.make(MAKE_ID, **env_kwargs(settings))
    obs, _ = env.reset(seed=args.seed)
    rng = np.random.default_rng(args.seed)
    torch.manual_seed(args.seed)
    cpu_s: dict[str, float] = defaultdict(float)
    calls: dict[str, int] = defaultdict(int)
    total_s, kg = 0.0, []
    with timing(cpu_s, calls):
        for _ in range(args.episodes):
            action = (rng.uniform(-1, 1, N_PARAMS).astype(np.float32) if policy is None
                      else policy.predict(obs, deterministic=False)[0])
            t0 = time.process_time()
            *_, info = env.step(action)
            total_s += time.process_time() - t0
            kg.append(info["material_used"]["mass_kg"])
            obs, _ = env.reset()
    env.close()
    n = args.episodes
    steps = calls[PARTS[0][0]] / n
    print(f"{n} episodes, actions {'of ' + str(args.policy) if policy else 'uniformly random'}"
          f", {np.mean(kg):.3f} kg of web on average; {settings.sim.timestep_s * 1e3:.2f} ms "
          f"steps, {round(settings.sim.settle_s / settings.sim.timestep_s)} of them settling")
    print(f"CPU an episode: {total_s / n:.3f} s, {steps:.0f} Bullet steps")
    for name, _, _ in PARTS:
        print(f"  {name:42s} {cpu_s[name] / n:.3f} s  {100 * cpu_s[name] / total_s:5.1f} %")
    rest = total_s - sum(cpu_s.values())
    print(f"  {'the rest of the loop':42s} {rest / n:.3f} s  {100 * rest / total_s:5.1f} %")


if __name__ == "__main__":
    main()
