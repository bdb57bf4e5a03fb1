"""How much the Kraft recommendation leans on the cap on tension (docs/materials.md, P4).

On Kraft, `recommend` answers the least web of its space, one bottom wrap, a spiral with no
overlap and one top wrap, at the highest tension it searches: half the paper's yield force
(800 N on a 0.5 m web), where machines are set because corners cause tension peaks. That cap is
an assumption that decides the answer. This runs that program at 20 %, 30 %, 40 % and 50 % of
the yield force on each example, both sides along the motion, 16 h after wrapping (relaxed, as
`recommend` judges), through the EUMOS sequence to 0.5 g on the nominal load: the highest level
passed, the margin at 0.5 g and the web's peak utilisation there. Prints a Markdown table.

    python -m benchmarks.tension_cap [--workers 2]
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
from multiprocessing import Pool
from typing import Any

from wrapenv.bench import run_levels
from wrapenv.design import ProgramSpace
from wrapenv.eumos import LevelVerdict, level_margin
from wrapenv.load import ORIENTATIONS, LoadUnit, Orientation
from wrapenv.profile import PulseProfile, eumos_levels
from wrapenv.program import Program
from wrapenv.wrap import WrapFormat

EXAMPLES = ("examples/pet_2layer_columnar.toml", "examples/pet_3layer_columnar.toml",
            "examples/pet_3layer_interlocked.toml")
YIELD_FRACTIONS = (0.2, 0.3, 0.4, 0.5)
TARGET_G = 0.5
HOURS_SINCE_WRAPPING = 16.0  # recommend's default (ASTM D5414's rest)


def lightest(space: ProgramSpace, tension_n: float) -> Program:
    """The least web of `space` (one bottom wrap where the space lays it, a spiral at its least
    overlap, one top wrap), every zone at `tension_n`."""
    values = space.low.copy()
    values[5:] = tension_n
    return space.program(values)


def to_target(load_path: str, load: LoadUnit, wrap: WrapFormat, orientation: Orientation,
              pulse: Callable[[float], PulseProfile] = PulseProfile
              ) -> tuple[str, LevelVerdict | None]:
    """The EUMOS sequence to `TARGET_G`, each level run as `pulse` makes it: the table's
    first cells (the load's name, then the highest level passed and the margin at the target,
    `{}` where the caller's cells go) and the target level's verdict (None if the unit failed
    before it)."""
    verdict = run_levels(load, [pulse(g) for g in eumos_levels(TARGET_G)],
                         orientation=orientation, stop_at_failure=True, wrap=wrap).verdict
    last = {round(v.level_g, 2): v for v in verdict.levels}.get(TARGET_G)
    margin = f"{level_margin(last, verdict.load_height_m):.2f}" if last else "–"
    best = verdict.highest_passed_g
    name = load_path.rsplit("/", 1)[-1].removesuffix(".toml")
    return (f"| {name} | {{}} | {'none' if best is None else f'{best:.1f} g'} | {margin} |",
            last)


def case(args: tuple[str, float, Orientation]) -> str:
    load_path, fraction, orientation = args
    load = LoadUnit.from_toml(load_path)
    space = ProgramSpace.for_layout(load.layout(), "kraft")
    tension = fraction * space.material.yield_force_n_per_m * space.web_width_m
    wrap = space.laid(lightest(space, tension)).relaxed(HOURS_SINCE_WRAPPING)
    row, last = to_target(load_path, load, wrap, orientation)
    peak = f"{last.wrap.peak_utilisation:.2f}" if last and last.wrap else "–"
    return row.format(f"{fraction:.0%} ({tension:.0f} N) | {orientation}") + f" {peak} |"


def print_table(columns: Sequence[str], case: Callable[[Any], str], cases: Sequence[Any],
                description: str) -> None:
    """The benchmarks' command line (`--workers`) and table: a Markdown row per case, run on
    a pool of workers, printed in order as they come."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    print("| " + " | ".join(columns) + " |")
    print("|" + "---|" * len(columns))
    with Pool(args.workers) as pool:
        for line in pool.imap(case, cases):
            print(line, flush=True)


def main() -> None:
    cases = [(load, f, o) for load in EXAMPLES for f in YIELD_FRACTIONS for o in ORIENTATIONS]
    print_table(("load", "tension (of yield force)", "side along the motion",
                 f"highest passed (to {TARGET_G} g)", f"margin at {TARGET_G} g",
                 "peak utilisation"), case, cases, __doc__.splitlines()[0])


if __name__ == "__main__":
    main()
