"""A cheaper screening fidelity against the default settings, measured side by side in one run.

For multi-fidelity search: screen candidates with `SimSettings.screening()`, confirm the best
with the defaults. Over a set of wrapped cases (the 2- and 3-layer columnar and the 3-layer
interlocked examples, the example wraps and lighter full-height formats, levels from 0.3 to
0.8 g, passes and failures), each case runs with the defaults and with each candidate setting,
alternated. Printed per setting: verdict agreement with the defaults (passed or not), the error
of the level's margin (`wrapenv.eumos.level_margin`, the figure a search ranks by) over the
levels not decided failed (margin > -1: a level stopped once decided only bounds its margin),
the permanent displacement's error, and the speed-up in CPU time over all cases.

    taskset -c 0 python -m benchmarks.bench_screening [--candidates | --only NAME ...]
"""

from __future__ import annotations

import argparse
import os
import time
from dataclasses import dataclass, replace

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from wrapenv.bench import SimSettings, run_level  # noqa: E402
from wrapenv.eumos import evaluate, level_margin  # noqa: E402
from wrapenv.load import LoadUnit  # noqa: E402
from wrapenv.profile import PulseProfile  # noqa: E402
from wrapenv.wrap import WrapFormat  # noqa: E402

#: A case's wrap and a case, as in CASES.
WrapSpec = str | tuple[str, int, float]
Case = tuple[str, WrapSpec, float]

UNITS = {"3L": "examples/pet_3layer_columnar.toml", "2L": "examples/pet_2layer_columnar.toml",
         "3L interlocked": "examples/pet_3layer_interlocked.toml"}
#: (unit, wrap: an example file or (material, layers, tension_n) over the full height, level g)
CASES: list[Case] = [
    ("3L", "examples/wrap_kraft_3layer.toml", 0.5), ("3L", "examples/wrap_kraft_3layer.toml", 0.8),
    ("3L", "examples/wrap_lldpe_3layer.toml", 0.5), ("3L", "examples/wrap_lldpe_3layer.toml", 0.7),
    ("3L", ("lldpe", 1, 70.0), 0.4), ("3L", ("lldpe", 1, 70.0), 0.6),
    ("3L", ("kraft", 1, 100.0), 0.5), ("3L", ("kraft", 1, 100.0), 0.7),
    ("2L", "examples/wrap_kraft_2layer.toml", 0.8),
    ("2L", "examples/wrap_lldpe_2layer.toml", 0.6), ("2L", "examples/wrap_lldpe_2layer.toml", 0.8),
    ("2L", ("lldpe", 2, 40.0), 0.5),
    ("3L interlocked", "examples/wrap_kraft_3layer.toml", 0.5),
    ("3L interlocked", "examples/wrap_lldpe_3layer.toml", 0.6),
]
CANDIDATES = {
    "end at first rest": SimSettings(simulate_stop=False),
    "stop when decided": SimSettings(stop_when_decided=True),
    "dt 1/160 s, end at first rest": SimSettings(timestep_s=1 / 160, simulate_stop=False),
    "dt 1/120 s, end at first rest": SimSettings(timestep_s=1 / 120, simulate_stop=False),
    # every case is wrapped: fewer iterations for a wrapped unit than its default 50
    "30 iterations, end at first rest": SimSettings(solver_iterations=30,
                                                    simulate_stop=False),
    "20 iterations, end at first rest": SimSettings(solver_iterations=20,
                                                    simulate_stop=False),
    "rigid boxes": SimSettings(rigid_boxes=True),
    "rigid boxes, screening()": replace(SimSettings.screening(), rigid_boxes=True),
    "rigid boxes, training()": replace(SimSettings.training(), rigid_boxes=True),
}


@dataclass
class Outcome:
    passed: bool
    margin: float
    permanent_m: float
    cpu_s: float


def wrap_of(spec: WrapSpec, height_m: float) -> WrapFormat:
    if isinstance(spec, str):
        return WrapFormat.from_toml(spec, height_m)
    material, layers, tension = spec
    return WrapFormat.from_dict({"material": material, "web_width_m": 0.5, "band": [
        {"from_m": 0.0, "to_m": height_m, "layers": layers, "tension_n": tension}]})


def run_case(case: Case, settings: SimSettings) -> Outcome:
    unit, spec, level = case
    load = LoadUnit.from_toml(UNITS[unit])
    wrap = wrap_of(spec, load.load_height_m)
    t0 = time.process_time()
    verdict = evaluate(run_level(load.layout(), PulseProfile(level), settings, wrap))
    return Outcome(verdict.passed, level_margin(verdict, load.load_height_m),
                   verdict.permanent_max_m or 0.0, time.process_time() - t0)


def describe(case: Case) -> str:
    unit, spec, level = case
    wrap = spec.split("/")[-1].removesuffix(".toml") if isinstance(spec, str) else \
        f"{spec[0]} {spec[1]} x {spec[2]:.0f} N"
    return f"{unit}, {wrap}, {level} g"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--candidates", action="store_true",
                        help="compare the candidate settings, not only SimSettings.screening()")
    parser.add_argument("--only", nargs="+", choices=CANDIDATES, metavar="NAME",
                        help="compare only these candidates (and the two named settings)")
    args = parser.parse_args(argv)
    chosen = args.only or (list(CANDIDATES) if args.candidates else [])
    settings = {name: CANDIDATES[name] for name in chosen}
    settings.setdefault("screening()", SimSettings.screening())
    settings.setdefault("training()", SimSettings.training())
    results: dict[str, list[Outcome]] = {"default": [], **{name: [] for name in settings}}
    print(f"{len(CASES)} wrapped cases; default: {SimSettings()}")
    for case in CASES:
        results["default"].append(run_case(case, SimSettings()))
        for name, s in settings.items():
            results[name].append(run_case(case, s))
        ref = results["default"][-1]
        print(f"  {describe(case):42s} default {'pass' if ref.passed else 'FAIL'} margin "
              f"{ref.margin:+.3f} | " + " | ".join(
                  f"{results[n][-1].margin:+.3f}" for n in settings), flush=True)
    base = results["default"]
    print(f"\n{'setting':45s} {'verdicts agree':>14} {'margin error mean / max':>23} "
          f"{'permanent error max mm':>22} {'speed-up':>8}")
    for name in settings:
        got = results[name]
        agree = sum(a.passed == b.passed for a, b in zip(got, base, strict=True))
        err = np.array([abs(a.margin - b.margin) for a, b in zip(got, base, strict=True)
                        if b.margin > -1 and a.margin > -1])
        perm = max(abs(a.permanent_m - b.permanent_m) for a, b in zip(got, base, strict=True))
        speed = sum(b.cpu_s for b in base) / sum(a.cpu_s for a in got)
        err_text = f"{err.mean():.3f} / {err.max():.3f}" if len(err) else "-"
        print(f"{name:45s} {agree:>7d} of {len(base):<4d} {err_text:>23} {1000 * perm:22.1f} "
              f"{speed:7.2f}x")


if __name__ == "__main__":
    main()
