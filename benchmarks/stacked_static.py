"""Does a bundle standing on a bundle hold below its static friction?

Statics: a bundle accelerated at a stays put on what it stands on while a < mu_s g, whatever
mu_k. The closed-form tests (tests/wrapenv/test_bench_mechanics.py) check that for a bundle on
the pallet; this checks it one contact higher, on a column of two PET bundles (the preset) on an
EUR pallet against its stop bar, every other pair gripping (1.0), at levels 7-12 % below the
bundle-bundle static coefficient and above the kinetic one, so a contact wrongly flipped to
sliding shows as a slide of centimetres. Prints a Markdown table: the top bundle's permanent
slip on the bottom one (mm) and the number of times its contact changed state, per body model
and solver iteration count. Then what the iterations change on the paper's unwrapped examples:
each level of the EUMOS sequence to its first failure, at 20 and at 50 iterations.

    python -m benchmarks.stacked_static
"""

from __future__ import annotations

import numpy as np

import wrapenv.bench
from wrapenv.bench import SimSettings, run_level, run_levels
from wrapenv.friction import StickSlip
from wrapenv.load import LoadUnit
from wrapenv.profile import PulseProfile

GRIP = {"static": 1.0, "kinetic": 1.0}
#: (level g, bundle-bundle static, kinetic): the level between the two coefficients, the
#: column's tipping level (0.28 / 0.66 m: 0.42 g) well above it; then the same at 0.4 g, where
#: the column rocks and statics alone does not decide; and a level far below static, a control.
CASES = ((0.25, 0.28, 0.22), (0.3, 0.32, 0.28), (0.4, 0.45, 0.35), (0.3, 0.45, 0.35))
ITERATIONS = (20, 50, 100)
EXAMPLES = ("examples/pet_2layer_columnar.toml", "examples/pet_3layer_columnar.toml")
EXAMPLE_LEVELS_G = (0.2, 0.3, 0.4, 0.5)


def column(static: float, kinetic: float) -> LoadUnit:
    return LoadUnit.from_dict({
        "pallet": {"preset": "EUR"}, "bundle": {"preset": "PET6x1.5L"},
        "stack": {"layers": 2, "pattern": "explicit", "positions": [[0.3, 0.0]]},
        "friction": {"sled_pallet": GRIP, "pallet_bundle": GRIP,
                     "bundle_bundle": {"static": static, "kinetic": kinetic}},
        "fixture": {"pallet_stopper": True}})


class _Counting(StickSlip):
    """StickSlip that counts the contact changes of every instance."""

    changes = 0

    def update(self, pos: np.ndarray, rot: np.ndarray, vel: np.ndarray,
               omega: np.ndarray) -> list[int]:
        changed = super().update(pos, rot, vel, omega)
        _Counting.changes += bool(changed)
        return changed


def slip_mm(level_g: float, static: float, kinetic: float, settings: SimSettings) -> float:
    trace = run_level(column(static, kinetic).layout(), PulseProfile(level_g), settings)
    rel = trace.bundle_pos_m[:, 1, 0] - trace.bundle_pos_m[:, 0, 0]
    return float(1e3 * (rel[-1] - rel[0]))


def _mm(metres: float | None) -> str:
    return "-" if metres is None else f"{1e3 * metres:.1f} mm"


def _slip_table() -> None:
    print("| level | bundle-bundle static / kinetic | boxes | iterations | top bundle's slip | "
          "contact changes |")
    print("|---|---|---|---|---|---|")
    wrapenv.bench.StickSlip = _Counting  # type: ignore[misc]
    try:
        for level_g, static, kinetic in CASES:
            for rigid in (False, True):
                for iterations in ITERATIONS:
                    _Counting.changes = 0
                    settings = SimSettings(solver_iterations=iterations, rigid_boxes=rigid)
                    mm = slip_mm(level_g, static, kinetic, settings)
                    print(f"| {level_g} g | {static} / {kinetic} "
                          f"| {'rigid' if rigid else 'reduced'} | {iterations} | {mm:+.2f} mm "
                          f"| {_Counting.changes} |")
    finally:
        wrapenv.bench.StickSlip = StickSlip  # type: ignore[misc]


def _examples_table() -> None:
    print("| example | iterations | level | result | elastic max | permanent (level) |")
    print("|---|---|---|---|---|---|")
    for path in EXAMPLES:
        for iterations in (20, 50):
            run = run_levels(LoadUnit.from_toml(path), EXAMPLE_LEVELS_G,
                             SimSettings(solver_iterations=iterations), stop_at_failure=True)
            for v in run.verdict.levels:
                print(f"| {path} | {iterations} | {v.level_g} g | {'PASS' if v.passed else 'FAIL'} "
                      f"| {_mm(v.elastic_max_m)} | {_mm(v.permanent_max_m)} |")


def main() -> None:
    _slip_table()
    print()
    _examples_table()


if __name__ == "__main__":
    main()
