"""Resident memory over many bench simulations (issue 15: a 10 000-simulation search must grow
by less than 50 MB).

Runs `--runs` levels the way a search does, each in a world of its own, on a small unit (one
layer of four bundles): in turn a pass at 0.3 g, a failure at 0.9 g stopped once decided, and
every tenth run wrapped in Kraft paper (which costs most per step). Prints the resident set size
(/proc/self/statm) after a warm-up and every `--every` runs, with the growth per 1000 runs.

    python -m benchmarks.bench_memory [--runs 10000]
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

from wrapenv.bench import SimSettings, run_level  # noqa: E402
from wrapenv.eumos import evaluate  # noqa: E402
from wrapenv.load import Layout, LoadUnit  # noqa: E402
from wrapenv.profile import PulseProfile  # noqa: E402
from wrapenv.wrap import WrapFormat  # noqa: E402

GOAL_MB = 50.0
WARM_UP_RUNS = 50
UNIT = {
    "pallet": {"preset": "EUR"}, "bundle": {"preset": "PET6x1.5L"},
    "stack": {"layers": 1, "pattern": "explicit",
              "positions": [[-0.15, -0.1], [0.15, -0.1], [-0.15, 0.1], [0.15, 0.1]]},
    "fixture": {"pallet_stopper": True},
}
WRAP = {"material": "kraft", "web_width_m": 0.5,
        "band": [{"from_m": 0.0, "to_m": 0.474, "layers": 1, "tension_n": 100.0}]}
LEVELS_G = (0.3, 0.9)


def rss_mb() -> float:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def one_run(k: int, layout: Layout, wrap: WrapFormat) -> bool:
    settings = SimSettings(stop_when_decided=True)
    wrapped = wrap if k % 10 == 9 else None
    return evaluate(run_level(layout, PulseProfile(LEVELS_G[k % 2]), settings, wrapped)).passed


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=10_000)
    parser.add_argument("--every", type=int, default=1000)
    args = parser.parse_args(argv)
    layout = LoadUnit.from_dict(UNIT).layout()
    wrap = WrapFormat.from_dict(WRAP)
    for k in range(WARM_UP_RUNS):  # allocator pools, imports, Bullet's first worlds
        one_run(k, layout, wrap)
    start, t0 = rss_mb(), time.perf_counter()
    print(f"after {WARM_UP_RUNS} warm-up runs: {start:.1f} MB resident")
    print(f"{'runs':>6} {'resident MB':>11} {'growth MB':>9} {'MB per 1000':>11} {'passed':>6} "
          f"{'s/run':>6}")
    passed = 0
    for k in range(1, args.runs + 1):
        passed += one_run(k, layout, wrap)
        if k % args.every == 0 or k == args.runs:
            now = rss_mb()
            print(f"{k:6d} {now:11.1f} {now - start:9.1f} {1000 * (now - start) / k:11.2f} "
                  f"{passed:6d} {(time.perf_counter() - t0) / k:6.3f}", flush=True)
    growth = rss_mb() - start
    verdict = "met" if growth < GOAL_MB else "NOT met"
    print(f"growth over {args.runs} runs: {growth:.1f} MB (goal < {GOAL_MB:.0f} MB: {verdict})")


if __name__ == "__main__":
    main()
