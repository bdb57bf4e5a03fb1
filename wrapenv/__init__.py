"""Virtual EUMOS 40509 acceleration bench for pallet loads wrapped in stretch paper or film."""

import gymnasium as _gym

#: The one place the version is written (pyproject.toml reads it): reports and JSON carry it, so
#: a verdict can be traced to the bench that gave it.
__version__ = "0.1.0"

#: The Gymnasium ids this package registers (entry points are imported only by `gym.make`).
ENV_IDS = {
    "wrapenv/WrapBench-v3": "wrapenv.envs:WrapBenchEnv",
    "wrapenv/WrapBenchRandom-v3": "wrapenv.envs:WrapBenchRandomEnv",
}

for _id, _entry_point in ENV_IDS.items():
    # One-step episodes end by `terminated`; no time limit, so `truncated` stays False.
    if _id not in _gym.registry:  # a re-import (importlib.reload) must not warn
        _gym.register(id=_id, entry_point=_entry_point)
