"""How converged must a wrapped unit's solve be? The same EUMOS sequences (one unit through
0.2 -> 0.8 g) with Bullet's solver at several iteration counts and contact ERPs
(`SimSettings.solver_iterations`, `wrapped_contact_erp`): the machine's default Kraft
program and the Kraft band example on the 3-layer example, the default LLDPE program on the
2-layer one; then the heaviest program of the search space on a two-bundle unit at 0.3 g (the
env tests' unit), which a stiffer solve can make blow up. Prints, per level, passed, elastic and
total permanent displacement (mm), and the CPU time of the sequence. Each solve is held at its
iterations (`max_solver_iterations` too: no rerun with more).

`--heavy`: instead, programs heavier than the search's answers on the 2-layer example at 0.2 g
(the Kraft default with 3, 10 and 20 top wraps, 20 the most a program takes, all at 800 N, and
the search space's heaviest program), each at the solves and at the defaults, which run a
creeping stack again with twice the iterations (`run_levels`, docs/bench.md, "A squeeze harder
still"); "still moving" marks a level that had not come to rest 3 s after the sled stopped.

    python -m benchmarks.bench_solver [--solves 20:0.08 50:0.08 50:0.05 100:0.05] [--heavy]
"""

from __future__ import annotations

import argparse
import re
import time
import tomllib
from pathlib import Path

import numpy as np

from wrapenv.bench import SimSettings, run_levels
from wrapenv.design import N_PARAMS, ProgramSpace
from wrapenv.load import LoadUnit
from wrapenv.profile import eumos_levels
from wrapenv.program_table import MAX_WRAPS_AT_ONE_HEIGHT
from wrapenv.wrap import WrapFormat

CASES = (("examples/pet_3layer_columnar.toml", "examples/program_kraft_default.toml"),
         ("examples/pet_3layer_columnar.toml", "examples/wrap_kraft_3layer.toml"),
         ("examples/pet_2layer_columnar.toml", "examples/program_lldpe_default.toml"))
TWO_BUNDLES = {"name": "two bundles", "pallet": {"preset": "EUR"},
               "bundle": {"preset": "PET6x1.5L"},
               "stack": {"layers": 1, "pattern": "explicit",
                         "positions": [[-0.2, 0.0], [0.2, 0.0]]}}


def sequence(load: LoadUnit, wrap: WrapFormat, levels: list[float], solve: str) -> str:
    """One sequence at `solve` ("ITERATIONS:ERP", or "default"), in one line."""
    if solve == "default":
        settings, iterations, erp = SimSettings(), "default", "default"
    else:
        iterations, erp = solve.split(":")
        settings = SimSettings(solver_iterations=int(iterations),
                               max_solver_iterations=int(iterations),
                               wrapped_contact_erp=float(erp))
    t0 = time.process_time()
    run = run_levels(load, levels, settings, stop_at_failure=True, wrap=wrap)
    # A valid level's figures are never None (None only reports a non-finite figure, and a
    # valid run stayed finite): the `is not None` tests only narrow the types.
    cells = [f"{v.level_g:.1f} g " + ("pass" if v.passed else "FAIL" if v.valid else
                                      f"INVALID ({v.invalid_reason})")
             + (f" {1e3 * v.elastic_max_m:.1f}/{1e3 * v.permanent_total_max_m:.1f}"
                if v.valid and v.elastic_max_m is not None
                and v.permanent_total_max_m is not None else "")
             + (" still moving" if v.not_at_rest else "") for v in run.verdict.levels]
    return (f"{iterations:>4s} it, ERP {erp}, {time.process_time() - t0:5.1f} CPU s, "
            f"solved at {run.solver_iterations}: " + "; ".join(cells))


def heavy(solves: list[str]) -> None:
    """Programs heavier than the answers, on the 2-layer example at 0.2 g (`--heavy`)."""
    load = LoadUnit.from_toml("examples/pet_2layer_columnar.toml")
    height = load.layout().load_height_m
    text = Path("examples/program_kraft_default.toml").read_text()
    wraps = {f"Kraft default, {n} top wraps": WrapFormat.from_dict(
        tomllib.loads(re.sub(r"(?m)^top_wraps = \d+", f"top_wraps = {n}", text)), "heavy",
        height) for n in (3, 10, MAX_WRAPS_AT_ONE_HEIGHT)}
    space = ProgramSpace.for_layout(load.layout(), "kraft")
    wraps["the search space's heaviest program"] = space.decode(np.ones(N_PARAMS))
    for name, wrap in wraps.items():
        print(f"examples/pet_2layer_columnar.toml + {name}", flush=True)
        for solve in [*solves, "default"]:
            print("  " + sequence(load, wrap, [0.2], solve), flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    default = SimSettings()
    parser.add_argument("--solves", nargs="+", metavar="ITERATIONS:ERP",
                        default=["20:0.08", "50:0.08", f"{default.solver_iterations}:"
                                 f"{default.wrapped_contact_erp}", "100:0.05"])
    parser.add_argument("--heavy", action="store_true",
                        help="programs heavier than the search's answers instead")
    args = parser.parse_args()
    print("per level: result, elastic / total permanent mm")
    if args.heavy:
        heavy(args.solves)
        return
    for load_path, wrap_path in CASES:
        load = LoadUnit.from_toml(load_path)
        wrap = WrapFormat.from_toml(wrap_path, load.layout().load_height_m)
        print(f"{load_path} + {wrap_path}", flush=True)
        for solve in args.solves:
            print("  " + sequence(load, wrap, eumos_levels(0.8), solve), flush=True)
    load = LoadUnit.from_dict(TWO_BUNDLES)
    space = ProgramSpace.for_layout(load.layout(), "kraft")
    heaviest = space.decode(np.ones(N_PARAMS))
    print("two bundles + the search space's heaviest Kraft program", flush=True)
    for solve in args.solves:
        print("  " + sequence(load, heaviest, [0.3], solve), flush=True)


if __name__ == "__main__":
    main()
