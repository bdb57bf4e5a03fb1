"""Over-relaxation and soft contacts: two more ways 20 iterations might converge a squeezed stack.

Issue 15 times the bench against plain PyBullet at 20 solver iterations, and a wrapped unit needs
50 (benchmarks/bench_solver_options.py: no engine parameter pybullet exposes lets 20 do it).
Two levers remain outside that list:

- **Over-relaxation** (SOR): Bullet's multibody contact solve scales each Gauss-Seidel update by
  the solver info's `m_sor` (`btMultiBodyConstraintSolver`: `m_jacDiagABInv = relaxation / d`),
  which speeds a stiff chain's convergence in textbook cases. pybullet does not expose it, but
  `loadBullet` copies a saved world's whole solver info into the world it loads into, so an
  empty world is saved, its `m_sor` (the 7th double of the solver info, 11 doubles before the
  iteration count) patched, and each bench world loads it first (benchmarks/bench_warm_start.py).
- **Soft contacts**: each bundle given a contact stiffness and critical damping
  (`changeDynamics(contactStiffness, contactDamping)`), which regularise the contact problem as
  a constraint-force mixing does, but only where bundles touch; a model change, so its own
  converged answer (100 iterations, the same stiffness) is the reference of its row.

Per run: the 3-layer example with the Kraft bands and the machine's default Kraft program (the
cases of bench_warm_start and bench_solver_options), at 0.2 g and 0.5 g: CPU s of the level, the
bundles' largest displacement along the motion, and how far that lies from the converged
answer. Run it on one quiet core:

    taskset -c 0 python -m benchmarks.bench_relaxation [--levels 0.2 0.5]
"""

from __future__ import annotations

import argparse
import contextlib
import math
import struct
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path

import wrapenv.bench
from benchmarks.bench_solver_options import level
from benchmarks.bench_warm_start import (
    EXAMPLE,
    WRAPS,
    worlds_loaded_from,
)
from wrapenv.bullet import BulletWorld, saved_empty_world
from wrapenv.load import LoadUnit
from wrapenv.wrap import WrapFormat

#: m_sor's place in btContactSolverInfoDoubleData: doubles before m_numIterations
SOR_DOUBLES_BEFORE_ITERATIONS = 11
#: 1.0: the saved world unpatched, a control that must reproduce the plain 20-iteration row
SORS = (1.0, 1.1, 1.3, 1.6)
#: contact stiffness per bundle (N/m), critically damped for a bundle's mass
STIFFNESSES_N_PER_M = (1e5, 1e6)
#: the heaviest body that is a bundle (the pallet is 25 kg)
BUNDLE_MAX_KG = 20.0


def sor_world(folder: Path, sor: float) -> Path:
    """An empty world saved by pybullet with its solver info's relaxation set to `sor`."""
    path = folder / f"world-sor-{sor}.bullet"
    data, iterations_at = saved_empty_world(path)
    if not data.startswith(b"BULLETd"):
        raise RuntimeError(f"{path}: not a double-precision world, m_sor is not where expected")
    at = iterations_at - 8 * SOR_DOUBLES_BEFORE_ITERATIONS
    (saved,) = struct.unpack_from("<d", data, at)
    if saved != 1.0:  # Bullet's default relaxation
        raise RuntimeError(f"{path}: found {saved} where m_sor (1.0) should be")
    struct.pack_into("<d", data, at, sor)
    path.write_bytes(bytes(data))
    return path


@contextlib.contextmanager
def soft_bundles(stiffness_n_per_m: float) -> Iterator[None]:
    """Every bundle added meanwhile gets this contact stiffness, critically damped."""
    class Soft(BulletWorld):
        def add_box(self, size_m: Sequence[float], centre_m: Sequence[float], mass_kg: float,
                    friction: float, rgba: Sequence[float] = (0.6, 0.6, 0.6, 1.0)) -> int:
            index = super().add_box(size_m, centre_m, mass_kg, friction, rgba)
            if 0 < mass_kg < BUNDLE_MAX_KG:
                damping = 2 * math.sqrt(stiffness_n_per_m * mass_kg)
                self._client.changeDynamics(self._ids[index], -1,
                                            contactStiffness=stiffness_n_per_m,
                                            contactDamping=damping)
            return index

    wrapenv.bench.BulletWorld = Soft  # type: ignore[misc]
    try:
        yield
    finally:
        wrapenv.bench.BulletWorld = BulletWorld  # type: ignore[misc]


def print_row(label: str, run: tuple[float, float, bool], converged: float) -> None:
    cpu, largest, rested = run
    print(f"  {label:34s} {cpu:6.2f} s  {1e3 * largest:7.2f} mm  "
          f"{1e3 * (largest - converged):+7.2f} mm"
          + ("" if rested else "  (did not come to rest: waited out)"), flush=True)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--levels", type=float, nargs="+", default=[0.2, 0.5])
    args = parser.parse_args(argv)
    load = LoadUnit.from_toml(EXAMPLE)
    with tempfile.TemporaryDirectory() as folder:
        sors = {sor: sor_world(Path(folder), sor) for sor in SORS}
        for path, g in ((p, g) for p in WRAPS for g in args.levels):
            wrap = WrapFormat.from_toml(path, load.load_height_m)
            print(f"\n{path}, {g} g: CPU s, largest displacement (mm), off the converged answer",
                  flush=True)
            converged = level(load, wrap, g, 100, contextlib.nullcontext())
            print_row("100 it (converged)", converged, converged[1])
            for n in (50, 20):
                print_row(f"{n} it", level(load, wrap, g, n, contextlib.nullcontext()),
                          converged[1])
            for sor, world in sors.items():
                print_row(f"20 it, over-relaxation {sor}",
                          level(load, wrap, g, 20, worlds_loaded_from(world)), converged[1])
            for k in STIFFNESSES_N_PER_M:
                soft = level(load, wrap, g, 100, soft_bundles(k))
                print_row(f"soft contacts {k:.0e} N/m, 100 it", soft, soft[1])
                print_row(f"soft contacts {k:.0e} N/m, 20 it",
                          level(load, wrap, g, 20, soft_bundles(k)), soft[1])


if __name__ == "__main__":
    main()
