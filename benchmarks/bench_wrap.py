"""Cost of the soft wrap, measured side by side in one run.

1. The 3-layer example (48 bundles) unwrapped and wrapped (examples/wrap_kraft_3layer.toml,
   examples/wrap_lldpe_3layer.toml) at the same levels: wall and CPU time per level, the time
   the level covers and the steps Bullet actually simulated (a level skips what cannot change),
   and where a step's time goes: Bullet's step (which grows when wrapped, because the squeezed
   layers close their gaps and touch), the wrap model's numpy and force calls, and the rest of
   the loop (state reads, contact states, records, checks).
2. The same unit wrapped by PyBullet's deformable world (benchmarks/deformable_wrap.py, a tube
   of similar node count), at 240 Hz (the bench's rate) and 500 Hz.

    taskset -c 0 python -m benchmarks.bench_wrap
"""

from __future__ import annotations

import os
import time
from collections import defaultdict
from collections.abc import Callable
from typing import ParamSpec, TypeVar

from benchmarks.deformable_wrap import run_deformable_wrap
from wrapenv import bench
from wrapenv.bench import SimSettings, run_level
from wrapenv.load import Layout, LoadUnit
from wrapenv.profile import PulseProfile
from wrapenv.wrap import WrapFormat
from wrapenv.wrap_physics import WrapNet

os.environ.setdefault("OMP_NUM_THREADS", "1")

EXAMPLE = "examples/pet_3layer_columnar.toml"
WRAPS = {"kraft": "examples/wrap_kraft_3layer.toml", "lldpe": "examples/wrap_lldpe_3layer.toml"}
LEVELS_G = (0.3, 0.5)

P = ParamSpec("P")
R = TypeVar("R")


class Timers:
    """CPU time spent in the bench's wrap coupling and in Bullet's step, by monkey-patching."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = defaultdict(float)
        self.calls: dict[str, int] = defaultdict(int)
        self._originals: dict[str, Callable[..., None]] = {
            "step": bench.BulletWorld.step, "wrap": bench._Run._apply_wrap}

    def _timed(self, name: str, fn: Callable[P, R]) -> Callable[P, R]:
        def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
            t0 = time.process_time()
            out = fn(*args, **kwargs)
            self.seconds[name] += time.process_time() - t0
            self.calls[name] += 1
            return out
        return wrapper

    def __enter__(self) -> Timers:
        setattr(bench.BulletWorld, "step", self._timed("step", self._originals["step"]))  # noqa: B010
        setattr(bench._Run, "_apply_wrap", self._timed("wrap", self._originals["wrap"]))  # noqa: B010
        return self

    def __exit__(self, *exc: object) -> None:
        setattr(bench.BulletWorld, "step", self._originals["step"])  # noqa: B010
        setattr(bench._Run, "_apply_wrap", self._originals["wrap"])  # noqa: B010


def level_run(layout: Layout, level_g: float, wrap: WrapFormat | None) -> dict[str, float]:
    settings = SimSettings()
    with Timers() as timers:
        t0, c0 = time.perf_counter(), time.process_time()
        trace = run_level(layout, PulseProfile(level_g), settings, wrap)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    level_s = float(trace.t_s[-1]) + settings.settle_s
    steps = timers.calls["step"]
    step_s, wrap_s = timers.seconds["step"], timers.seconds["wrap"]
    # real-time factor of what Bullet simulated (like for like with the deformable run below)
    rtf = steps * settings.timestep_s / wall
    return {"wall": wall, "cpu": cpu, "level_s": level_s, "rtf": rtf, "steps": steps,
            "step_ms": 1000 * step_s / steps, "wrap_ms": 1000 * wrap_s / steps,
            "other_ms": 1000 * (cpu - step_s - wrap_s) / steps}


def main() -> None:
    load = LoadUnit.from_toml(EXAMPLE)
    layout = load.layout()
    wraps = {name: WrapFormat.from_toml(path, load.load_height_m) for name, path in WRAPS.items()}
    settings = SimSettings()
    print(f"3-layer example (48 bundles), dt 1/240 s, {settings.solver_iterations} solver "
          "iterations; best of 2 (CPU time)")
    print(f"{'level':>5} {'wrap':>6} {'wall s':>7} {'CPU s':>6} {'level s':>7} {'real-time x':>11} "
          f"{'steps':>6} {'Bullet ms/step':>14} {'wrap ms/step':>12} {'other ms/step':>13} "
          f"{'CPU vs unwrapped':>16}")
    ours = {}
    for level in LEVELS_G:
        base = None
        for name, wrap in (("none", None), *wraps.items()):
            r = min((level_run(layout, level, wrap) for _ in range(2)), key=lambda x: x["cpu"])
            base = base or r
            ours[(level, name)] = r
            print(f"{level:5.1f} {name:>6} {r['wall']:7.2f} {r['cpu']:6.2f} {r['level_s']:7.2f} "
                  f"{r['rtf']:11.2f} {r['steps']:6d} {r['step_ms']:14.2f} {r['wrap_ms']:12.2f} "
                  f"{r['other_ms']:13.2f} {r['cpu'] / base['cpu']:15.2f}x")
    nodes = len(WrapNet(wraps["kraft"], layout).node_body)

    print(f"\nPyBullet deformable-world tube vs this wrap (ours: {nodes} nodes), 0.5 g, 2 s")
    kraft = ours[(0.5, "kraft")]
    for dt in (1 / 240, 1 / 500):
        d = run_deformable_wrap(layers=3, nodes_around=24, rings=7, sim_seconds=2.0,
                                timestep_s=dt, level_g=0.5)
        verdict = "EXPLODED" if d["exploded"] else "stable"
        print(f"  deformable {d['nodes']} nodes, dt 1/{round(1 / dt)} s: {d['sim_s']:.2f} s "
              f"simulated in {d['wall_s']:.2f} s, real-time x{d['realtime_factor']:.2f} "
              f"({verdict}); this wrap (whole bench, kraft) x{kraft['rtf']:.2f}: "
              f"{kraft['rtf'] / d['realtime_factor']:.1f}x faster")
        wrap_share = kraft["wrap_ms"] / 1000 * 240  # wall s of wrap model per simulated s
        print(f"    wrap model alone: {wrap_share:.3f} s per simulated s vs the deformable "
              f"run's {1 / d['realtime_factor']:.2f} s: "
              f"{1 / d['realtime_factor'] / wrap_share:.0f}x")


if __name__ == "__main__":
    main()
