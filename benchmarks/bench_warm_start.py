"""Would warm-starting Bullet's multibody solver let a wrapped unit converge in fewer iterations?

Issue 15's bench costs what plain PyBullet costs at the same iterations, but a wrapped unit
needs 50 where the issue's plain run takes 20: each step solves the squeezed stack's contacts
from zero, because Bullet warm-starts the contacts of reduced-coordinate bodies only with the
solver mode SOLVER_USE_ARTICULATED_WARMSTARTING, which pybullet's `setPhysicsEngineParameter`
cannot set. `loadBullet` can: Bullet's world importer copies the solver mode of the file's world
into the world it loads into. So an empty world is saved (`saveBullet`), its solver mode found
(the int after the iteration count, set to a marker value) and patched, and each bench world
loads it before the bench sets its own parameters again; the importer also resets the residual
threshold, which pybullet sets to 1e-7, so that is set again too. A control run loads the
unpatched file: it must reproduce the default bench exactly.

Per run: the 3-layer example wrapped in Kraft bands and by the machine's default Kraft program,
at 0.2 g (where an unconverged solve creeps) and 0.5 g, CPU s of the level, and the bundles'
largest and mean displacement along the motion at its end (the converged reference: 100
iterations).

    taskset -c 0 python -m benchmarks.bench_warm_start [--iterations 10 20 50 100]
"""

from __future__ import annotations

import argparse
import contextlib
import tempfile
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

import wrapenv.bench
from wrapenv.bench import SimSettings, run_level
from wrapenv.bullet import BulletWorld, load_saved_world, solver_mode_world
from wrapenv.load import LoadUnit
from wrapenv.profile import PulseProfile
from wrapenv.trace import Trace
from wrapenv.wrap import WrapFormat

EXAMPLE = "examples/pet_3layer_columnar.toml"
#: the Kraft band example, and the machine's default Kraft program (3 + 3 wraps and a 50 %
#: spiral at 800 N), which crept 15-25 mm at 0.2 g under 20 iterations (`SimSettings`)
WRAPS = ("examples/wrap_kraft_3layer.toml", "examples/program_kraft_default.toml")
#: btContactSolverInfo's solver mode flag (Bullet's btContactSolverInfo.h)
SOLVER_USE_ARTICULATED_WARMSTARTING = 4096


@contextlib.contextmanager
def worlds_loaded_from(path: Path | None, rigid: bool = False,
                       parameters: dict[str, Any] | None = None) -> Iterator[None]:
    """Every bench world built meanwhile loads `path` first (None: the bench as it is); `rigid`
    makes its boxes maximal-coordinate (rigid) bodies as pybullet makes them (torques as
    external torques; `SimSettings.rigid_boxes` is the bench's own), whose velocities are read
    from Bullet, as when these variants were first measured; `parameters` are engine
    parameters set after the bench's own."""
    if path is None:
        yield
        return
    saved = path

    class Loaded(BulletWorld):
        def _set_parameters(self, solver_iterations: int, contact_erp: float | None) -> None:
            client = self._client  # the world's own pybullet client (benchmark only)
            load_saved_world(client, saved)
            if rigid:
                create = client.createMultiBody

                def create_rigid(*args: Any, **kwargs: Any) -> int:
                    return create(*args, **(kwargs | {"useMaximalCoordinates": True}))

                client.createMultiBody = create_rigid
            super()._set_parameters(solver_iterations, contact_erp)
            if parameters:
                client.setPhysicsEngineParameter(**parameters)

        def state(self, indices: Sequence[int]) -> tuple[np.ndarray, ...]:
            if not rigid:
                return super().state(indices)
            return (*self.poses(indices), *self.velocities(indices))

    wrapenv.bench.BulletWorld = Loaded  # type: ignore[misc]
    try:
        yield
    finally:
        wrapenv.bench.BulletWorld = BulletWorld  # type: ignore[misc]


def timed_level(load: LoadUnit, wrap: WrapFormat, level_g: float,
                settings: SimSettings) -> tuple[float, Trace, np.ndarray]:
    """CPU s of one level of a fresh unit, its trace, and each bundle's displacement (m) along
    the motion at its end."""
    t0 = time.process_time()
    trace = run_level(load.layout(), PulseProfile(level_g), settings, wrap=wrap)
    cpu = time.process_time() - t0
    return cpu, trace, trace.bundle_pos_m[-1, :, 0] - trace.bundle_pos_m[0, :, 0]


def level(load: LoadUnit, wrap: WrapFormat, level_g: float, iterations: int,
          world: Path | None) -> tuple[float, float, float]:
    """CPU s, largest and mean displacement (m) along the motion of the bundles."""
    with worlds_loaded_from(world):
        cpu, _, dx = timed_level(load, wrap, level_g,
                                 SimSettings(solver_iterations=iterations))
    return cpu, float(np.max(np.abs(dx))), float(np.mean(dx))


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iterations", type=int, nargs="+", default=[10, 20, 50, 100])
    parser.add_argument("--levels", type=float, nargs="+", default=[0.2, 0.5])
    args = parser.parse_args(argv)
    load = LoadUnit.from_toml(EXAMPLE)
    with tempfile.TemporaryDirectory() as folder:
        plain = solver_mode_world(Path(folder), 0)
        warm = solver_mode_world(Path(folder), SOLVER_USE_ARTICULATED_WARMSTARTING)
        default = SimSettings().solver_iterations
        for path, g in ((p, g) for p in WRAPS for g in args.levels):
            wrap = WrapFormat.from_toml(path, load.load_height_m)
            base = level(load, wrap, g, default, None)
            control = level(load, wrap, g, default, plain)
            print(f"{path}, {g} g: a world loaded from the unpatched file reproduces the bench "
                  f"at {default} iterations: "
                  f"{'yes' if control[1:] == base[1:] else 'NO'} ({1e3 * control[1]:.3f} mm "
                  f"against {1e3 * base[1]:.3f} mm)")
            print(f"{'iterations':>10}  {'warm start':>10}  {'CPU s':>6}  {'max mm':>7}  "
                  f"{'mean mm':>7}")
            for n in args.iterations:
                for label, world in (("no", None), ("yes", warm)):
                    cpu, largest, mean = level(load, wrap, g, n, world)
                    print(f"{n:>10}  {label:>10}  {cpu:6.2f}  {1e3 * largest:7.2f}  "
                          f"{1e3 * mean:7.2f}", flush=True)


if __name__ == "__main__":
    main()
