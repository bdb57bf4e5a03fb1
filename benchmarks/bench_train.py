"""PPO training throughput: episodes per second of the training envs, settings side by side.

The vector env `wrapbench train` builds (`wrapenv/WrapBenchRandom-v3`, target level only, a new
random unit every one-step episode) stepped with uniformly random actions, as PPO's rollouts
step it (the policy's forward pass and its update take well under 1 % of a rollout here).
Both settings of a vector env see the same units and actions (seeded); the configurations are
alternated in rounds so a busy machine disturbs each alike:

- the bench's default settings (`SimSettings()`, before issue 15) and the training settings
  (`TrainSettings.sim`: `SimSettings.training()`), and how far the latter's verdicts and
  margins stand from the former's on the same episodes;
- the training settings with rigid boxes (`SimSettings.rigid_boxes`);
- `DummyVecEnv` (1 env, in this process) and `SubprocVecEnv` with 2 and 4 env processes (a
  vector step waits for its slowest env; more envs than cores let the others use the wait);
- with `--pooled`, what `wrapbench train` runs since 2026-11-28: `PooledVecEnv`, a rollout of
  `TrainSettings.n_envs` one-step episodes handed to one worker per core as each comes free
  (`--episodes` then a multiple of it).

`--policy RUN/policy.zip` takes the actions from a trained policy, sampled as its own training
rollouts sample them, instead of uniformly at random: the programs a training run simulates
once it has learned (lighter ones, whose layers slide longer).

    python -m benchmarks.bench_train [--episodes 32] [--rounds 2] [--envs 1 2 4 8] [--pooled]
                                     [--settings default training rigid] [--policy FILE]
"""

from __future__ import annotations

import argparse
import os
import resource
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

from recommender.episodes import PooledVecEnv
from recommender.policy import MAKE_ID, TrainSettings, env_kwargs, load_policy
from wrapenv.bench import SimSettings
from wrapenv.design import N_PARAMS

#: The settings compared, by their command-line key; the first one run is the reference.
SETTINGS = {"default": ("default SimSettings()", SimSettings()),
            "training": ("TrainSettings.sim", TrainSettings().sim),
            "rigid": ("the same, rigid boxes", replace(TrainSettings().sim, rigid_boxes=True))}


#: A vector env to measure: its name, its class, its envs, and the workers of a pooled one.
VecConfig = tuple[str, type[DummyVecEnv] | type[SubprocVecEnv], int, dict[str, Any]]


def vec_configs(envs: list[int], pooled: bool) -> list[VecConfig]:
    """`make_vec_env` with each of `envs` (in this process when 1, else one process each) and,
    if `pooled`, the vector env `wrapbench train` builds, one worker per core."""
    out: list[VecConfig] = [("DummyVecEnv x 1", DummyVecEnv, 1, {}) if n == 1 else
                            (f"SubprocVecEnv x {n}", SubprocVecEnv, n, {}) for n in envs]
    if pooled:
        workers, n_envs = os.cpu_count() or 1, TrainSettings().n_envs
        out.append((f"PooledVecEnv {n_envs}/{workers}", PooledVecEnv, n_envs,
                    {"workers": workers}))
    return out


Outcome = tuple[bool, float, bool]  # an episode's (passed, margin, valid)


def episodes_per_s(sim: SimSettings, vec_config: VecConfig, episodes: int, seed: int,
                   policy: PPO | None) -> tuple[float, float, float, list[Outcome]]:
    """Episodes per second of wall time, episodes per CPU second of the whole process tree
    (env workers included, their start-up too; Linux), the mean reward and each episode's
    outcome, over `episodes` (a multiple of the envs) with seeded random actions, or the
    `policy`'s."""
    _, cls, n_envs, vec_kwargs = vec_config
    cpu0 = _cpu_s()
    vec = make_vec_env(MAKE_ID, n_envs=n_envs, seed=seed, vec_env_cls=cls,
                       vec_env_kwargs=vec_kwargs,
                       env_kwargs=env_kwargs(TrainSettings(sim=sim)))
    rng = np.random.default_rng(seed)
    torch.manual_seed(seed)
    rewards = []
    outcomes: list[Outcome] = []
    try:
        obs = vec.reset()
        t0 = time.perf_counter()
        for _ in range(episodes // n_envs):
            actions = (rng.uniform(-1, 1, (n_envs, N_PARAMS)).astype(np.float32)
                       if policy is None
                       else policy.predict(np.asarray(obs), deterministic=False)[0])
            obs, reward, _, infos = vec.step(actions)
            rewards.extend(reward.tolist())
            outcomes.extend((bool(i["passed"]), float(i["margin"]), bool(i["valid"]))
                            for i in infos)
        wall = time.perf_counter() - t0
        workers = sum(_process_cpu_s(p.pid) for p in getattr(vec, "processes", []))
    finally:
        vec.close()
    cpu = _cpu_s() - cpu0 + workers   # a pool's workers, this process's children: once closed
    return len(rewards) / wall, len(rewards) / cpu, float(np.mean(rewards)), outcomes


def _cpu_s() -> float:
    """This process's CPU time and its ended children's."""
    return sum(u.ru_utime + u.ru_stime for u in (resource.getrusage(resource.RUSAGE_SELF),
                                                 resource.getrusage(resource.RUSAGE_CHILDREN)))


def _process_cpu_s(pid: int) -> float:
    """CPU time of an env worker (SubprocVecEnv starts them from a forkserver: they are not
    this process's children, so `getrusage` never counts them)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--episodes", type=int, default=32, help="per configuration and round")
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--envs", type=int, nargs="*", default=[1, 2, 4],
                        help="vector env sizes (default 1 2 4)")
    parser.add_argument("--pooled", action="store_true",
                        help="also the vector env `wrapbench train` builds (PooledVecEnv)")
    parser.add_argument("--settings", nargs="+", choices=list(SETTINGS), default=list(SETTINGS),
                        help="the first is the reference of the ratios and agreements")
    parser.add_argument("--policy", type=Path, help="a trained policy.zip to take actions from")
    args = parser.parse_args(argv)
    configs = vec_configs(args.envs, args.pooled)
    if any(n < 1 or args.episodes % n for _, _, n, _ in configs):
        parser.error("every vector env's envs must be >= 1 and divide --episodes")
    policy = None if args.policy is None else load_policy(args.policy, TrainSettings().material)
    torch.set_num_threads(1)   # as in training: the workers have the cores
    settings = {SETTINGS[key][0]: SETTINGS[key][1] for key in args.settings}
    print(f"{os.cpu_count()} cores; {args.episodes} episodes per configuration and round, "
          f"{args.rounds} rounds (goal >= 5 episodes/s on 2 cores); actions "
          f"{'uniformly random' if policy is None else f'sampled from {args.policy}'}")
    rates: dict[tuple[str, str], list[tuple[float, float]]] = {}
    outcomes: dict[str, list[Outcome]] = {name: [] for name in settings}
    for round_ in range(args.rounds):
        for config in configs:
            vec_name = config[0]
            for sim_name, sim in settings.items():
                wall, cpu, reward, seen = episodes_per_s(sim, config, args.episodes,
                                                         seed=round_, policy=policy)
                rates.setdefault((vec_name, sim_name), []).append((wall, cpu))
                outcomes[sim_name].extend(seen)
                print(f"  round {round_}: {vec_name:18s} {sim_name:22s} {wall:5.2f} episodes/s, "
                      f"{cpu:5.2f} per CPU s (mean reward {reward:+.3f})", flush=True)
    print("\nepisodes/s of wall time (episodes per CPU second); ratios of the wall figures to "
          "the defaults'")
    print(f"{'vector env':18s} " + " ".join(f"{name:>24s}" for name in settings) + "  ratios")
    for vec_name, *_ in configs:
        mean = [np.mean(rates[vec_name, sim_name], axis=0) for sim_name in settings]
        print(f"{vec_name:18s} " + " ".join(f"{w:11.2f} ({c:.2f} /CPU s)" for w, c in mean)
              + "  " + ", ".join(f"{m[0] / mean[0][0]:.2f} x" for m in mean[1:]))
    default, *cheaper = outcomes.items()
    for name, seen in cheaper:
        agreement(default[1], seen, name)


def agreement(default: list[Outcome], cheaper: list[Outcome], name: str) -> None:
    """How far a cheaper setting's rewards stand from the defaults' on the same episodes:
    verdicts, the margin where both passed (a failure's margin is bounded once decided), and
    simulations that blew up (rewarded as failures)."""
    agree = sum(a[0] == b[0] for a, b in zip(default, cheaper, strict=True))
    error = np.array([abs(a[1] - b[1]) for a, b in zip(default, cheaper, strict=True)
                      if a[0] and b[0]])
    text = f"{error.mean():.3f} / {error.max():.3f}" if len(error) else "-"
    print(f"{name} against the defaults on the same episodes: verdicts agree "
          f"{agree} of {len(default)}, margin error where both passed (mean / max) {text}; "
          f"blown up {sum(not o[2] for o in default)} and {sum(not o[2] for o in cheaper)}")


if __name__ == "__main__":
    main()
