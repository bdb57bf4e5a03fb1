"""The bench against plain PyBullet (issue 15), measured side by side in one run.

Plain PyBullet: the same boxes as the bench (sled deck, stopper, pallet and the 48 bundles of
examples/pet_3layer_columnar.toml, from `wrapenv.scene.BenchScene`), each with Bullet's own
single friction coefficient, chosen once so that the products Bullet forms give each pair its
static value, and every other dynamics setting PyBullet's default. The same sled pulse as an
inertial field (0.3 s still, then the 0.5 g pulse), dt 1/240 s, 20 solver iterations, no
stick-slip, no wrap, nothing read back while it steps.

The bench: `run_level` on the same unit at 0.5 g, Kraft-wrapped (examples/wrap_kraft_3layer.toml),
with default settings: world building, settling and laying the wrap, the pulse, rest detection
and the trace. Its level ends when nothing more can happen, so it simulates less time than the
issue's plain run; the plain run is therefore timed for the 4.5 s the issue measured, and for
exactly as long as the bench's level lasted (settling plus the trace), the like-for-like figure
per simulated second. A wrapped unit is solved with `SimSettings.solver_iterations` (50)
where the issue's plain run has 20: the plain 4.5 s is also timed with as many, and with the
iterations a new PyBullet world has (read from the engine: 50 in pybullet 3.2.7), plain PyBullet
as it ships. The bench also runs with rigid boxes (`SimSettings.rigid_boxes`), and plain
PyBullet with rigid boxes too (20 iterations), for a like-for-like count of that choice.

Each timing is the median of `--repeat` runs, alternated, inside this process (imports and
interpreter start-up excluded, which only dilutes a ratio towards 1); wall and CPU time are both
printed (CPU time is less disturbed by other work on the machine). `--whole-process` also times
each run as a fresh interpreter, imports included, as the issue measured; `--instructions`
counts each run's instructions with valgrind's callgrind (an interpreter that makes the run minus
one that only imports), which load on the machine does not disturb. It also counts the contact
points Bullet holds at rest after each run: the solver's work per iteration grows with them, and
a wrapped unit's squeezed layers hold about twice the plain stack's. Run it on one core:

    taskset -c 0 python -m benchmarks.bench_baseline [--whole-process] [--instructions]
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from functools import partial

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pybullet as pb  # noqa: E402

from wrapenv.bench import BenchUnit, SimSettings, run_level  # noqa: E402
from wrapenv.load import Layout, LoadUnit  # noqa: E402
from wrapenv.profile import G, PulseProfile  # noqa: E402
from wrapenv.scene import PALLET_NAME, SLED, BenchScene  # noqa: E402
from wrapenv.wrap import WrapFormat  # noqa: E402

EXAMPLE = "examples/pet_3layer_columnar.toml"
WRAP = "examples/wrap_kraft_3layer.toml"
LEVEL_G = 0.5
ISSUE_SIM_S = 4.5
#: how many of the timed runs are the bench's own (first in the list): each is compared with
#: every plain run
BENCH_RUNS = 2
SETTLE_S = SimSettings().settle_s


def part_coefficients(scene: BenchScene) -> dict[int, float]:
    """One coefficient per part (by world index, `BenchScene.parts`) whose products are the
    static pair values: bundle-bundle = b², pallet-bundle = p b, sled-pallet = s p."""
    f = scene.layout.friction
    bundle = f.bundle_bundle.static ** 0.5
    pallet = f.pallet_bundle.static / bundle
    out = {scene.index(SLED): f.sled_pallet.static / pallet, scene.index(PALLET_NAME): pallet}
    out.update({scene.index(b.name): bundle for b in scene.layout.bundles})
    return out


def plain_pybullet(layout: Layout, profile: PulseProfile, sim_s: float,
                   timestep_s: float = 1 / 240, iterations: int = 20,
                   rigid: bool = False) -> int:
    """The plain run: build, settle still for `SETTLE_S`, run the pulse, `sim_s` in all
    (`rigid`: boxes with maximal coordinates, not `createMultiBody`'s default).
    Returns how many contact points Bullet holds at the end."""
    client = pb.connect(pb.DIRECT)
    try:
        pb.setTimeStep(timestep_s, physicsClientId=client)
        pb.setPhysicsEngineParameter(numSolverIterations=iterations, physicsClientId=client)
        scene = BenchScene(layout)
        mu = part_coefficients(scene)
        for box, part in zip(scene.bodies, scene.parts.tolist(), strict=True):
            half = [s / 2 for s in box.size_m]
            shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=half,
                                            physicsClientId=client)
            body = pb.createMultiBody(box.mass_kg, shape, basePosition=list(box.start_centre_m),
                                      useMaximalCoordinates=rigid, physicsClientId=client)
            pb.changeDynamics(body, -1, lateralFriction=mu[part], physicsClientId=client)
        steps = round(sim_s / timestep_s)
        settle = round(SETTLE_S / timestep_s)
        for accel in profile.accel((np.arange(steps) - settle) * timestep_s).tolist():
            pb.setGravity(-accel, 0.0, -G, physicsClientId=client)
            pb.stepSimulation(physicsClientId=client)
        return len(pb.getContactPoints(physicsClientId=client))
    finally:
        pb.disconnect(client)


def pybullet_default_iterations() -> int:
    """The solver iterations a new PyBullet world has: plain PyBullet as it ships."""
    client = pb.connect(pb.DIRECT)
    try:
        return int(pb.getPhysicsEngineParameters(physicsClientId=client)["numSolverIterations"])
    finally:
        pb.disconnect(client)


def bench_level(rigid: bool = False) -> int:
    """The bench's level (as `run_level` runs it; `rigid`: `SimSettings.rigid_boxes`); returns
    how many contact points Bullet holds at rest after it."""
    load = LoadUnit.from_toml(EXAMPLE)
    with BenchUnit(load.layout(), SimSettings(rigid_boxes=rigid),
                   WrapFormat.from_toml(WRAP, load.load_height_m)) as unit:
        unit.level(PulseProfile(LEVEL_G))
        return unit.world.contact_points()


def plain_level(sim_s: float, iterations: int = 20, rigid: bool = False) -> int:
    return plain_pybullet(LoadUnit.from_toml(EXAMPLE).layout(), PulseProfile(LEVEL_G), sim_s,
                          iterations=iterations, rigid=rigid)


def in_a_fresh_interpreter(call: str) -> Callable[[], object]:
    """A run as its own process: interpreter start-up and imports included."""
    code = f"from benchmarks.bench_baseline import *; {call}"
    return lambda: subprocess.run([sys.executable, "-c", code], check=True,
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def instructions(call: str) -> int:
    """Instructions `call` executes: callgrind's count for an interpreter that imports this
    module and makes the call, minus one that only imports it."""
    def count(code: str) -> int:
        with tempfile.TemporaryDirectory() as folder:
            done = subprocess.run(
                ["valgrind", "--tool=callgrind", f"--callgrind-out-file={folder}/out",
                 sys.executable, "-c", code], capture_output=True, text=True, check=True)
        found = re.search(r"Collected : (\d+)", done.stderr)
        if found is None:
            raise RuntimeError(f"no instruction count from valgrind: {done.stderr[-300:]}")
        return int(found.group(1))

    imports = "from benchmarks.bench_baseline import *"
    return count(f"{imports}; {call}") - count(imports)


def child_cpu_s() -> float:
    usage = os.times()
    return usage.children_user + usage.children_system


def compare(runs: dict[str, Callable[[], object]], repeat: int, clock: Callable[[], float],
            title: str) -> None:
    """Median wall and CPU time of each run (alternated), and the ratio of each of the first
    `BENCH_RUNS` runs (the bench's) to the rest."""
    results: dict[str, list[tuple[float, float]]] = {name: [] for name in runs}
    for _ in range(repeat):
        for name, fn in runs.items():
            wall, cpu = time.perf_counter(), clock()
            fn()
            results[name].append((time.perf_counter() - wall, clock() - cpu))
    wall_s = {n: statistics.median(w for w, _ in r) for n, r in results.items()}
    cpu_s = {n: statistics.median(c for _, c in r) for n, r in results.items()}
    print(f"\n{title}, median of {repeat}")
    print(f"{'run':44s} {'wall s':>7} {'CPU s':>7}")
    for name in runs:
        print(f"{name:44s} {wall_s[name]:7.3f} {cpu_s[name]:7.3f}")
    for bench in list(runs)[:BENCH_RUNS]:
        for name in list(runs)[BENCH_RUNS:]:
            print(f"ratio {bench} / {name}: {wall_s[bench] / wall_s[name]:.2f} wall, "
                  f"{cpu_s[bench] / cpu_s[name]:.2f} CPU (goal <= 1.0)")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--whole-process", action="store_true",
                        help="also time each run as a fresh interpreter, imports included")
    parser.add_argument("--instructions", action="store_true",
                        help="also count each run's instructions (valgrind, minutes per run)")
    args = parser.parse_args(argv)
    load = LoadUnit.from_toml(EXAMPLE)
    trace = run_level(load.layout(), PulseProfile(LEVEL_G),  # warm-up, and how long it lasts
                      wrap=WrapFormat.from_toml(WRAP, load.load_height_m))
    level_sim_s = SETTLE_S + float(trace.t_s[-1])
    wrapped_iterations = SimSettings().solver_iterations
    print(f"3-layer example (48 bundles), {LEVEL_G} g, dt 1/240 s; the bench's wrapped unit "
          f"{wrapped_iterations} solver iterations, a new PyBullet world "
          f"{pybullet_default_iterations()}; CPUs {sorted(os.sched_getaffinity(0))}")
    print(f"the bench's level: {SETTLE_S:.2f} s settling + {trace.t_s[-1]:.2f} s of pulse and "
          f"rest = {level_sim_s:.2f} s simulated")
    runs: list[tuple[str, Callable[[], object], str]] = [
        ("bench, Kraft-wrapped", bench_level, "bench_level()"),
        ("bench, Kraft-wrapped, rigid boxes", partial(bench_level, True), "bench_level(True)"),
        (f"plain PyBullet, {ISSUE_SIM_S} s", partial(plain_level, ISSUE_SIM_S),
         f"plain_level({ISSUE_SIM_S})"),
        (f"plain PyBullet, {level_sim_s:.2f} s", partial(plain_level, level_sim_s),
         f"plain_level({level_sim_s})"),
    ]
    default = pybullet_default_iterations()
    for iterations in sorted({default, wrapped_iterations}):
        name = f"plain, {ISSUE_SIM_S} s, {iterations} it"
        runs.append((name + (" (PyBullet's default)" if iterations == default else ""),
                     partial(plain_level, ISSUE_SIM_S, iterations),
                     f"plain_level({ISSUE_SIM_S}, {iterations})"))
    runs.append((f"plain, {ISSUE_SIM_S} s, 20 it, rigid boxes",
                 partial(plain_level, ISSUE_SIM_S, 20, True),
                 f"plain_level({ISSUE_SIM_S}, 20, True)"))
    compare({name: fn for name, fn, _ in runs}, args.repeat, time.process_time,
            "in this process")
    bench_points, plain_points = bench_level(), plain_level(ISSUE_SIM_S)
    print(f"contact points at rest after the level: bench {bench_points}, plain "
          f"{plain_points} ({bench_points / plain_points:.2f} x: the wrap presses the bundles' "
          "side faces together, up to four points per touching pair of faces)")
    if args.whole_process:
        compare({name: in_a_fresh_interpreter(code) for name, _, code in runs}, args.repeat,
                child_cpu_s, "each run a fresh interpreter (imports included)")
    if args.instructions:
        counts = {name: instructions(code) for name, _, code in runs}
        print("\ninstructions (callgrind; the run alone, imports subtracted)")
        for name, n in counts.items():
            print(f"{name:44s} {n / 1e9:7.2f} G")
        for bench, _, _ in runs[:BENCH_RUNS]:
            for name, _, _ in runs[BENCH_RUNS:]:
                print(f"ratio {bench} / {name}: {counts[bench] / counts[name]:.2f} "
                      "(goal <= 1.0)")


if __name__ == "__main__":
    main()
