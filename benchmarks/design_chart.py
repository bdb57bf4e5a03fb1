"""The design chart of docs/wrap.md: what a wrapping program does to the 2- and 3-layer examples.

For Kraft paper and LLDPE film, every combination of wraps (1 to 6) and tension (three values
per material) is run as a machine program: `n` bottom wraps, a spiral up at the overlap that
lays `n` layers (1 - 1/n: 0 % for one, 50 % for two, 83 % for six), `n` top wraps, one tension
for every zone. Each runs the EUMOS sequence 0.2 -> 0.8 g (the road rule forward) against the
stopper, stopping at the first failure. Reported per cell: elastic displacement and the wrap's
peak utilisation at 0.5 g (the legal level) with the place it peaks, and the highest level
passed; a † marks a unit that had not come to rest when the bench stopped waiting. Then the
sensitivity to the load's give: the example wraps (examples/wrap_*_{2,3}layer.toml) with the
bundles' corner stiffness halved and doubled.

    python -m benchmarks.design_chart                    # everything: about 2 CPU-hours
    python -m benchmarks.design_chart --quick            # wraps 1, 3, 6 at the middle tension
    python -m benchmarks.design_chart --only sensitivity --workers 2
    python -m benchmarks.design_chart --only chart --layers 2    # one example, every cell

Prints Markdown tables; runs go to `--workers` processes (default 2).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass, replace
from multiprocessing import Pool

from wrapenv.bench import SimSettings, run_levels
from wrapenv.load import LoadUnit
from wrapenv.profile import PulseProfile, eumos_levels
from wrapenv.wrap import WrapFormat

TARGET_G = 0.8
CHART_LEVEL_G = 0.5
LOADS = {2: "examples/pet_2layer_columnar.toml", 3: "examples/pet_3layer_columnar.toml"}
#: Three tensions per material, N per layer of a 0.5 m web: Kraft half, once and twice the
#: card's default (docs/materials.md P4; the machine default, 800 N, squeezes a many-layer wrap
#: so hard that the stack creeps, see `creeps`), film from half its default (L4) to half its
#: yield force.
TENSIONS_N = {"kraft": (125.0, 250.0, 500.0), "lldpe": (35.0, 70.0, 94.0)}
WRAPS = (1, 2, 3, 4, 5, 6)
GIVES = (0.5, 1.0, 2.0)
#: The examples' wraps, by material and layers of bundles.
EXAMPLE_WRAPS = "examples/wrap_{material}_{layers}layer.toml"


@dataclass(frozen=True)
class Case:
    layers: int
    material: str
    wraps: int | None      # None: the example wrap of this material and unit
    tension_n: float | None
    give: float = 1.0


@dataclass(frozen=True)
class Result:
    case: Case
    elastic_mm: float | None      # at CHART_LEVEL_G (None: not reached)
    utilisation: float | None
    where: str
    highest_g: float | None
    failure: str
    web_m2: float
    seconds: float
    #: The unit had not come to rest when the bench stopped waiting (3 s after the sled): a
    #: squeezed stack creeping on Bullet's contacts, so its displacements are not the wrap's.
    creeps: bool = False


def program(material: str, wraps: int, tension_n: float, load_height_m: float) -> WrapFormat:
    """n bottom wraps, a spiral laying n layers, n top wraps, one tension."""
    return WrapFormat.from_dict({"material": material, "web_width_m": 0.5, "program": {
        "bottom_wraps": wraps, "bottom_tension_n": tension_n, "up_overlap": 1.0 - 1.0 / wraps,
        "middle_tension_n": tension_n, "top_wraps": wraps, "top_tension_n": tension_n}},
        load_height_m=load_height_m)


def run(case: Case) -> Result:
    t0 = time.perf_counter()
    load = replace(LoadUnit.from_toml(LOADS[case.layers]), pallet_stopper=True)
    load = load.with_give(case.give)
    h = load.load_height_m
    if case.wraps is None:
        wrap = WrapFormat.from_toml(EXAMPLE_WRAPS.format(material=case.material,
                                                         layers=case.layers), h)
    else:
        assert case.tension_n is not None
        wrap = program(case.material, case.wraps, case.tension_n, h)
    bench = run_levels(load, eumos_levels(TARGET_G), stop_at_failure=True, wrap=wrap)
    verdict = bench.verdict
    at = {round(v.level_g, 2): v for v in verdict.levels}.get(CHART_LEVEL_G)
    trace = {round(t.level_g, 2): t for t in bench.traces}.get(CHART_LEVEL_G)
    waited = SimSettings().max_rest_wait_s + PulseProfile(CHART_LEVEL_G).duration_s
    last = verdict.levels[-1]
    failure = "" if last.passed else f"{last.level_g:.1f} g: " + ", ".join(
        k for k, ok in last.criteria.items() if not ok)
    top = at.wrap.critical[0] if at is not None and at.wrap and at.wrap.critical else None
    return Result(
        case=case,
        elastic_mm=None if at is None or at.elastic_max_m is None else 1000 * at.elastic_max_m,
        utilisation=top.utilisation if top else None,
        where=f"{top.where} {top.height_m:.2f} m" if top else "",
        highest_g=verdict.highest_passed_g, failure=failure,
        web_m2=wrap.material_used_on(load.layout()).area_m2,
        seconds=time.perf_counter() - t0,
        creeps=trace is not None and float(trace.t_s[-1]) >= waited - 1e-6)


def _cell(r: Result) -> str:
    elastic = "–" if r.elastic_mm is None else f"{r.elastic_mm:.0f} mm"
    use = "–" if r.utilisation is None else f"{100 * r.utilisation:.0f} %"
    best = "none" if r.highest_g is None else f"{r.highest_g:.1f} g"
    return f"{elastic}{' †' if r.creeps else ''} · {use} · **{best}**"


def chart(results: list[Result], tensions: dict[str, tuple[float, ...]]) -> None:
    for layers in LOADS:
        for material in TENSIONS_N:
            rows = [r for r in results if r.case.layers == layers
                    and r.case.material == material and r.case.give == 1.0
                    and r.case.wraps is not None]
            if not rows:
                continue
            print(f"\n{layers}-layer example, {material}: elastic at {CHART_LEVEL_G} g · "
                  "peak utilisation at 0.5 g · highest level passed (web m² for the row)\n")
            print("| wraps | " + " | ".join(f"{t:.0f} N" for t in tensions[material])
                  + " | web | most loaded place at 0.5 g (top tension) |")
            print("|---" * (len(tensions[material]) + 3) + "|")
            for wraps in sorted({r.case.wraps for r in rows if r.case.wraps is not None}):
                cells = {r.case.tension_n or 0.0: r for r in rows if r.case.wraps == wraps}
                line = [_cell(cells[t]) if t in cells else "" for t in tensions[material]]
                last = cells[max(cells)]
                print(f"| {wraps} | " + " | ".join(line)
                      + f" | {last.web_m2:.1f} m² | {last.where} |")


def sensitivity(results: list[Result]) -> None:
    rows = [r for r in results if r.case.wraps is None]
    if not rows:
        return
    print("\nThe load's give (bundle corner stiffness x 0.5, 1, 2), the examples' wraps: "
          "elastic at 0.5 g · highest level passed (first failure)\n")
    print("| unit | wrap | " + " | ".join(f"give x {g}" for g in GIVES) + " |")
    print("|---" * (len(GIVES) + 2) + "|")
    for layers in LOADS:
        for material in TENSIONS_N:
            cells = {r.case.give: r for r in rows
                     if r.case.layers == layers and r.case.material == material}
            if cells:
                print(f"| {layers} layers | {material} example | "
                      + " | ".join(_give_cell(cells[g]) if g in cells else "" for g in GIVES)
                      + " |")


def _give_cell(r: Result) -> str:
    elastic = "–" if r.elastic_mm is None else f"{r.elastic_mm:.1f} mm{' †' if r.creeps else ''}"
    best = "none" if r.highest_g is None else f"{r.highest_g:.1f} g"
    return f"{elastic} · **{best}**" + (f" (fails {r.failure})" if r.failure else "")


def cases(args: argparse.Namespace) -> tuple[list[Case], dict[str, tuple[float, ...]]]:
    tensions: dict[str, tuple[float, ...]] = {
        m: ((t[1],) if args.quick else t) for m, t in TENSIONS_N.items()}
    wraps = (1, 3, 6) if args.quick else WRAPS
    out = []
    if args.only in (None, "chart"):
        out += [Case(layers, material, n, t) for layers in args.layers for material in TENSIONS_N
                for n in wraps for t in tensions[material]]
    if args.only in (None, "sensitivity"):
        out += [Case(layers, material, None, None, give) for layers in args.layers
                for material in TENSIONS_N for give in GIVES]
    return out, tensions


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="wraps 1, 3, 6 at each material's middle tension only")
    parser.add_argument("--only", choices=("chart", "sensitivity"))
    parser.add_argument("--layers", type=int, nargs="+", choices=tuple(LOADS),
                        default=tuple(LOADS), help="which examples (layers of bundles)")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    todo, tensions = cases(args)
    t0 = time.perf_counter()
    # the slowest first (3 layers, many wraps), so the pool ends together
    todo.sort(key=lambda c: (-c.layers, -(c.wraps or 3)))
    with Pool(args.workers) as pool:
        results = list(pool.imap_unordered(run, todo))
    chart(results, tensions)
    sensitivity(results)
    if any(r.creeps for r in results):
        print("\n†: the unit had not come to rest 3 s after the sled stopped (a squeezed stack "
              "creeping on the bench's contacts): that displacement is not the wrap's.")
    cpu = sum(r.seconds for r in results)
    print(f"\n{len(results)} EUMOS sequences, {cpu:.0f} s of simulation in "
          f"{time.perf_counter() - t0:.0f} s ({args.workers} workers)")


if __name__ == "__main__":
    main()
