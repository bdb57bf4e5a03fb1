"""The wrap table of docs/wrap.md: the 2- and 3-layer examples unwrapped, in Kraft paper and in
LLDPE.

Each unit runs the EUMOS sequence from 0.2 g up to 0.8 g (the road rule forward), stopping at
the first failure, as `wrapbench simulate LOAD --wrap WRAP --eumos --target 0.8` does, with the
pallet blocked by the stopper: the examples' pallets (static friction 0.45 on the sled) would
otherwise slide from 0.45 g on, and the load would never feel the higher levels.
Runs go to two processes; prints a Markdown table.

    python -m benchmarks.wrap_table
"""

from __future__ import annotations

from dataclasses import replace
from multiprocessing import Pool

from wrapenv.bench import run_levels
from wrapenv.load import LoadUnit
from wrapenv.profile import eumos_levels
from wrapenv.wrap import WrapFormat

TARGET_G = 0.8
CASES = [
    (load, wrap)
    for layers in (2, 3)
    for load, wrap in (
        (f"examples/pet_{layers}layer_columnar.toml", None),
        (f"examples/pet_{layers}layer_columnar.toml", f"examples/wrap_kraft_{layers}layer.toml"),
        (f"examples/pet_{layers}layer_columnar.toml", f"examples/wrap_lldpe_{layers}layer.toml"),
    )
]


def row(case: tuple[str, str | None]) -> str:
    load_path, wrap_path = case
    load = replace(LoadUnit.from_toml(load_path), pallet_stopper=True)
    wrap = WrapFormat.from_toml(wrap_path, load.load_height_m) if wrap_path else None
    run = run_levels(load, eumos_levels(TARGET_G), stop_at_failure=True, wrap=wrap)
    v = run.verdict
    last = v.levels[-1]
    failed = "" if last.passed else (
        f"fails {last.level_g:.1f} g: "
        + ", ".join(k for k, ok in last.criteria.items() if not ok)
        + (f" ({last.damage[0]}{', ...' if len(last.damage) > 1 else ''})" if last.damage else "")
    )
    at = {round(level.level_g, 2): level for level in v.levels}
    half = at.get(0.5)

    def mm(x: float | None) -> str:
        return "–" if x is None else f"{1000 * x:.1f}"

    if wrap is not None:
        used = wrap.material_used_on(load.layout())
        material = f"{used.area_m2:.2f} m², {1000 * used.mass_kg:.0f} g"
        fmt = " + ".join(f"{b.layers}×{b.tension_n:.0f} N" for b in wrap.bands)
        name = f"{wrap.material.name.split(' (')[0]} ({fmt})"
    else:
        material, name = "–", "unwrapped"
    best = v.highest_passed_g
    return (f"| {load.stack.layers} | {name} | {'none' if best is None else f'{best:.1f} g'} | "
            f"{mm(half.elastic_max_m if half else None)} | "
            f"{mm(half.permanent_max_m if half else None)} | "
            f"{mm(half.permanent_low20_m if half else None)} | "
            f"{mm(half.pallet_slip_m if half else None)} | "
            f"{'yes' if half and half.wrap and half.wrap.torn else 'no' if wrap else '–'} | "
            f"{material} | {failed} |")


def main() -> None:
    print("| layers | wrap (bands: layers × tension) | highest passed | elastic at 0.5 g mm | "
          "permanent at 0.5 g mm | lowest 20 cm at 0.5 g mm | pallet slip at 0.5 g mm | "
          "torn | material used | first failure |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    with Pool(2) as pool:
        for line in pool.imap(row, CASES):
            print(line, flush=True)


if __name__ == "__main__":
    main()
