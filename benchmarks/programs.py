"""The engineer's comparison: the recommended wrapping program against a machine's default.

For each example load (2-layer and 3-layer columnar, 3-layer interlocked) and each web (Kraft
paper, LLDPE film): the machine's default program (3 bottom wraps, a spiral up at 50 % overlap,
3 top wraps, every tension at half the web's yield force) and the program `wrapbench recommend`
finds for 0.5 g, each run through the EUMOS sequence up to 0.8 g (the road rule forward) as
`wrapbench simulate LOAD --wrap WRAP --target 0.8` does: web laid, cycle time, highest level
passed and the margin at 0.5 g. Prints a Markdown table.

    python -m benchmarks.programs [--budget 48] [--workers 2] [--loads LOAD.toml ...]
                                  [--materials kraft lldpe]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from recommender.text import program_summary
from wrapenv.bench import run_levels
from wrapenv.design import ProgramSpace
from wrapenv.eumos import level_margin
from wrapenv.load import LoadUnit
from wrapenv.material import MATERIALS as CARDS
from wrapenv.profile import eumos_levels
from wrapenv.wrap import WrapFormat

EXAMPLES = ("examples/pet_2layer_columnar.toml", "examples/pet_3layer_columnar.toml",
            "examples/pet_3layer_interlocked.toml")
MATERIALS = ("kraft", "lldpe")
ROAD_RULE_G = 0.8


def recommended(load: str, material: str, budget: int,
                workers: int) -> tuple[WrapFormat | None, float]:
    """The program `wrapbench recommend` writes (--wrap-out), and its wall time; None when it
    found none that passes (exit status 1)."""
    with tempfile.TemporaryDirectory() as tmp:
        wrap = Path(tmp) / "wrap.toml"
        t0 = time.perf_counter()
        code = subprocess.run(
            [sys.executable, "-m", "recommender.cli", "recommend", load, "--material", material,
             "--budget", str(budget), "--workers", str(workers), "--wrap-out", str(wrap)],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL).returncode
        wall = time.perf_counter() - t0
        if code == 1:
            return None, wall
        if code != 0:
            raise SystemExit(f"recommend {load} --material {material}: exit {code}")
        return WrapFormat.from_toml(wrap, LoadUnit.from_toml(load).load_height_m), wall


def row(load_path: str, name: str, wrap: WrapFormat, note: str = "") -> str:
    load = LoadUnit.from_toml(load_path)
    verdict = run_levels(load, eumos_levels(ROAD_RULE_G), stop_at_failure=True,
                         wrap=wrap).verdict
    at = {round(v.level_g, 2): v for v in verdict.levels}
    half = at.get(0.5)
    margin = f"{level_margin(half, verdict.load_height_m):.2f}" if half else "–"
    used = wrap.material_used_on(load.layout())
    best = verdict.highest_passed_g
    assert wrap.program is not None
    return (f"| {Path(load_path).stem} | {wrap.material.name.split(' (')[0]} | {name} | "
            f"{program_summary(wrap.program)} | {used.mass_kg:.3f} kg ({used.area_m2:.1f} m²) | "
            f"{wrap.cycle_time_s:.0f} s | {'none' if best is None else f'{best:.1f} g'} | "
            f"{margin} | {note} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--budget", type=int, default=48)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--loads", nargs="+", default=EXAMPLES, metavar="LOAD.toml")
    parser.add_argument("--materials", nargs="+", default=MATERIALS, choices=MATERIALS)
    args = parser.parse_args()
    print("| load | web | program | settings | web laid | cycle | highest passed (to 0.8 g) | "
          "margin at 0.5 g | search |")
    print("|---|---|---|---|---|---|---|---|---|")
    for load_path in args.loads:
        layout = LoadUnit.from_toml(load_path).layout()
        for material in args.materials:
            space = ProgramSpace.for_layout(layout, material)
            print(row(load_path, "machine default", space.laid(space.machine_default())),
                  flush=True)
            wrap, wall = recommended(load_path, material, args.budget, args.workers)
            if wrap is None:
                web = CARDS[material].name.split(" (")[0]
                print(f"| {Path(load_path).stem} | {web} | recommended for 0.5 g | none "
                      f"passes within the budget and rounds (exit 1) | | | | | {wall:.0f} s |",
                      flush=True)
            else:
                print(row(load_path, "recommended for 0.5 g", wrap, f"{wall:.0f} s"), flush=True)


if __name__ == "__main__":
    main()
