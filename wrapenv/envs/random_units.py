"""The distribution of load units `WrapBenchRandomEnv` draws from (its class docstring says it
in words): EUR pallets against the stopper, 1-3 layers of random bundles, friction about a
base."""

from __future__ import annotations

from typing import Any

import numpy as np

from wrapenv.calibrated import Calibration
from wrapenv.config import InputError
from wrapenv.load import PAIRS, PALLET_PRESETS, Friction, LoadUnit

RANDOM_LAYERS = (1, 3)
RANDOM_BUNDLE_LENGTH_M = (0.2, 0.4)
RANDOM_BUNDLE_WIDTH_M = (0.15, 0.3)
RANDOM_BUNDLE_HEIGHT_M = (0.2, 0.35)
RANDOM_BUNDLE_MASS_KG = (4.0, 14.0)
RANDOM_PATTERNS = ("columnar", "interlocked")
RANDOM_FRICTION_SPREAD = 0.15
RANDOM_KINETIC_RATIO = 0.8
RANDOM_MAX_TRIES = 100
#: The pallet every random unit stands on.
RANDOM_PALLET = "EUR"
#: The friction units are drawn about without a calibration: the bench's defaults.
DEFAULT_BASE = Friction()


def base_friction(calibration: Calibration | None) -> Friction:
    """The friction random units spread about: the defaults, with the calibrated pairs in
    place as the bench takes them (`Calibration.friction_over`: a pair that never slipped is
    only bounded)."""
    return DEFAULT_BASE if calibration is None else calibration.friction_over(DEFAULT_BASE)


def sample_unit(rng: np.random.Generator, base_friction: Friction) -> LoadUnit:
    """A load unit drawn from the distribution (`WrapBenchRandomEnv`'s docstring)."""
    for _ in range(RANDOM_MAX_TRIES):
        data: dict[str, Any] = {
            "name": "random unit",
            "pallet": {"preset": RANDOM_PALLET},
            "bundle": {
                "length_m": round(float(rng.uniform(*RANDOM_BUNDLE_LENGTH_M)), 3),
                "width_m": round(float(rng.uniform(*RANDOM_BUNDLE_WIDTH_M)), 3),
                "height_m": round(float(rng.uniform(*RANDOM_BUNDLE_HEIGHT_M)), 3),
                "mass_kg": round(float(rng.uniform(*RANDOM_BUNDLE_MASS_KG)), 1),
            },
            "stack": {
                "layers": int(rng.integers(RANDOM_LAYERS[0], RANDOM_LAYERS[1] + 1)),
                "pattern": str(RANDOM_PATTERNS[int(rng.integers(len(RANDOM_PATTERNS)))]),
            },
            "friction": {},
            "fixture": {"pallet_stopper": True},
        }
        for pair in PAIRS:
            spread = rng.uniform(1 - RANDOM_FRICTION_SPREAD, 1 + RANDOM_FRICTION_SPREAD)
            static = round(float(base_friction.pair(pair).static * spread), 3)
            data["friction"][pair] = {"static": static,
                                      "kinetic": round(RANDOM_KINETIC_RATIO * static, 3)}
        b, s = data["bundle"], data["stack"]
        data["name"] = (f"random: {s['layers']} x {s['pattern']}, bundle "
                        f"{b['length_m']:.3f} x {b['width_m']:.3f} x {b['height_m']:.3f} m, "
                        f"{b['mass_kg']:.1f} kg")
        try:
            return LoadUnit.from_dict(data, source="random unit")
        except InputError:
            continue
    raise RuntimeError(f"no valid load unit in {RANDOM_MAX_TRIES} draws")


def outside(unit: LoadUnit, base: Friction = DEFAULT_BASE) -> tuple[str, ...]:
    """How `unit` lies outside the distribution about `base` friction (one phrase per feature,
    none when inside): a policy trained on it proposes for such a unit by extrapolation."""
    p, b, s = unit.pallet, unit.bundle, unit.stack
    eur = PALLET_PRESETS[RANDOM_PALLET]
    out = []
    if (p.length_m, p.width_m, p.height_m) != (eur.length_m, eur.width_m, eur.height_m):
        out.append(f"a {p.length_m:g} x {p.width_m:g} m pallet, not the {RANDOM_PALLET} "
                   f"pallet's {eur.length_m:g} x {eur.width_m:g}")
    if not RANDOM_LAYERS[0] <= s.layers <= RANDOM_LAYERS[1]:
        out.append(f"{s.layers} layers, not {RANDOM_LAYERS[0]}-{RANDOM_LAYERS[1]}")
    if s.pattern not in RANDOM_PATTERNS:
        out.append(f"the {s.pattern} pattern, not {' or '.join(RANDOM_PATTERNS)}")
    ranges = {"length_m": RANDOM_BUNDLE_LENGTH_M, "width_m": RANDOM_BUNDLE_WIDTH_M,
              "height_m": RANDOM_BUNDLE_HEIGHT_M, "mass_kg": RANDOM_BUNDLE_MASS_KG}
    for key, (low, high) in ranges.items():
        value = getattr(b, key)
        if not low <= value <= high:
            out.append(f"bundle {key} {value:g}, not {low:g}-{high:g}")
    if not unit.pallet_stopper:
        out.append("no stop bar behind the pallet")
    return tuple(out) + _friction_outside(unit.friction, base)


def _friction_outside(friction: Friction, base: Friction) -> tuple[str, ...]:
    """Each coefficient outside the spread the units draw about `base` (kinetic: its share of
    the drawn static), to the 3 decimals they are drawn with."""
    out = []
    for pair in PAIRS:
        static = base.pair(pair).static
        ranges = {"static": (static * (1 - RANDOM_FRICTION_SPREAD),
                             static * (1 + RANDOM_FRICTION_SPREAD))}
        ranges["kinetic"] = (RANDOM_KINETIC_RATIO * ranges["static"][0],
                             RANDOM_KINETIC_RATIO * ranges["static"][1])
        for kind, (low, high) in ranges.items():
            value = getattr(friction.pair(pair), kind)
            if not low - 5e-4 <= value <= high + 5e-4:
                out.append(f"{pair} {kind} {value:g}, not {low:.3f}-{high:.3f}")
    return tuple(out)
