"""How light a bundle the bench can hold under a tight wrap.

A wrap's squeeze reaches Bullet as explicit forces, and a contact solve holds a squeezed stack
only up to some ratio of that squeeze to the bundles' weight: beyond it the run blows up and is
reported invalid (never a pass). Here cartons of 0.30 x 0.20 x 0.20 m, four columnar layers on
an EUR pallet against its stop bar, of several masses, each wrapped by the least web of
`recommend`'s space (one bottom wrap, a touching spiral, one top wrap) at several tensions and by
the machine's default Kraft program (examples/program_kraft_default.toml: 800 N, 3 bottom and 3
top wraps, a 50 % overlap spiral), a fresh unit at 0.2 g and at 0.5 g. Prints a Markdown table:
P pass, F fail, I invalid (with the reason), and the solver iterations of the answer (more than
50 when the squeeze was not solved with fewer and the run was made again: `run_levels`).

    python -m benchmarks.light_bundles [--workers 2]
"""

from __future__ import annotations

from benchmarks.tension_cap import lightest, print_table
from wrapenv.bench import run_levels
from wrapenv.design import ProgramSpace
from wrapenv.load import LoadUnit
from wrapenv.wrap import WrapFormat

MASSES_KG = (0.3, 0.5, 1.0, 2.0, 4.0)
LEAST_WEB_TENSIONS_N = (80.0, 200.0, 400.0, 800.0)
DEFAULT_PROGRAM = "examples/program_kraft_default.toml"
LEVELS_G = (0.2, 0.5)


def unit(mass_kg: float) -> LoadUnit:
    return LoadUnit.from_dict({
        "name": f"cartons of {mass_kg:g} kg", "pallet": {"preset": "EUR"},
        "bundle": {"length_m": 0.3, "width_m": 0.2, "height_m": 0.2, "mass_kg": mass_kg},
        "stack": {"layers": 4, "pattern": "columnar"}, "fixture": {"pallet_stopper": True}})


def _wrap(load: LoadUnit, program: str) -> WrapFormat:
    if program == "default":
        return WrapFormat.from_toml(DEFAULT_PROGRAM, load.load_height_m)
    space = ProgramSpace.for_layout(load.layout(), "kraft")
    return space.laid(lightest(space, float(program)))


def case(args: tuple[float, str]) -> str:
    mass, program = args
    load = unit(mass)
    run = run_levels(load, LEVELS_G, wrap=_wrap(load, program), fresh=True)
    cells = [("P" if v.passed else "F" if v.valid else f"I ({v.invalid_reason})")
             for v in run.verdict.levels]
    cells.append(str(run.solver_iterations))
    name = "default Kraft program (800 N)" if program == "default" else \
        f"least web at {float(program):.0f} N"
    return f"| {mass:g} kg | {name} | " + " | ".join(cells) + " |"


def main() -> None:
    cases = [(m, p) for m in MASSES_KG
             for p in (*(f"{t}" for t in LEAST_WEB_TENSIONS_N), "default")]
    print_table(("carton", "wrap", *(f"{g} g" for g in LEVELS_G), "solver iterations"), case, cases,
                __doc__.splitlines()[0])


if __name__ == "__main__":
    main()
