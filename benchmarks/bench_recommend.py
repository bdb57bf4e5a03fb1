"""Wall time of `wrapbench recommend` on the bundled example, and the speed-up of 2 workers over 1.

1. The same search (seed 0, 16 candidates x 3 samples, identical candidates whatever the number
   of workers) with 1 and with 2 worker processes: wall time and ratio.
2. The README's main job as a user runs it: `wrapbench recommend` with its defaults.

    python benchmarks/bench_recommend.py
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

from recommender.search import Problem, RobustSearch, SearchSettings
from wrapenv.load import LoadUnit

EXAMPLE = "examples/pet_2layer_columnar.toml"


def search_wall(workers: int) -> tuple[float, float]:
    settings = SearchSettings(samples=3, popsize=8, max_candidates=16, patience=99,
                              workers=workers)
    problem = Problem.build(LoadUnit.from_toml(EXAMPLE), settings)
    search = RobustSearch(problem)
    t0 = time.perf_counter()
    state = search.run(search.start())
    best = state.best(settings.margin_goal)
    return time.perf_counter() - t0, best.mass_kg if best else float("nan")


def main() -> None:
    walls = {}
    for workers in (1, 2):
        walls[workers], mass = search_wall(workers)
        print(f"search, 16 candidates x 3 samples, {workers} worker(s): {walls[workers]:.1f} s "
              f"(best {mass:.3f} kg)", flush=True)
    print(f"speed-up of 2 workers over 1: {walls[1] / walls[2]:.2f}x (goal >= 1.7x)")
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        done = subprocess.run(
            [sys.executable, "-m", "recommender.cli", "recommend",
             "--checkpoint", str(Path(tmp) / "s.ckpt"), "--json", str(Path(tmp) / "r.json")],
            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        wall = time.perf_counter() - t0
    print(f"wrapbench recommend (defaults, bundled example): {wall:.0f} s, exit "
          f"{done.returncode} (goal < 300 s); its output:\n{done.stdout}")


if __name__ == "__main__":
    main()
