"""One bench level in this tree against another revision of the repository, side by side.

Extracts `--base` (any git revision) into a temporary folder and runs the same levels there and
here, each in a fresh interpreter with its own tree on the path, alternated, `--repeat` times:
CPU seconds of `run_level` alone (after a warm-up level), median, and the speed-up.

    taskset -c 0 python -m benchmarks.bench_versions --base 03bae20
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
CASES = [  # (load, wrap or "-", level g)
    ("examples/pet_3layer_columnar.toml", "examples/wrap_kraft_3layer.toml", "0.5"),
    ("examples/pet_3layer_columnar.toml", "examples/wrap_lldpe_3layer.toml", "0.5"),
    ("examples/pet_3layer_columnar.toml", "-", "0.5"),
    ("examples/pet_2layer_columnar.toml", "-", "0.3"),
]


def level_cpu_s(tree: Path, case: tuple[str, str, str]) -> float:
    env = {**os.environ, "PYTHONPATH": str(tree), "OMP_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-c", CHILD, *case], cwd=tree, env=env,
                          capture_output=True, text=True, check=True)
    return float(done.stdout.split()[-1])


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--base", required=True, help="the git revision to compare with")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as folder:
        archive = subprocess.run(["git", "-C", str(REPO), "archive", args.base],
                                 capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", folder], input=archive, check=True)
        trees = {args.base: Path(folder), "this tree": REPO}
        print(f"CPU s of one level, median of {args.repeat}, each run a fresh interpreter")
        for case in CASES:
            times: dict[str, list[float]] = {name: [] for name in trees}
            for _ in range(args.repeat):
                for name, tree in trees.items():
                    times[name].append(level_cpu_s(tree, case))
            before, after = (statistics.median(t) for t in times.values())
            wrap = Path(case[1]).stem if case[1] != "-" else "unwrapped"
            print(f"  {Path(case[0]).stem:22s} {wrap:18s} {case[2]} g: {args.base} "
                  f"{before:.2f} s, this tree {after:.2f} s: {before / after:.2f} x", flush=True)


if __name__ == "__main__":
    main()
