"""Speed of one bench level under each setting, measured side by side in one run.

Units: the 2- and 3-layer columnar examples unwrapped at 0.3 g, and the 3-layer example in its
Kraft and LLDPE wraps at 0.5 g. Settings: the defaults; every step simulated
(`skip_still=False`: what skipping the still stretches saves); the defaults stopping once a
level is decided failed (`stop_when_decided`, for searches); and the screening fidelity
(`SimSettings.screening()`). Per unit and setting: CPU seconds per level (median of
`--repeat`, settings alternated), the steps Bullet simulated, the verdict, and for each setting
the closed-form slip error of tests/wrapenv/test_bench_mechanics.py (0.6 g, mu_k 0.4).

    taskset -c 0 python -m benchmarks.bench_speed
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")  # one core, as the goal asks

from wrapenv import bench  # noqa: E402
from wrapenv.bench import SimSettings, run_level  # noqa: E402
from wrapenv.eumos import evaluate  # noqa: E402
from wrapenv.load import Layout, LoadUnit  # noqa: E402
from wrapenv.profile import G, PulseProfile  # noqa: E402
from wrapenv.wrap import WrapFormat  # noqa: E402

UNITS = [  # (name, load, wrap, level g)
    ("2 layers", "examples/pet_2layer_columnar.toml", None, 0.3),
    ("3 layers", "examples/pet_3layer_columnar.toml", None, 0.3),
    ("3 layers, Kraft", "examples/pet_3layer_columnar.toml", "examples/wrap_kraft_3layer.toml",
     0.5),
    ("3 layers, LLDPE", "examples/pet_3layer_columnar.toml", "examples/wrap_lldpe_3layer.toml",
     0.5),
]
SETTINGS = {
    "default": SimSettings(),
    "every step": SimSettings(skip_still=False),
    "stop when decided": SimSettings(stop_when_decided=True),
    "screening()": SimSettings.screening(),
}


def counted_level(layout: Layout, level_g: float, settings: SimSettings,
                  wrap: WrapFormat | None) -> tuple[float, int, str]:
    """CPU seconds, Bullet steps and verdict of one level."""
    steps = 0
    real = bench.BulletWorld.step

    def counting(world: bench.BulletWorld) -> None:
        nonlocal steps
        steps += 1
        real(world)

    setattr(bench.BulletWorld, "step", counting)  # noqa: B010 (mypy: no method assignment)
    try:
        t0 = time.process_time()
        trace = run_level(layout, PulseProfile(level_g), settings, wrap)
        cpu = time.process_time() - t0
    finally:
        setattr(bench.BulletWorld, "step", real)  # noqa: B010
    verdict = evaluate(trace)
    return cpu, steps, "pass" if verdict.passed else "fail"


def slip_error(settings: SimSettings) -> str:
    """Closed-form check (see tests/wrapenv/test_bench_mechanics.py) at 0.6 g: the slide
    passes the elastic limit, so a setting that stops once decided does not finish it."""
    load = LoadUnit.from_dict({
        "pallet": {"preset": "EUR"}, "bundle": {"preset": "PET6x1.5L"},
        "stack": {"layers": 1, "pattern": "explicit", "positions": [[0.4, 0.0]]},
        "friction": {"sled_pallet": {"static": 1.0, "kinetic": 1.0},
                     "pallet_bundle": {"static": 0.5, "kinetic": 0.4}}})
    p = PulseProfile(0.6, ramp_s=0.0)
    tr = run_level(load.layout(), p, settings)
    if tr.stopped_early:
        return "stopped once decided"
    rel = tr.bundle_pos_m[:, 0, 0] - tr.pallet_pos_m[:, 0]
    a, mk, d = 0.6 * G, 0.4, p.decel_ratio * 0.6 * G
    dv = (a - mk * G) * p.dwell_s
    expected = 0.5 * (a - mk * G) * p.dwell_s**2 + dv**2 / (2 * (d + mk * G))
    return f"{100 * (-(rel[-1] - rel[0]) / expected - 1):+.2f} %"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    print(f"CPU s per level, median of {args.repeat}; Bullet steps; verdict")
    print(f"{'unit':22s} " + " ".join(f"{name:>24s}" for name in SETTINGS))
    for name, load_path, wrap_path, level in UNITS:
        load = LoadUnit.from_toml(load_path)
        wrap = WrapFormat.from_toml(wrap_path, load.load_height_m) if wrap_path else None
        layout = load.layout()
        runs: dict[str, list[tuple[float, int, str]]] = {s: [] for s in SETTINGS}
        for _ in range(args.repeat):
            for setting, settings in SETTINGS.items():
                runs[setting].append(counted_level(layout, level, settings, wrap))
        cells = []
        for setting in SETTINGS:
            cpu = statistics.median(r[0] for r in runs[setting])
            _, steps, verdict = runs[setting][-1]
            cells.append(f"{cpu:6.2f} s {steps:5d} st {verdict:>4s}")
        print(f"{name + f' {level} g':22s} " + " ".join(f"{c:>24s}" for c in cells))
    print("\nclosed-form slip error at 0.6 g: " + ", ".join(
        f"{setting} {slip_error(settings)}" for setting, settings in SETTINGS.items()))


if __name__ == "__main__":
    main()
