"""How deep a falling bundle drives into what it lands on, and how soon the solver pushes it out.

The bench calls a level invalid where bodies stand deeper in each other than
`PENETRATION_LIMIT_M` for `PENETRATION_HOLD_S` (wrapenv/bench.py): the solver lost the contact.
An impact drives a body in for a few steps before the solver pushes it out. This measures those
impacts on the unwrapped columnar examples and on the 3-layer one in a light film that gives
way, at levels where bundles fall, over friction drawn around the examples' own: the deepest
overlap of each level read at every step, the steps it stood past the limit, and how each rule
judges the level: the hold (today), and a limit on one reading every `PENETRATION_READ_STEPS`
steps (until 2026-12-03), which judged an impact by whether a reading fell on its step.

    python -m benchmarks.impacts [--draws 10] [--seed 0] [--workers 2] [--training]
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass, replace
from multiprocessing import Pool
from pathlib import Path
from typing import Any

import numpy as np

from wrapenv import bench
from wrapenv.load import FrictionPair, LoadUnit
from wrapenv.profile import PulseProfile
from wrapenv.wrap import WrapFormat

#: (example, its wrap or None, levels in g at which its bundles slide, tip and fall); the light
#: film gives way on the 3-layer unit from 0.6 g and lets bundles fall with the wrap's
#: contact ERP, which pushes an overlap out more slowly (wrapenv/bench.py)
CASES = (("examples/pet_3layer_columnar.toml", None, (0.30, 0.35, 0.40, 0.45, 0.50)),
         ("examples/pet_2layer_columnar.toml", None, (0.45, 0.50, 0.55)),
         ("examples/pet_3layer_columnar.toml", "examples/wrap_lldpe_1layer_light.toml",
          (0.60, 0.80, 1.00)))
#: Half-widths of the draws around the example's coefficients.
STATIC_SPREAD, KINETIC_SPREAD = 0.05, 0.03


@dataclass(frozen=True)
class Draw:
    path: str
    wrap_path: str | None
    level_g: float
    training: bool  # at PPO training's settings (SimSettings.training) instead of the defaults
    pallet_bundle: FrictionPair
    bundle_bundle: FrictionPair


@dataclass(frozen=True)
class Impact:
    draw: Draw
    valid: bool
    invalid_reason: str
    deepest_mm: float
    steps_past_limit: int
    read_past_limit: bool  # a reading every PENETRATION_READ_STEPS steps fell past the limit
    #: The share of the readings' possible phases (step mod PENETRATION_READ_STEPS) that would
    #: have read the overlap past the limit: the chance the one-reading rule calls the level
    #: invalid, where the impact's step falls anywhere between readings.
    chance_read: float


class _Recorded(bench._Run):
    """A level whose overlap is read at every step it observes (a query: the physics is the
    bench's own), with the step of each reading."""

    def __init__(self, *args: Any) -> None:
        super().__init__(*args)
        self.depths: list[tuple[int, float]] = []

    def _check(self, pos: np.ndarray, vel: np.ndarray, step: int) -> None:
        self.depths.append((step, self.world.max_penetration_m()))
        super()._check(pos, vel, step)


def _drawn(pair: FrictionPair, rng: np.random.Generator) -> FrictionPair:
    static = pair.static + rng.uniform(-STATIC_SPREAD, STATIC_SPREAD)
    kinetic = min(static, pair.kinetic + rng.uniform(-KINETIC_SPREAD, KINETIC_SPREAD))
    return FrictionPair(round(static, 3), round(kinetic, 3))


def draws(n: int, seed: int, training: bool) -> list[Draw]:
    rng = np.random.default_rng(seed)
    out: list[Draw] = []
    for path, wrap_path, levels in CASES:
        friction = LoadUnit.from_toml(path).friction
        for level in levels:
            out.extend(Draw(path, wrap_path, level, training, _drawn(friction.pallet_bundle, rng),
                            _drawn(friction.bundle_bundle, rng)) for _ in range(n))
    return out


def measure(draw: Draw) -> Impact:
    load = LoadUnit.from_toml(draw.path)
    load = load.with_friction(replace(load.friction, pallet_bundle=draw.pallet_bundle,
                                            bundle_bundle=draw.bundle_bundle))
    layout = load.layout()
    wrap = (WrapFormat.from_toml(draw.wrap_path, layout.load_height_m) if draw.wrap_path
            else None)
    settings = bench.SimSettings.training() if draw.training else bench.SimSettings()
    with bench.BenchUnit(layout, settings, wrap) as unit:
        run = _Recorded(unit.world, layout, PulseProfile(draw.level_g), unit.settings,
                        unit.stick_slip, unit.wrap, None)
        trace = run.execute()
    steps, depths = (np.array(x) for x in zip(*run.depths, strict=True))
    past = depths > bench.PENETRATION_LIMIT_M
    every = bench.PENETRATION_READ_STEPS
    read = past & (steps % every == 0)
    phases = len(set((steps[past] % every).tolist()))
    return Impact(draw, trace.valid, trace.invalid_reason, 1000 * float(depths.max()),
                  int(past.sum()), bool(read.any()), phases / every)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--draws", type=int, default=10, help="friction draws per level")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--training", action="store_true",
                        help="at PPO training's settings: a 1/160 s step, a level ended once "
                             "decided failed")
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    with Pool(args.workers) as pool:
        impacts = pool.map(measure, draws(args.draws, args.seed, args.training))
    print(f"limit {1000 * bench.PENETRATION_LIMIT_M:g} mm, hold {bench.PENETRATION_HOLD_S:g} s, "
          f"{args.draws} friction draws a level, "
          f"{'training' if args.training else 'default'} settings")
    print(f"{'example':46s} level  deepest overlap, mm  past the limit  most steps past it  "
          "invalid: the hold / one reading (expected)")
    for path, wrap_path, levels in CASES:
        name = Path(path).stem + (f" + {Path(wrap_path).stem}" if wrap_path else "")
        for level in levels:
            cell = [i for i in impacts if (i.draw.path, i.draw.wrap_path, i.draw.level_g) ==
                    (path, wrap_path, level)]
            deepest = [i.deepest_mm for i in cell]
            print(f"{name:46s} {level:.2f}  {min(deepest):5.1f}-{max(deepest):5.1f}"
                  f"          {sum(i.steps_past_limit > 0 for i in cell):3d} of {len(cell):<3d}"
                  f"    {max(i.steps_past_limit for i in cell):5d}               "
                  f"{sum(not i.valid for i in cell):3d} / {sum(i.read_past_limit for i in cell)}"
                  f" ({sum(i.chance_read for i in cell):.2f})")
    print(f"levels: {len(impacts)}; an overlap past the limit in "
          f"{sum(i.steps_past_limit > 0 for i in impacts)}; invalid under the hold "
          f"{sum(not i.valid for i in impacts)}, under one reading "
          f"{sum(i.read_past_limit for i in impacts)} (expected "
          f"{sum(i.chance_read for i in impacts):.2f})")
    for i in impacts:
        if not i.valid:
            print(f"  invalid: {i.draw}: {i.invalid_reason}")
    print(f"{time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
