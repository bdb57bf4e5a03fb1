"""One bench level in this tree against another revision of the repository, side by side.

Extracts `--base` (any git revision) into a temporary folder and runs the same levels there and
here, each in a fresh interpreter with its own tree on the path, alternated, `--repeat` times:
CPU seconds of `run_level` alone (after a warm-up level), median, and the speed-up. With
`--episodes N`, also N of PPO training's one-step episodes (`wrapbench train`'s env and
settings, seeded uniformly random actions), CPU an episode.

    taskset -c 0 python -m benchmarks.bench_versions --base 03bae20 [--episodes 20]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
CHILD = """
import sys, time
from wrapenv.bench import run_level
from wrapenv.load import LoadUnit
from wrapenv.profile import PulseProfile
from wrapenv.wrap import WrapFormat
load = LoadUnit.from_toml(sys.argv[1])
wrap = WrapFormat.from_toml(sys.argv[2], load.load_height_m) if sys.argv[2] != "-" else None
run_level(load.layout(), PulseProfile(0.3), wrap=wrap)
t0 = time.process_time()
run_level(load.layout(), PulseProfile(float(sys.argv[3])), wrap=wrap)
print(time.process_time() - t0)
"""
EPISODES = """
import sys, time
import gymnasium as gym
import numpy as np
import wrapenv
from recommender.policy import MAKE_ID, TrainSettings, env_kwargs
from wrapenv.design import N_PARAMS
env = gym.make(MAKE_ID, **env_kwargs(TrainSettings()))
env.reset(seed=11)
rng = np.random.default_rng(11)
n = int(sys.argv[1])
cpu = 0.0
for k in range(n + 1):  # the first one warms up
    action = rng.uniform(-1, 1, N_PARAMS).astype(np.float32)
    t0 = time.process_time()
    env.step(action)
    cpu += (time.process_time() - t0) if k else 0.0
    env.reset()
env.close()
print(cpu / n)
"""
CASES = [  # (load, wrap or "-", level g)
    ("examples/pet_3layer_columnar.toml", "examples/wrap_kraft_3layer.toml", "0.5"),
    ("examples/pet_3layer_columnar.toml", "examples/wrap_lldpe_3layer.toml", "0.5"),
    ("examples/pet_3layer_columnar.toml", "-", "0.5"),
    ("examples/pet_2layer_columnar.toml", "-", "0.3"),
]


def child_cpu_s(tree: Path, code: str, *args: str) -> float:
    """What `code` prints last, run in a fresh interpreter with `tree` first on the path."""
    env = {**os.environ, "PYTHONPATH": str(tree), "OMP_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-c", code, *args], cwd=tree, env=env,
                          capture_output=True, text=True, check=True)
    return float(done.stdout.split()[-1])


def side_by_side(trees: dict[str, Path], repeat: int, code: str, *args: str
                 ) -> tuple[float, float]:
    """Median CPU seconds in the two trees, runs alternated."""
    times: dict[str, list[float]] = {name: [] for name in trees}
    for _ in range(repeat):
        for name, tree in trees.items():
            times[name].append(child_cpu_s(tree, code, *args))
    before, after = (statistics.median(t) for t in times.values())
    return before, after


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--base", required=True, help="the git revision to compare with")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--episodes", type=int, default=0,
                        help="also time this many PPO training episodes (0: none)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as folder:
        archive = subprocess.run(["git", "-C", str(REPO), "archive", args.base],
                                 capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", folder], input=archive, check=True)
        trees = {args.base: Path(folder), "this tree": REPO}
        print(f"CPU s of one level, median of {args.repeat}, each run a fresh interpreter")
        for case in CASES:
            before, after = side_by_side(trees, args.repeat, CHILD, *case)
            wrap = Path(case[1]).stem if case[1] != "-" else "unwrapped"
            print(f"  {Path(case[0]).stem:22s} {wrap:18s} {case[2]} g: {args.base} "
                  f"{before:.2f} s, this tree {after:.2f} s: {before / after:.2f} x", flush=True)
        if args.episodes:
            before, after = side_by_side(trees, args.repeat, EPISODES, str(args.episodes))
            print(f"  a training episode (of {args.episodes}, random actions): {args.base} "
                  f"{before:.3f} s, this tree {after:.3f} s: {before / after:.2f} x")


if __name__ == "__main__":
    main()
