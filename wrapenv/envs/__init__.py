"""Gymnasium environments of the virtual bench (registered by ``import wrapenv``):
``wrapenv/WrapBench-v3`` (`WrapBenchEnv`) and ``wrapenv/WrapBenchRandom-v3``
(`WrapBenchRandomEnv`); what they observe is `wrapenv.envs.observation`."""

from wrapenv.envs.observation import OBS_NAMES
from wrapenv.envs.wrapbench import WrapBenchEnv, WrapBenchRandomEnv, reward_terms

__all__ = ["OBS_NAMES", "WrapBenchEnv", "WrapBenchRandomEnv", "reward_terms"]
