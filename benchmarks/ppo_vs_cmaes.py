"""A trained PPO policy against random actions and against the CMA-ES search.

1. Held-out random units (drawn like `WrapBenchRandom-v3` draws them, from a stream no training
   env uses), target level only: pass rate and mean material of the policy's proposals and of
   uniformly random actions.
2. `--search N`: the first N held-out units also searched with `wrapbench recommend` (CMA-ES,
   its defaults), and per unit the policy's material against the search's (issue 15's goal: the
   policy passes >= 90 % of held-out units with at most 1.5 x the material the search finds).
3. Every example load: `wrapbench recommend` with CMA-ES (its defaults) and with
   `--method ppo --policy`, run as a user runs them: exit status, material, highest EUMOS level
   passed, robust pass rate, evaluations and wall time.

    python benchmarks/ppo_vs_cmaes.py --policy RUN/policy.zip [--held-out 12] [--target 0.5]
                                      [--search N] [--only held-out|ppo|cmaes]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from recommender.policy import evaluate, held_out_loads
from recommender.text import program_summary
from wrapenv.program import Program, Reinforcement

EXAMPLES = ("examples/pet_2layer_columnar.toml", "examples/pet_3layer_columnar.toml",
            "examples/pet_3layer_interlocked.toml")


def held_out(policy: Path, n: int, target_g: float, searched: int) -> None:
    loads = held_out_loads(n, seed=0)
    proposals = []
    for name, source in (("policy", policy), ("random", None)):
        t0 = time.perf_counter()
        trials = evaluate(source, loads, "kraft", target_g, seed=0)
        wall = time.perf_counter() - t0
        passed = sum(t.passed for t in trials)
        kg = np.mean([t.material_kg for t in trials])
        print(f"held-out units ({n}), {name:6s}: passed {passed}/{n}, mean material {kg:.3f} kg, "
              f"invalid {sum(not t.valid for t in trials)}, {wall:.0f} s", flush=True)
        if source is not None:
            proposals = trials
    for k, (load, trial) in enumerate(zip(loads[:searched], proposals, strict=False)):
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "load.toml"
            path.write_text(load.to_toml())
            searched_kg, result = search_material(str(path), target_g)
        ratio = f"{trial.material_kg / searched_kg:.2f} x" if searched_kg else "-"
        print(f"held-out unit {k} ({load.stack.layers} layers, {load.stack.pattern}): policy "
              f"{'pass' if trial.passed else 'FAIL'} {trial.material_kg:.3f} kg; search "
              f"{result}; policy / search {ratio}", flush=True)


def run_recommend(load: str, method: list[str], target_g: float) -> tuple[dict | None, str]:
    """`wrapbench recommend` run as a user runs it: its JSON (None when it found no passing
    program) and, if none, why, with the wall time."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out.json"
        t0 = time.perf_counter()
        code = subprocess.run(["wrapbench", "recommend", load, "--target", str(target_g),
                               "--json", str(out), *method], cwd=tmp,
                              stdout=subprocess.DEVNULL).returncode
        wall = time.perf_counter() - t0
        if code != 0 or not out.exists():
            return None, f"exit {code}, no passing program, {wall:.0f} s"
        return json.loads(out.read_text()), f"{wall:.0f} s"


def search_material(load: str, target_g: float) -> tuple[float | None, str]:
    """The CMA-ES search's material for a load (None when it found no passing program)."""
    r, said = run_recommend(load, [], target_g)
    if r is None:
        return None, said
    kg = float(r["material_used"]["mass_kg"])
    return kg, f"{kg:.3f} kg, {said}"


def recommend(load: str, method: list[str], target_g: float) -> str:
    r, said = run_recommend(load, method, target_g)
    if r is None:
        return said
    program = program_summary(Program(**{
        k: v for k, v in r["program"].items() if k != "reinforcement"},
        reinforcements=tuple(Reinforcement(**x) for x in r["program"].get("reinforcement", []))))
    return (f"{r['material_used']['mass_kg']:.3f} kg ({program}), highest "
            f"{r['verdict']['highest_passed_g']:.1f} g, robust {r['robust_pass_rate']:.0%}, "
            f"{r['evaluations']} simulations, {said}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--policy", type=Path)
    parser.add_argument("--held-out", type=int, default=12)
    parser.add_argument("--target", type=float, default=0.5)
    parser.add_argument("--search", type=int, default=0, metavar="N",
                        help="also search the first N held-out units with CMA-ES")
    parser.add_argument("--only", choices=("held-out", "ppo", "cmaes"),
                        help="one part (the CMA-ES searches need no policy)")
    args = parser.parse_args()
    if args.policy is None and args.only != "cmaes":
        parser.error("--policy is needed unless --only cmaes")
    if args.only in (None, "held-out"):
        held_out(args.policy, args.held_out, args.target, args.search)
    methods = []
    if args.only in (None, "ppo"):
        methods.append(("ppo", ["--method", "ppo", "--policy", str(args.policy.resolve())]))
    if args.only in (None, "cmaes"):
        methods.append(("cmaes", []))
    for load in EXAMPLES:
        for name, method in methods:
            result = recommend(str(Path(load).resolve()), method, args.target)
            print(f"{Path(load).stem}, {name:5s}: {result}", flush=True)


if __name__ == "__main__":
    main()
