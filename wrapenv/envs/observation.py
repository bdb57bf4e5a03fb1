"""What a wrapbench environment observes: a load unit, the target and the web, as features
scaled so that usual units land in [0, 1]. Policies record `OBS_NAMES` (recommender/policy.py):
a new material card adds no feature, so saved policies keep their shape."""

from __future__ import annotations

import math

import numpy as np

from wrapenv.calibrated import Calibration
from wrapenv.config import MAX_FRICTION_COEFFICIENT
from wrapenv.load import PAIRS, PATTERNS, Layout, LoadUnit
from wrapenv.material import Material

# Scales of the observation's features (divisors), chosen so usual loads land in [0, 1].
LAYERS_SCALE = 4.0
BUNDLE_SIZE_SCALE_M = 0.5
BUNDLE_MASS_SCALE_KG = 20.0
PALLET_SIZE_SCALE_M = 1.2   # the EUR pallet's length
LOAD_HEIGHT_SCALE_M = 2.0

#: The largest standard deviation of a friction coefficient the observation holds: the most a
#: CAL.json may give (its loader's bound), so every calibration that loads is observable.
MAX_FRICTION_STD = MAX_FRICTION_COEFFICIENT

#: Observation features in order: (name, upper bound of the space). Every lower bound is 0.
OBS_FEATURES: tuple[tuple[str, float], ...] = (
    ("layers", 10.0),
    ("bundle_length", 10.0),
    ("bundle_width", 10.0),
    ("bundle_height", 10.0),
    ("bundle_mass", 10.0),
    ("pallet_length", 10.0),
    ("pallet_width", 10.0),
    ("pallet_height", 10.0),
    ("load_height", 10.0),
    *((f"pattern_{p}", 1.0) for p in PATTERNS),
    *((f"friction_{pair}_{kind}", MAX_FRICTION_COEFFICIENT) for pair in PAIRS
      for kind in ("static", "kinetic")),
    ("target_g", 1.1),
    *((f"friction_{pair}_{kind}_std", MAX_FRICTION_STD) for pair in PAIRS
      for kind in ("static", "kinetic")),
    ("material_grammage", 10.0),
    ("material_log_stiffness", 10.0),
    ("material_yield_strain", 10.0),
    ("material_break_strain", 10.0),
    ("material_break_force", 10.0),
    ("material_is_paper", 1.0),
)
OBS_NAMES: tuple[str, ...] = tuple(name for name, _ in OBS_FEATURES)


def observe(unit: LoadUnit, layout: Layout, target_g: float, material: Material,
            calibration: Calibration | None) -> np.ndarray:
    """The observation of `unit` (laid out as `layout`), in the order of `OBS_FEATURES`."""
    b, p = unit.bundle, unit.pallet
    cal = calibration.friction if calibration is not None else {}
    friction, std = [], []
    for pair in PAIRS:
        fp = unit.friction.pair(pair)
        friction += [fp.static, fp.kinetic]
        c = cal.get(pair)
        std += [c.static_std, c.kinetic_std] if c is not None else [0.0, 0.0]
    values = [
        unit.stack.layers / LAYERS_SCALE,
        b.length_m / BUNDLE_SIZE_SCALE_M,
        b.width_m / BUNDLE_SIZE_SCALE_M,
        b.height_m / BUNDLE_SIZE_SCALE_M,
        b.mass_kg / BUNDLE_MASS_SCALE_KG,
        p.length_m / PALLET_SIZE_SCALE_M,
        p.width_m / PALLET_SIZE_SCALE_M,
        p.height_m / PALLET_SIZE_SCALE_M,
        layout.load_height_m / LOAD_HEIGHT_SCALE_M,
        *(float(unit.stack.pattern == pattern) for pattern in PATTERNS),
        *friction,
        target_g,
        *std,
        *material_features(material),
    ]
    return np.array(values, np.float32)


def material_features(card: Material) -> list[float]:
    """The web as the observation sees it (the last six `OBS_FEATURES`): a policy records
    them, so that one trained on a card whose figures have since changed is refused."""
    return [card.grammage_kg_m2 / 0.1, math.log10(card.stiffness_n_per_m) / 6,
            card.yield_strain, card.break_strain, card.break_force_n_per_m / 1e4,
            float(card.kind == "paper")]
