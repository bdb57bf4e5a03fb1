"""Speed of the virtual bench on this machine, measured side by side in one run.

Prints the real-time factor (simulated seconds per wall second) for 1-, 2- and 3-layer columnar
units at 0.3 g, and the wall time of one 0.5 g level of the 3-layer 48-bundle example, for the
default settings and a cheaper setting, with the closed-form slip error of each setting.

    python benchmarks/bench_speed.py
"""

from __future__ import annotations

import os
import time
from dataclasses import replace

from wrapenv.bench import SimSettings, run_level
from wrapenv.load import LoadUnit
from wrapenv.profile import G, PulseProfile

os.environ.setdefault("OMP_NUM_THREADS", "1")  # one core, as the goal asks

EXAMPLE = {
    1: "examples/pet_2layer_columnar.toml",
    2: "examples/pet_2layer_columnar.toml",
    3: "examples/pet_3layer_columnar.toml",
}


def timed(layout, profile, settings, repeat=3):
    best, trace = float("inf"), None
    for _ in range(repeat):
        t0 = time.perf_counter()
        trace = run_level(layout, profile, settings)
        best = min(best, time.perf_counter() - t0)
    return best, trace


def slip_error_pct(settings: SimSettings) -> float:
    """Closed-form check (see tests/wrapenv/test_bench_mechanics.py) at 0.6 g."""
    load = LoadUnit.from_dict({
        "pallet": {"preset": "EUR"}, "bundle": {"preset": "PET6x1.5L"},
        "stack": {"layers": 1, "pattern": "explicit", "positions": [[0.4, 0.0]]},
        "friction": {"sled_pallet": {"static": 1.0, "kinetic": 1.0},
                     "pallet_bundle": {"static": 0.5, "kinetic": 0.4}}})
    p = PulseProfile(0.6, ramp_s=0.0)
    tr = run_level(load.layout(), p, settings)
    rel = tr.bundle_pos[:, 0, 0] - tr.pallet_pos[:, 0]
    a, mk, d = 0.6 * G, 0.4, p.decel_ratio * 0.6 * G
    dv = (a - mk * G) * p.dwell_s
    expected = 0.5 * (a - mk * G) * p.dwell_s**2 + dv**2 / (2 * (d + mk * G))
    return 100 * (-(rel[-1] - rel[0]) / expected - 1)


def main() -> None:
    default = SimSettings()
    cheap = replace(default, sample_every=2, solver_iterations=10)
    header = ("layers", "bodies", "setting", "sim s", "wall s", "real-time x")
    print(" ".join(f"{h:>{w}}" for h, w in zip(header, (6, 6, 8, 6, 7, 11), strict=True)))
    for layers, path in EXAMPLE.items():
        load = LoadUnit.from_toml(path)
        load = LoadUnit(load.name, load.pallet, load.bundle,
                        replace(load.stack, layers=layers), load.friction)
        layout = load.layout()
        for name, s in (("default", default), ("cheap", cheap)):
            wall, tr = timed(layout, PulseProfile(0.3), s)
            sim = tr.t_s[-1] + s.settle_s
            print(f"{layers:>6} {len(layout.bundles) + 1:>6} {name:>8} {sim:6.2f} {wall:7.3f} "
                  f"{sim / wall:11.1f}")
    layout = LoadUnit.from_toml(EXAMPLE[3]).layout()
    print("\none 0.5 g level, 3-layer 48-bundle example (goal <= 0.4 s):")
    results = {}
    for name, s in (("default", default), ("cheap", cheap)):
        wall, tr = timed(layout, PulseProfile(0.5), s)
        results[name] = wall
        print(f"  {name:8s} dt=1/{round(1 / s.timestep_s)} s, {s.solver_iterations} iterations, "
              f"contacts every {s.sample_every} step(s): {wall:.3f} s wall for "
              f"{tr.t_s[-1] + s.settle_s:.2f} s simulated; closed-form slip error "
              f"{slip_error_pct(s):+.2f} %")
    print(f"  ratio default/cheap: {results['default'] / results['cheap']:.2f}")


if __name__ == "__main__":
    main()
