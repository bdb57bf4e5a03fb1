"""Invalid episodes in PPO training, and the runs the bench made again to avoid them.

Episodes as an untrained policy plays them: `wrapbench train`'s environment
(`wrapenv/WrapBenchRandom-v3` at `TrainSettings.sim`: a 1/160 s step, 50 solver iterations
for a wrapped unit), a random unit per seed, and an action drawn N(0, 1) per parameter and
clipped to [-1, 1], as PPO's first rollouts draw it (seed s: `numpy.random.default_rng(s)`).
Prints how many episodes ended invalid and why, and how many runs `run_levels` made again
with more solver iterations (`wrapenv.bench.unconverged`) and how those ended.

    python -m benchmarks.training_invalid [--material kraft] [--episodes 2000] [--first 0]
        [--minutes 45] [--workers 2] [--seeds 1382,2034] [--log FILE.jsonl]

`--seeds` plays only those seeds; `--log` appends every invalid or rerun episode as a JSON line
(seed, action, reason, reruns) to replay it.
"""

from __future__ import annotations

import argparse
import json
import time
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager
from multiprocessing import Pool
from typing import Any
from unittest import mock

import gymnasium as gym
import numpy as np

import wrapenv  # noqa: F401  (registers the environments)
from recommender.policy import MAKE_ID, TrainSettings, env_kwargs
from wrapenv import bench
from wrapenv.envs import wrapbench


@contextmanager
def heard_runs(runs: list[bench.BenchRun]) -> Iterator[None]:
    """Every `BenchRun` the environment gets from `run_levels`, kept in `runs`."""
    real = bench.run_levels

    def keeping(*args: Any, **kwargs: Any) -> bench.BenchRun:
        run = real(*args, **kwargs)
        runs.append(run)
        return run

    with mock.patch.object(wrapbench, "run_levels", keeping):
        yield


def episode(env: gym.Env, seed: int) -> dict[str, Any]:
    """One episode of `seed`: its action, whether it was valid and why not, its reruns."""
    env.reset(seed=seed)
    action = np.clip(np.random.default_rng(seed).normal(0.0, 1.0, env.action_space.shape),
                     -1.0, 1.0).astype(np.float32)
    runs: list[bench.BenchRun] = []
    with heard_runs(runs):
        _, _, _, _, info = env.step(action)
    reasons = [level["invalid_reason"] for level in info["verdict"]["levels"]
               if level.get("invalid_reason")]
    return {"seed": seed, "action": action.tolist(), "valid": bool(info["valid"]),
            "passed": bool(info["passed"]), "reason": reasons[0] if reasons else "",
            "reruns": [list(map(list, run.unsolved_at)) for run in runs if run.unsolved_at],
            "iterations": [run.solver_iterations for run in runs]}


def work(job: tuple[str, list[int], float]) -> list[dict[str, Any]]:
    material, seeds, minutes = job
    env = gym.make(MAKE_ID, **env_kwargs(TrainSettings(material=material)))
    start, played = time.monotonic(), []
    try:
        for seed in seeds:
            if time.monotonic() - start > minutes * 60:
                break
            played.append(episode(env, seed))
    finally:
        env.close()
    return played


def kind(reason: str) -> str:
    """An invalid reason without its figures ("bodies interpenetrate by 53 mm ..." -> "bodies
    interpenetrate by N mm ...")."""
    return " ".join("N" if word.replace(".", "").isdigit() else word for word in reason.split())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--material", default="kraft", choices=("kraft", "lldpe"))
    parser.add_argument("--episodes", type=int, default=2000)
    parser.add_argument("--first", type=int, default=0, help="the first seed")
    parser.add_argument("--minutes", type=float, default=45.0, help="stop each worker after")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--seeds", default="", help="comma-separated seeds to play instead")
    parser.add_argument("--log", default="", help="append invalid or rerun episodes here")
    args = parser.parse_args()
    seeds = ([int(s) for s in args.seeds.split(",")] if args.seeds
             else list(range(args.first, args.first + args.episodes)))
    jobs = [(args.material, seeds[w::args.workers], args.minutes) for w in range(args.workers)]
    start = time.monotonic()
    with Pool(args.workers) as pool:
        played = sorted((e for part in pool.map(work, jobs) for e in part),
                        key=lambda e: e["seed"])
    invalid = [e for e in played if not e["valid"]]
    rerun = [e for e in played if e["reruns"]]
    print(f"{args.material}: {len(played)} episodes (seeds {played[0]['seed']}-"
          f"{played[-1]['seed']}) in {time.monotonic() - start:.0f} s on {args.workers} workers")
    print(f"invalid: {len(invalid)} ({100 * len(invalid) / len(played):.3f} %)")
    for reason, n in Counter(kind(e["reason"]) for e in invalid).most_common():
        print(f"  {n:5d}  {reason}")
    print(f"made again with more solver iterations: {len(rerun)} episodes")
    whys = Counter(" then ".join(f"{it}: {why}" for it, why in e["reruns"][0]) for e in rerun)
    for why, n in whys.most_common():
        print(f"  {n:5d}  {why}")
    ended = Counter(("valid" if e["valid"] else "invalid") + (", passed" if e["passed"] else "")
                    for e in rerun)
    if rerun:
        print("  ended: " + ", ".join(f"{n} {end}" for end, n in ended.most_common()))
    if args.log:
        with open(args.log, "a", encoding="utf-8") as log:
            for e in played:
                if not e["valid"] or e["reruns"]:
                    log.write(json.dumps(e) + "\n")


if __name__ == "__main__":
    main()
