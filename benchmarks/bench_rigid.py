"""Would rigid (maximal-coordinate) boxes make the bench cheaper? (issue 15)

The bench's boxes are reduced-coordinate bodies (`btMultiBody`), whose contacts Bullet does not
warm-start. Rigid bodies are warm-started, but a box sliding on a dynamic one veers and slides
short (`BulletWorld.add_box`). pybullet's solver mode already holds two friction directions
(SOLVER_USE_2_FRICTION_DIRECTIONS); the veer comes from directions that follow the sliding
velocity, which SOLVER_DISABLE_VELOCITY_DEPENDENT_FRICTION_DIRECTION turns off. That flag, like
the warm-start one, is reached through a saved world's solver mode (`bench_warm_start`).

Compared, each case on the bench as it is and with rigid boxes (with and without the flag):
the closed-form slide of tests/wrapenv/test_bench_mechanics.py at 0.6 g; the 2- and 3-layer
columnar examples unwrapped at 0.3 g; the 3-layer example in Kraft bands at 0.5 g. Per case:
CPU s and the bundles' largest displacement along the motion at the end, or why the run became
unphysical.

    taskset -c 0 python -m benchmarks.bench_rigid
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.bench_speed import slip_error
from benchmarks.bench_warm_start import world_file, worlds_loaded_from
from wrapenv.bench import SimSettings, run_level
from wrapenv.load import LoadUnit
from wrapenv.profile import PulseProfile
from wrapenv.wrap import WrapFormat

#: btContactSolverInfo's solver mode flag (Bullet's btContactSolverInfo.h)
SOLVER_DISABLE_VELOCITY_DEPENDENT_FRICTION_DIRECTION = 64
CASES = (  # (name, load, wrap, level g)
    ("2 layers, 0.3 g", "examples/pet_2layer_columnar.toml", None, 0.3),
    ("3 layers, 0.3 g", "examples/pet_3layer_columnar.toml", None, 0.3),
    ("3 layers, Kraft bands, 0.5 g", "examples/pet_3layer_columnar.toml",
     "examples/wrap_kraft_3layer.toml", 0.5),
)


def case(load: LoadUnit, wrap: WrapFormat | None, level_g: float) -> tuple[float, str]:
    """CPU s, and the largest displacement along the motion or why the run is invalid."""
    t0 = time.process_time()
    trace = run_level(load.layout(), PulseProfile(level_g), SimSettings(), wrap=wrap)
    cpu = time.process_time() - t0
    dx = trace.bundle_pos[-1, :, 0] - trace.bundle_pos[0, :, 0]
    if not trace.valid:
        return cpu, f"invalid: {trace.invalid_reason}"
    return cpu, f"{1e3 * np.max(np.abs(dx)):.1f} mm"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="runs per case, alternated")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as folder:
        plain = world_file(Path(folder), 0)
        steady = world_file(Path(folder), SOLVER_DISABLE_VELOCITY_DEPENDENT_FRICTION_DIRECTION)
        variants = (("the bench (reduced coordinates)", None, False),
                    ("rigid boxes", plain, True),
                    ("rigid, friction directions not from velocity", steady, True))
        print("closed-form slide at 0.6 g: " + ", ".join(
            f"{label} {_slip(world, rigid)}" for label, world, rigid in variants))
        for name, load_path, wrap_path, level_g in CASES:
            load = LoadUnit.from_toml(load_path)
            wrap = WrapFormat.from_toml(wrap_path, load.load_height_m) if wrap_path else None
            cpu: dict[str, list[float]] = {label: [] for label, _, _ in variants}
            end: dict[str, str] = {}
            for _ in range(args.repeat):
                for label, world, rigid in variants:
                    with worlds_loaded_from(world, rigid):
                        seconds, end[label] = case(load, wrap, level_g)
                    cpu[label].append(seconds)
            base = statistics.median(cpu[variants[0][0]])
            print(f"{name} (CPU s, median of {args.repeat}; the end of the last run):")
            for label, _, _ in variants:
                median = statistics.median(cpu[label])
                print(f"  {label}: {median:.2f} s ({median / base:.2f} x), {end[label]}",
                      flush=True)


def _slip(world: Path | None, rigid: bool) -> str:
    with worlds_loaded_from(world, rigid):
        return slip_error(SimSettings())


if __name__ == "__main__":
    main()
