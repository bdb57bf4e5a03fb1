"""What a training run's `log.csv` says: episodes, blown-up runs, and the first against the last
window of episodes (reward, pass rate, mean material of the stochastic policy's programs).

    python -m benchmarks.train_log RUN/log.csv [--window 256]
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path


def means(rows: list[dict[str, str]], key: str) -> float:
    return sum(float(r[key]) for r in rows) / len(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("log", type=Path)
    parser.add_argument("--window", type=int, default=256)
    args = parser.parse_args()
    with args.log.open(newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        raise SystemExit(f"{args.log}: no episodes")
    blown = sum(1 for r in rows if float(r["valid"]) == 0)
    print(f"{len(rows)} episodes, {blown} blown up (rewarded as failures)")
    first, last = rows[:args.window], rows[-args.window:]
    for key, name in (("reward", "reward"), ("passed", "pass rate"),
                      ("material_kg", "mean material, kg")):
        print(f"first / last {args.window} episodes, {name}: "
              f"{means(first, key):.2f} -> {means(last, key):.2f}")


if __name__ == "__main__":
    main()
