"""Does any other setting of Bullet's solver let a wrapped unit converge at 20 iterations?

Issue 15 times the bench against plain PyBullet at 20 solver iterations; a wrapped unit needs 50
(`SimSettings.solver_iterations`: at 20 a squeezed stack creeps and comes to rest late).
Here each engine parameter pybullet's `setPhysicsEngineParameter` offers for the contact solve
is set, one at a time, on top of the bench's 20-iteration solve: the MLCP solvers (projected
Gauss-Seidel and Dantzig's pivoting, which solve the contacts as one system), cone friction off,
a friction ERP, no contact slop, a tighter contact-breaking threshold, more inner iterations.
And one that could make the bench's own 50 iterations cheaper: a residual threshold above
pybullet's 1e-7, below which the solve ends before its last iteration (Bullet's
`m_leastSquaresResidualThreshold`, the largest squared velocity error of a constraint row).

Per run: the 3-layer example with the machine's default Kraft program and with the Kraft bands
(the cases of benchmarks/bench_warm_start.py), at 0.2 g (where an unconverged solve creeps) and
0.5 g: CPU s of the level, the bundles' largest displacement along the motion at its end, and
how far that lies from the converged answer (100 iterations). Run it on one quiet core:

    taskset -c 0 python -m benchmarks.bench_solver_options [--levels 0.2 0.5] [--no-dantzig]
"""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Iterator
from typing import Any

import numpy as np
import pybullet as pb

import wrapenv.bench
from benchmarks.bench_warm_start import EXAMPLE, WRAPS, timed_level
from wrapenv.bench import SimSettings
from wrapenv.bullet import BulletWorld
from wrapenv.load import LoadUnit
from wrapenv.profile import PulseProfile
from wrapenv.wrap import WrapFormat

ISSUE_ITERATIONS = 20
#: Bullet's contact-breaking threshold is a process-wide global (gContactBreakingThreshold), not
#: a world's: a world that sets it sets it for every later world, so it is put back after.
BULLET_BREAKING_THRESHOLD_M = 0.02
#: (label, iterations, engine parameters set after the bench's own)
SOLVES: tuple[tuple[str, int, dict[str, Any]], ...] = (
    ("100 it (converged)", 100, {}),
    ("50 it (the bench)", 50, {}),
    ("20 it", ISSUE_ITERATIONS, {}),
    ("20 it, cone friction off", ISSUE_ITERATIONS, {"enableConeFriction": 0}),
    ("20 it, friction ERP 0.2", ISSUE_ITERATIONS, {"frictionERP": 0.2}),
    ("20 it, contact slop 0", ISSUE_ITERATIONS, {"contactSlop": 0.0}),
    ("20 it, breaking threshold 1 mm", ISSUE_ITERATIONS, {"contactBreakingThreshold": 0.001}),
    ("20 it, 4 inner iterations", ISSUE_ITERATIONS, {"numNonContactInnerIterations": 4}),
    ("50 it, residual threshold 1e-6", 50, {"solverResidualThreshold": 1e-6}),
    ("50 it, residual threshold 1e-5", 50, {"solverResidualThreshold": 1e-5}),
    ("50 it, residual threshold 1e-4", 50, {"solverResidualThreshold": 1e-4}),
    ("20 it, MLCP + PGS", ISSUE_ITERATIONS,
     {"constraintSolverType": pb.CONSTRAINT_SOLVER_LCP_PGS}),
    ("20 it, MLCP + Dantzig", ISSUE_ITERATIONS,
     {"constraintSolverType": pb.CONSTRAINT_SOLVER_LCP_DANTZIG}),
)


@contextlib.contextmanager
def engine_parameters(parameters: dict[str, Any]) -> Iterator[None]:
    """Every bench world built meanwhile sets `parameters` after its own (benchmark only)."""
    class Tuned(BulletWorld):
        def _set_parameters(self, solver_iterations: int, contact_erp: float | None) -> None:
            super()._set_parameters(solver_iterations, contact_erp)
            if parameters:
                self._client.setPhysicsEngineParameter(**parameters)

    wrapenv.bench.BulletWorld = Tuned  # type: ignore[misc]
    try:
        yield
    finally:
        wrapenv.bench.BulletWorld = BulletWorld  # type: ignore[misc]
        if "contactBreakingThreshold" in parameters:
            client = pb.connect(pb.DIRECT)
            pb.setPhysicsEngineParameter(contactBreakingThreshold=BULLET_BREAKING_THRESHOLD_M,
                                         physicsClientId=client)
            pb.disconnect(client)


def level(load: LoadUnit, wrap: WrapFormat, level_g: float, iterations: int,
          worlds: contextlib.AbstractContextManager[None]) -> tuple[float, float, bool]:
    """CPU s, the bundles' largest displacement along the motion (m), and whether it rested,
    with the bench's worlds built as `worlds` builds them meanwhile."""
    settings = SimSettings(solver_iterations=iterations)
    with worlds:
        cpu, trace, dx = timed_level(load, wrap, level_g, settings)
    waited_out_s = PulseProfile(level_g).duration_s + settings.max_rest_wait_s
    rested = trace.valid and float(trace.t_s[-1]) < waited_out_s - settings.timestep_s
    return cpu, float(np.max(np.abs(dx))), rested


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--levels", type=float, nargs="+", default=[0.2, 0.5])
    parser.add_argument("--no-dantzig", action="store_true",
                        help="leave out Dantzig's solver (about a minute per level)")
    args = parser.parse_args(argv)
    load = LoadUnit.from_toml(EXAMPLE)
    solves = [s for s in SOLVES if not (args.no_dantzig and "Dantzig" in s[0])]
    for path, g in ((p, g) for p in WRAPS for g in args.levels):
        wrap = WrapFormat.from_toml(path, load.load_height_m)
        print(f"\n{path}, {g} g: CPU s, largest displacement (mm), off the converged answer",
              flush=True)
        converged = None
        for label, iterations, parameters in solves:
            cpu, largest, rested = level(load, wrap, g, iterations,
                                         engine_parameters(parameters))
            converged = largest if converged is None else converged
            print(f"  {label:32s} {cpu:6.2f} s  {1e3 * largest:7.2f} mm  "
                  f"{1e3 * (largest - converged):+7.2f} mm"
                  + ("" if rested else "  (did not come to rest: waited out)"), flush=True)


if __name__ == "__main__":
    main()
