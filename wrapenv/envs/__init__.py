"""Gymnasium environments of the virtual bench (registered by ``import wrapenv``):
``wrapenv/WrapBench-v0`` (`WrapBenchEnv`) and ``wrapenv/WrapBenchRandom-v0``
(`WrapBenchRandomEnv`)."""

from wrapenv.envs.wrapbench import OBS_NAMES, WrapBenchEnv, WrapBenchRandomEnv, reward_terms

__all__ = ["OBS_NAMES", "WrapBenchEnv", "WrapBenchRandomEnv", "reward_terms"]
