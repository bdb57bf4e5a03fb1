"""PooledVecEnv: PPO's one-step episodes simulated by worker processes, as if in this one."""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces
from stable_baselines3.common.env_util import make_vec_env

from recommender.episodes import PooledVecEnv
from recommender.policy import MAKE_ID, TrainSettings, env_kwargs


def _random_unit_envs(workers: int) -> PooledVecEnv:
    vec = make_vec_env(MAKE_ID, n_envs=4, seed=3, vec_env_cls=PooledVecEnv,
                       vec_env_kwargs={"workers": workers}, env_kwargs=env_kwargs(TrainSettings()))
    assert isinstance(vec, PooledVecEnv)
    return vec


def test_a_step_in_the_workers_is_the_step_in_this_process():
    """The same seeds and actions give the same rewards, outcomes and next units: a training
    run does not depend on how many workers simulate it."""
    actions = np.random.default_rng(0).uniform(-1, 1, (4, 9)).astype(np.float32)
    rollouts = []
    for workers in (1, 2):
        vec = _random_unit_envs(workers)
        assert (vec.pool is None) == (workers == 1)
        try:
            first = vec.reset()
            obs, rewards, dones, infos = vec.step(actions)
        finally:
            vec.close()
        rollouts.append((first, obs, rewards, dones, infos))
    (first1, obs1, rew1, done1, info1), (first2, obs2, rew2, done2, info2) = rollouts
    np.testing.assert_array_equal(first1, first2)
    np.testing.assert_array_equal(obs1, obs2)        # the next random units
    assert not np.array_equal(obs1, first1)
    np.testing.assert_array_equal(rew1, rew2)
    assert done1.all() and done2.all()               # one-step episodes
    for a, b, seen in zip(info1, info2, first1, strict=True):
        assert a["verdict"] == b["verdict"] and a["material_used"] == b["material_used"]
        np.testing.assert_array_equal(a["terminal_observation"], seen)
        np.testing.assert_array_equal(b["terminal_observation"], seen)
        assert a["episode"]["r"] == b["episode"]["r"]   # Monitor's record, for SB3's logs


def test_no_more_workers_than_envs():
    vec = PooledVecEnv([lambda: gym.make("CartPole-v1")], workers=4)
    try:
        assert vec.pool is None
    finally:
        vec.close()


STEP_S = 3600.0


class _SlowEnv(gym.Env):
    """A step that takes `STEP_S`, and says when it started (in `folder`)."""

    observation_space = spaces.Box(-1.0, 1.0, (1,), np.float32)
    action_space = spaces.Box(-1.0, 1.0, (1,), np.float32)

    def __init__(self, folder: Path) -> None:
        self.folder = folder

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        return np.zeros(1, np.float32), {}

    def step(self, action):
        (self.folder / str(os.getpid())).touch()
        time.sleep(STEP_S)
        return np.zeros(1, np.float32), 0.0, True, False, {}


@pytest.mark.timeout(120)  # a close that waited for the hour-long step fails here
def test_closing_within_a_step_stops_the_workers_without_waiting_for_it(tmp_path):
    """An interrupt (Ctrl-C, SIGTERM) can come while the workers simulate: closing then ends
    them instead of waiting for their episodes."""
    vec = PooledVecEnv([lambda: _SlowEnv(tmp_path)] * 2, workers=2)
    vec.reset()
    vec.step_async(np.zeros((2, 1), np.float32))
    stepping = threading.Thread(target=_ignore_errors(vec.step_wait), daemon=True)
    stepping.start()
    deadline = time.monotonic() + 60
    while len(list(tmp_path.iterdir())) < 2:
        assert time.monotonic() < deadline, "the workers never started their steps"
        time.sleep(0.05)
    workers = [int(p.name) for p in tmp_path.iterdir()]
    vec.close()        # in the main thread, as the training's clean-up runs it
    for pid in workers:
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)


def _ignore_errors(call):
    def run() -> None:
        try:
            call()
        except Exception:   # the step's workers were stopped under it
            pass
    return run
