"""What an environment observes (wrapenv/envs/observation.py): friction spreads a policy can
take in, and the card figures a policy records."""

from __future__ import annotations

import math

import pytest

from wrapenv.calibrated import CalibratedPair, Calibration
from wrapenv.config import InputError
from wrapenv.envs.observation import (
    MAX_FRICTION_STD,
    OBS_FEATURES,
    check_observable,
    material_features,
)
from wrapenv.material import MATERIALS


def test_a_calibration_within_the_observed_spread_is_taken():
    check_observable(Calibration({"pallet_bundle": CalibratedPair(
        0.5, 0.4, static_std=MAX_FRICTION_STD, kinetic_std=0.03)}), "cal.json")


def test_a_spread_a_policy_cannot_observe_is_refused_naming_the_pair(assert_input_error):
    wide = Calibration({"bundle_bundle": CalibratedPair(0.4, 0.33, kinetic_std=2.5)})
    with pytest.raises(InputError) as info:
        check_observable(wide, "cal.json")
    assert_input_error(info.value, "cal.json", "friction.bundle_bundle.kinetic_std")


def test_the_card_features_are_the_last_six_of_the_observation_and_fit_its_bounds():
    names = [name for name, _ in OBS_FEATURES[-6:]]
    assert names[0] == "material_grammage" and names[-1] == "material_is_paper"
    for card in MATERIALS.values():
        features = material_features(card)
        bounds = [high for _, high in OBS_FEATURES[-6:]]
        assert len(features) == 6 and all(0 <= f <= b for f, b in zip(features, bounds,
                                                                      strict=True))
    # Kraft's 90 g/m² and 4e5 N/m: 0.9 and log10(4e5) / 6 = 0.934
    kraft = material_features(MATERIALS["kraft"])
    assert kraft[:2] == pytest.approx([0.9, math.log10(4e5) / 6])
    assert kraft[-1] == 1.0 and material_features(MATERIALS["lldpe"])[-1] == 0.0
