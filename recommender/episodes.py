"""PPO's rollouts of one-step episodes, simulated by a pool of worker processes.

An episode of `wrapenv/WrapBenchRandom-v3` is one program tested on one random unit, so a
rollout is a batch of independent simulations. SB3's `SubprocVecEnv` keeps one env per process
and steps them in lockstep: each vector step waits for its slowest episode (0.14-1.2 s of CPU
here), and two workers on two cores sat idle about a third of the time. `PooledVecEnv` makes one
vector step of the whole rollout (`n_envs` envs, one step each) and hands its episodes to the
workers one at a time, so every core stays busy until the last episode ends
(`benchmarks/bench_train.py`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env import DummyVecEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnvStepReturn

from wrapenv.pool import ProcessPool


def _step(env: gym.Env, action: np.ndarray) -> tuple[Any, ...]:
    """One env's step, in a worker, on the copy of the env that was sent to it."""
    return env.step(action)


class PooledVecEnv(DummyVecEnv):
    """`DummyVecEnv` whose steps run in `workers` processes (in this one when 1).

    The envs live in this process, which resets them and computes their observations; a step
    sends each env, as it stands, with its action to a worker, and the episode's outcome comes
    back. The copy stepped there is dropped: the envs are one-step episodes, reset after every
    step. Results come back in the envs' order, so a seed gives the same rollout.
    """

    def __init__(self, env_fns: list[Callable[[], gym.Env]], workers: int) -> None:
        super().__init__(env_fns)
        processes = min(workers, self.num_envs)
        self.pool = ProcessPool(processes) if processes > 1 else None

    def step_wait(self) -> VecEnvStepReturn:
        if self.pool is None:
            return super().step_wait()
        results = self.pool.map(_step, self.envs, self.actions)
        for i, (obs, reward, terminated, truncated, info) in enumerate(results):
            self.buf_rews[i], self.buf_infos[i] = reward, info
            self.buf_dones[i] = terminated or truncated
            info["TimeLimit.truncated"] = truncated and not terminated   # as DummyVecEnv
            if self.buf_dones[i]:
                info["terminal_observation"] = obs
                obs, self.reset_infos[i] = self.envs[i].reset()
            self._save_obs(i, obs)
        # the infos are the workers' answers, unpickled anew: no copy needed to keep them apart
        return (self._obs_from_buf(), np.copy(self.buf_rews), np.copy(self.buf_dones),
                list(self.buf_infos))

    def close(self) -> None:
        """Stop the workers without waiting for a step under way (an interrupt can come
        within one): they hold nothing but copies of the envs."""
        if self.pool is not None:
            self.pool.terminate()
            self.pool = None
        super().close()
