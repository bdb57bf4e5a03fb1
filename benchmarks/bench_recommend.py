"""`wrapbench recommend` on the bundled example: this tree against another revision, side by side.

1. The README's main job as a user runs it (`recommend` with its defaults, 2 workers), in this
   tree and in `--base` (any git revision, extracted into a temporary folder), alternated,
   each a fresh interpreter with its own tree on the path: wall time, CPU time of the whole
   process tree (the workers included: on a busy machine the fairer figure), simulations, and
   the answer (program, kg of web, pass probability).
   With `--held-out K` the unit is the K-th of the held-out random units (`held_out_loads`,
   seed 0, as `ppo_vs_cmaes.py` numbers them) instead, and `--material` the wrap's material.
2. With `--scaling`: the same search (seed 0, 16 candidates x 3 samples, identical candidates
   whatever the number of workers) with 1 and with 2 worker processes: wall time and ratio.

    python -m benchmarks.bench_recommend [--base main] [--repeat 1] [--scaling]
        [--held-out K] [--material lldpe]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
EXAMPLE = "examples/pet_2layer_columnar.toml"


def recommend(tree: Path, workers: int, unit: list[str]) -> dict[str, Any]:
    """One `recommend` run with its defaults in `tree` (`unit`: a load file and a material, or
    nothing for the bundled example): times, exit status and its answer."""
    env = {**os.environ, "PYTHONPATH": str(tree), "OMP_NUM_THREADS": "1"}
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "r.json"
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        done = subprocess.run([sys.executable, "-m", "recommender.cli", "recommend", *unit,
                               "--workers", str(workers), "--json", str(out)], cwd=tree, env=env,
                              stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        result = json.loads(out.read_text()) if out.exists() else {}
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"wall_s": wall, "cpu_s": cpu, "exit": done.returncode, **_answer(result)}


def _answer(result: dict[str, Any]) -> dict[str, Any]:
    if not result:
        return {"answer": "no answer"}
    p = result["pass_probability"]
    return {"answer": f"{json.dumps(result['program'], sort_keys=True)}, "
                      f"{result['material_used']['mass_kg']:.3f} kg, pass probability "
                      f"{p['passed']}/{p['samples']}, search margin {result['search_margin']:.2f}",
            "simulations": result["evaluations"]}


def held_out_unit(k: int, material: str, folder: Path) -> list[str]:
    """`recommend`'s arguments for the k-th held-out random unit, written into `folder`."""
    from recommender.policy import held_out_loads

    path = folder / f"held_out_{k}.toml"
    path.write_text(held_out_loads(k + 1, seed=0)[k].to_toml())
    return [str(path), "--material", material]


def compare(base: str, repeat: int, workers: int, held_out: int | None, material: str) -> None:
    with tempfile.TemporaryDirectory() as folder:
        unit = [] if held_out is None else held_out_unit(held_out, material, Path(folder))
        trees = {base: Path(folder) / "base", "this tree": REPO}
        trees[base].mkdir()
        archive = subprocess.run(["git", "-C", str(REPO), "archive", base],
                                 capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(trees[base])], input=archive, check=True)
        runs: dict[str, list[dict[str, Any]]] = {name: [] for name in trees}
        for _ in range(repeat):
            for name, tree in trees.items():
                run = recommend(tree, workers, unit)
                runs[name].append(run)
                print(f"  {name:10s} wall {run['wall_s']:6.1f} s, CPU {run['cpu_s']:6.1f} s, "
                      f"exit {run['exit']}, {run.get('simulations')} simulations: "
                      f"{run['answer']}", flush=True)
    walls = {name: min(float(r["wall_s"]) for r in rs) for name, rs in runs.items()}
    cpus = {name: min(float(r["cpu_s"]) for r in rs) for name, rs in runs.items()}
    print(f"recommend, {workers} workers (best of {repeat}): {base} {walls[base]:.0f} s wall / "
          f"{cpus[base]:.0f} s CPU, this tree {walls['this tree']:.0f} s / "
          f"{cpus['this tree']:.0f} s: {walls[base] / walls['this tree']:.2f} x wall, "
          f"{cpus[base] / cpus['this tree']:.2f} x CPU (goal <= 60 s wall on 2 cores)")


def scaling() -> None:
    from recommender.search import Problem, RobustSearch, SearchSettings
    from wrapenv.load import LoadUnit

    walls = {}
    for workers in (1, 2):
        settings = SearchSettings(samples=3, popsize=8, max_candidates=16, patience=99,
                                  workers=workers)
        search = RobustSearch(Problem.build(LoadUnit.from_toml(REPO / EXAMPLE), settings))
        t0 = time.perf_counter()
        best = search.run(search.start()).best(settings.margin_goal)
        walls[workers] = time.perf_counter() - t0
        print(f"search, 16 candidates x 3 samples, {workers} worker(s): {walls[workers]:.1f} s "
              f"(best {best.mass_kg if best else float('nan'):.3f} kg)", flush=True)
    print(f"speed-up of 2 workers over 1: {walls[1] / walls[2]:.2f}x (goal >= 1.7x)")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--base", default="main", help="the git revision to compare with")
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--scaling", action="store_true", help="also 1 against 2 workers")
    parser.add_argument("--held-out", type=int, help="the k-th held-out random unit instead")
    parser.add_argument("--material", default="kraft", help="with --held-out")
    args = parser.parse_args(argv)
    compare(args.base, args.repeat, args.workers, args.held_out, args.material)
    if args.scaling:
        scaling()


if __name__ == "__main__":
    main()
