"""One bench level in this tree against another revision of the repository, side by side.

Extracts `--base` (any git revision) into a temporary folder and runs the same levels there and
here, each in a fresh interpreter with its own tree on the path, alternated, `--repeat` times:
CPU seconds of `run_level` alone (after a warm-up level), median, and the speed-up. With
`--episodes N`, also N of PPO training's one-step episodes (`wrapbench train`'s env and
settings, seeded uniformly random actions), CPU an episode.

A machine whose speed drifts from run to run (seen: the same level 2.3 to 3.3 s) hides a change
of a few per cent in the totals. So each run also times pybullet's `stepSimulation` and the
report gives the rest (the Python of a step, building the world) per second of it: where both
trees simulate the same steps (the same runs, bit for bit), Bullet's seconds are the same work
and that ratio is the machine's speed taken out.

    taskset -c 0 python -m benchmarks.bench_versions --base 03bae20 [--episodes 20]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
#: Times pybullet's steps into `bullet_s` (run first in every child).
TIMED_STEPS = """
import time
import pybullet as pb
bullet_s = [0.0]
_step = pb.stepSimulation
def _timed_step(*args, **kwargs):
    t0 = time.process_time()
    try:
        return _step(*args, **kwargs)
    finally:
        bullet_s[0] += time.process_time() - t0
pb.stepSimulation = _timed_step
"""
CHILD = TIMED_STEPS + """
import sys
from wrapenv.bench import run_level
from wrapenv.load import LoadUnit
from wrapenv.profile import PulseProfile
from wrapenv.wrap import WrapFormat
load = LoadUnit.from_toml(sys.argv[1])
wrap = WrapFormat.from_toml(sys.argv[2], load.load_height_m) if sys.argv[2] != "-" else None
run_level(load.layout(), PulseProfile(0.3), wrap=wrap)
t0, bullet_s[0] = time.process_time(), 0.0
run_level(load.layout(), PulseProfile(float(sys.argv[3])), wrap=wrap)
print(time.process_time() - t0, bullet_s[0])
"""
EPISODES = TIMED_STEPS + """
import sys
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
    if k == 1:
        bullet_s[0] = 0.0
    env.step(action)
    cpu += (time.process_time() - t0) if k else 0.0
    env.reset()
env.close()
print(cpu / n, bullet_s[0] / n)
"""
CASES = [  # (load, wrap or "-", level g)
    ("examples/pet_3layer_columnar.toml", "examples/wrap_kraft_3layer.toml", "0.5"),
    ("examples/pet_3layer_columnar.toml", "examples/wrap_lldpe_3layer.toml", "0.5"),
    ("examples/pet_3layer_columnar.toml", "-", "0.5"),
    ("examples/pet_2layer_columnar.toml", "-", "0.3"),
]


@dataclass(frozen=True)
class Timing:
    """Medians over the runs in one tree: CPU seconds in all, and the CPU outside Bullet's
    steps per second inside them."""

    total_s: float
    rest_per_bullet_s: float


def child_cpu_s(tree: Path, code: str, *args: str) -> tuple[float, float]:
    """The CPU seconds `code` prints (in all, in Bullet's steps), run in a fresh interpreter
    with `tree` first on the path."""
    env = {**os.environ, "PYTHONPATH": str(tree), "OMP_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-c", code, *args], cwd=tree, env=env,
                          capture_output=True, text=True, check=True)
    total, bullet = done.stdout.split()[-2:]
    return float(total), float(bullet)


def side_by_side(trees: dict[str, Path], repeat: int, code: str, *args: str
                 ) -> tuple[Timing, Timing]:
    """Medians in the two trees, runs alternated."""
    runs: dict[str, list[tuple[float, float]]] = {name: [] for name in trees}
    for _ in range(repeat):
        for name, tree in trees.items():
            runs[name].append(child_cpu_s(tree, code, *args))
    before, after = (_median(r) for r in runs.values())
    return before, after


def _median(runs: list[tuple[float, float]]) -> Timing:
    return Timing(statistics.median(t for t, _ in runs),
                  statistics.median((t - b) / b for t, b in runs))


def _line(what: str, base: str, before: Timing, after: Timing) -> str:
    return (f"  {what}: {base} {before.total_s:.3f} s, this tree {after.total_s:.3f} s: "
            f"{before.total_s / after.total_s:.2f} x; the rest per Bullet second "
            f"{before.rest_per_bullet_s:.3f} and {after.rest_per_bullet_s:.3f}: "
            f"{(1 + before.rest_per_bullet_s) / (1 + after.rest_per_bullet_s):.3f} x less CPU "
            f"for the same steps")


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
            print(_line(f"{Path(case[0]).stem} {wrap} {case[2]} g", args.base, before, after),
                  flush=True)
        if args.episodes:
            before, after = side_by_side(trees, args.repeat, EPISODES, str(args.episodes))
            print(_line(f"a training episode (of {args.episodes}, random actions)", args.base,
                        before, after))


if __name__ == "__main__":
    main()
