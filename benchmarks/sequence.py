"""The bundled examples through the EUMOS sequence as a lab runs it (one unit, each level from
where the last left it) and on a fresh unit per level, side by side.

Per level: the permanent displacement since the unit was put on the sled (what the 5 % criterion
judges), the largest shift of a layer on the one below, both in mm, and P(ass) or F(ail); the
sequence stops at the first failure, as `wrapbench simulate --eumos` does. The last columns give
the highest level passed and each sequence's wall time (disturbed by whatever else runs; the
ratio of the two, measured side by side, less so).

    nice -n 10 python -m benchmarks.sequence [--target G]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from wrapenv.bench import run_levels
from wrapenv.eumos import Verdict
from wrapenv.load import LoadUnit
from wrapenv.profile import eumos_levels
from wrapenv.wrap import WrapFormat

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
#: (load, wrap or None): every bundled load unwrapped, and wrapped by its example wraps.
CASES = (
    ("pet_2layer_columnar", None),
    ("pet_2layer_columnar", "wrap_kraft_2layer"),
    ("pet_2layer_columnar", "wrap_lldpe_2layer"),
    ("pet_3layer_columnar", None),
    ("pet_3layer_columnar", "wrap_kraft_3layer"),
    ("pet_3layer_columnar", "wrap_lldpe_3layer"),
    ("pet_3layer_interlocked", None),
)


def _cells(verdict: Verdict, levels: list[float]) -> list[str]:
    by_level = {v.level_g: v for v in verdict.levels}
    out = []
    for g in levels:
        v = by_level.get(round(g, 4))
        if v is None:
            out.append("")
            continue
        total, shift = v.permanent_total_max_m, v.layer_shift_max_m
        figures = ("n/a" if total is None or shift is None
                   else f"{1000 * total:.1f}/{1000 * shift:.1f}")
        out.append(f"{figures} {'P' if v.passed else ('I' if not v.valid else 'F')}")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--target", type=float, default=0.5)
    args = parser.parse_args()
    levels = eumos_levels(args.target)
    head = (f"{'load + wrap':42} {'sequence':10} "
            + " ".join(f"{f'{g:.1f} g':>13}" for g in levels) + "  highest   time s")
    print("per level: permanent since put on / layer shift, mm; P pass, F fail, I invalid")
    print(head)
    times = {"cumulative": 0.0, "fresh": 0.0}
    for load_name, wrap_name in CASES:
        load = LoadUnit.from_toml(EXAMPLES / f"{load_name}.toml")
        wrap = (WrapFormat.from_toml(EXAMPLES / f"{wrap_name}.toml", load.load_height_m)
                if wrap_name else None)
        for fresh in (False, True):
            start = time.perf_counter()
            run = run_levels(load, levels, stop_at_failure=True, wrap=wrap, fresh=fresh)
            seconds = time.perf_counter() - start
            times[run.verdict.sequence] += seconds
            best = run.verdict.highest_passed_g
            name = f"{load_name} + {wrap_name or 'unwrapped'}" if not fresh else ""
            print(f"{name:42} {run.verdict.sequence:10} "
                  + " ".join(f"{c:>13}" for c in _cells(run.verdict, levels))
                  + f"  {'none' if best is None else f'{best:.1f} g':>7}  {seconds:7.1f}")
    print(f"wall time, all cases: cumulative {times['cumulative']:.0f} s, fresh "
          f"{times['fresh']:.0f} s (ratio {times['cumulative'] / times['fresh']:.2f})")


if __name__ == "__main__":
    main()
