"""How much the verdicts lean on the assumptions docs/materials.md marks [A]: the examples'
friction, Kraft's glued seam, either web's stiffness (LLDPE's applied stiffness is two
assumptions multiplied; Kraft's is derived, and no bench test fits it), the load's give (the
bundles' edge stiffness, which no source gives), the membrane model's shear and damping ratios,
the web's cross-direction share of its machine-direction law (`cd_ratio`, which the panels
between the rings have), the pulse's shape where no source gives it (the ramp to the level, the
sled's braking after it), and how far down onto the pallet the bottom wraps' web reaches
(`ONTO_PALLET_M`).

The programs are the answers that matter: on Kraft, the least web of `recommend`'s space (one
bottom wrap, a touching spiral, one top wrap), which it answers on the examples, here at half
the yield force (its margin is about the same at 20-50 %: benchmarks/tension_cap.py); on LLDPE,
the machine's default program (examples/program_lldpe_default.toml, its bottom wraps where the
search lays them). Each runs on the 2- and 3-layer columnar examples, both sides along the
motion, 16 h after wrapping (relaxed, as `recommend` judges), through the EUMOS sequence to 0.5
g on the nominal load. Variants: the examples' friction (nominal), the bench's default friction
(the CTU Code's figures), the examples' pallet-bundle and bundle-bundle coefficients 0.05 and
0.10 lower (kinetic in the same ratio), a seam of 1000 N/m (the low end of P5's range) instead
of 3000, either web's stiffness halved and doubled (Kraft's P1 range is 0.6-2 x its figure),
either web's `cd_ratio` halved, and, for either web, the bundles' edges a tenth, a quarter and
four times as stiff (`LoadUnit.with_give`; the wrap model sets the web and the edges in series
as springs, so on Kraft, the stiffer of the two by far, the edges decide how far the load
moves), the membrane model's shear stiffness of a panel and damping of every element halved and
doubled, the pulse ramped to its level in 0.02 or 0.15 s instead of 0.05 s, the sled braking at
0.125 or 0.5 of the level instead of 0.25, and the bottom wraps' web from the sled surface (the
pallet's whole side) or over 22 mm of it (its deck boards) instead of 44 mm (the deck boards and
the cross boards under them). Prints a Markdown table: the highest level passed and the margin
at 0.5 g.

    python -m benchmarks.sensitivity [--workers 2]
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

from benchmarks.tension_cap import (
    HOURS_SINCE_WRAPPING,
    TARGET_G,
    lightest,
    print_table,
    to_target,
)
from wrapenv.design import ProgramSpace
from wrapenv.load import ORIENTATIONS, Friction, FrictionPair, LoadUnit, Orientation
from wrapenv.profile import PulseProfile
from wrapenv.program import Program
from wrapenv.wrap import WrapFormat

EXAMPLES = ("examples/pet_2layer_columnar.toml", "examples/pet_3layer_columnar.toml")
LLDPE_PROGRAM = "examples/program_lldpe_default.toml"
#: The pulse's variants: PulseProfile's ramp and braking, which no source gives [A].
PULSES: dict[str, Callable[[float], PulseProfile]] = {
    "ramp 0.02 s": lambda g: PulseProfile(g, ramp_s=0.02),
    "ramp 0.15 s": lambda g: PulseProfile(g, ramp_s=0.15),
    "braking 0.125 x the level": lambda g: PulseProfile(g, decel_ratio=0.125),
    "braking 0.5 x the level": lambda g: PulseProfile(g, decel_ratio=0.5),
}
#: How far down onto the pallet the bottom wraps' web reaches, against the space's
#: `ONTO_PALLET_M` [A]: the whole pallet side, as until 2026-11-27, or its deck boards only.
ONTO_PALLET: dict[str, float] = {
    "bottom wraps from the sled surface": math.inf,
    "bottom wraps 22 mm onto the pallet": 0.022,
}
#: The bundles' edges this many times as stiff as the load file gives them (the load's give
#: [A], docs/materials.md B1: no source gives it; its accepted range is 1e4-5e6 N/m per m
#: against the preset's 6e5).
EDGES = ("edge stiffness x 0.1", "edge stiffness x 0.25", "edge stiffness x 4")
#: The membrane model's figures no source gives [A] (`Material.shear_ratio`, the panels' shear
#: stiffness over the web's, and `Material.damping_ratio`, each element's damping as a
#: fraction of critical): halved and doubled.
MEMBRANE = ("panel shear x 0.5", "panel shear x 2", "wrap damping x 0.5", "wrap damping x 2")
#: (material, variant): what each variant changes is in `variant`.
VARIANTS = (("kraft", "nominal"), ("kraft", "CTU default friction"),
            ("kraft", "friction -0.05"), ("kraft", "friction -0.10"), ("kraft", "seam 1000 N/m"),
            ("kraft", "stiffness x 0.5"), ("kraft", "stiffness x 2"),
            ("kraft", "cross direction x 0.5"), ("lldpe", "nominal"),
            ("lldpe", "stiffness x 0.5"), ("lldpe", "stiffness x 2"),
            ("lldpe", "cross direction x 0.5"),
            *((m, v) for m in ("kraft", "lldpe")
              for v in (*EDGES, *MEMBRANE, *PULSES, *ONTO_PALLET)))


def _lower(friction: Friction, delta: float) -> Friction:
    """The pallet-bundle and bundle-bundle coefficients `delta` lower, kinetic in ratio."""
    def lowered(pair: FrictionPair) -> FrictionPair:
        static = pair.static - delta
        return FrictionPair(static, pair.kinetic * static / pair.static)
    return replace(friction, pallet_bundle=lowered(friction.pallet_bundle),
                   bundle_bundle=lowered(friction.bundle_bundle))


def _program(space: ProgramSpace, pallet_height_m: float, material: str, variant: str
             ) -> Program:
    """The answer that matters on `material`, its bottom wraps where `variant` lays them."""
    if material == "kraft":
        program = lightest(space, 0.5 * space.material.yield_force_n_per_m * space.web_width_m)
    else:
        given = WrapFormat.from_toml(LLDPE_PROGRAM, space.load_height_m).program
        assert given is not None
        program = replace(given, bottom_from_m=space.bottom_from_m)
    if variant in ONTO_PALLET:
        program = replace(program,
                          bottom_from_m=max(0.0, pallet_height_m - ONTO_PALLET[variant]))
    return program


def _unit_and_wrap(load_path: str, material: str, variant: str) -> tuple[LoadUnit, WrapFormat]:
    load = LoadUnit.from_toml(load_path)
    space = ProgramSpace.for_layout(load.layout(), material)
    wrap = space.laid(_program(space, load.pallet.height_m, material, variant))
    if variant == "CTU default friction":
        load = load.with_friction(replace(Friction(), sled_pallet=load.friction.sled_pallet))
    elif variant.startswith("friction -"):
        load = load.with_friction(_lower(load.friction, float(variant.split("-")[1])))
    elif variant == "seam 1000 N/m":
        wrap = replace(wrap, material=replace(wrap.material, seam_strength_n_per_m=1000.0))
    elif variant == "cross direction x 0.5":
        wrap = replace(wrap, material=replace(wrap.material, cd_ratio=wrap.material.cd_ratio / 2))
    elif variant in MEMBRANE:
        field = "shear_ratio" if variant.startswith("panel shear") else "damping_ratio"
        scale = float(variant.rsplit(" x ", 1)[1])
        card = replace(wrap.material, **{field: getattr(wrap.material, field) * scale})
        wrap = replace(wrap, material=card)
    elif variant.startswith("stiffness x "):
        wrap = wrap.scaled(stiffness_scale=float(variant.removeprefix("stiffness x ")))
    elif variant.startswith("edge stiffness x "):
        load = load.with_give(float(variant.removeprefix("edge stiffness x ")))
    return load, wrap.relaxed(HOURS_SINCE_WRAPPING)


def case(args: tuple[str, str, str, Orientation]) -> str:
    load_path, material, variant, orientation = args
    load, wrap = _unit_and_wrap(load_path, material, variant)
    row, _ = to_target(load_path, load, wrap, orientation, PULSES.get(variant, PulseProfile))
    return row.format(f"{material} | {variant} | {orientation}")


def main() -> None:
    cases = [(load, m, v, o) for load in EXAMPLES for m, v in VARIANTS for o in ORIENTATIONS]
    print_table(("load", "web", "variant", "side along the motion",
                 f"highest passed (to {TARGET_G} g)", f"margin at {TARGET_G} g"), case, cases,
                __doc__.splitlines()[0])


if __name__ == "__main__":
    main()
