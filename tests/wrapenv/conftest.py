"""What the bench's tests share: a web weak enough to tear, on a unit that slides into it."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from wrapenv.load import FrictionPair, LoadUnit
from wrapenv.wrap import WrapFormat

#: A custom card that yields at 0.2 % and breaks at 0.4 % strain.
WEAK_WEB: dict[str, Any] = {"grammage_kg_m2": 0.05, "stiffness_n_per_m": 4e4,
                            "yield_strain": 0.002, "break_strain": 0.004,
                            "hardening_ratio": 0.5}


def slick_two_layers() -> LoadUnit:
    """The 2-layer example with a slippery pallet deck (0.2/0.15) and a stopper behind it."""
    load = LoadUnit.from_toml("examples/pet_2layer_columnar.toml")
    friction = replace(load.friction, pallet_bundle=FrictionPair(0.2, 0.15))
    return replace(load.with_friction(friction), pallet_stopper=True)


def weak_wrap_on_a_slick_unit() -> tuple[LoadUnit, WrapFormat]:
    """One layer of `WEAK_WEB` at 20 N over the whole slick 2-layer unit: it tears at 0.5 g
    (tests/wrapenv/test_wrap_physics.py)."""
    wrap = WrapFormat.from_dict({"material": WEAK_WEB, "web_width_m": 0.5, "band": [
        {"from_m": 0.0, "to_m": 0.804, "layers": 1, "tension_n": 20.0}]})
    return slick_two_layers(), wrap


def kraft_example() -> tuple[LoadUnit, WrapFormat]:
    """The 2-layer example and its bundled Kraft wrap."""
    load = LoadUnit.from_toml("examples/pet_2layer_columnar.toml")
    return load, WrapFormat.from_toml("examples/wrap_kraft_2layer.toml", load.load_height_m)
