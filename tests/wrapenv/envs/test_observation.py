"""What an environment observes (wrapenv/envs/observation.py): friction spreads a policy can
take in, and the card figures a policy records."""

from __future__ import annotations

import json
import math

import pytest

from wrapenv.calibrated import CalibratedPair, Calibration
from wrapenv.config import InputError
from wrapenv.envs.observation import (
    MAX_FRICTION_STD,
    OBS_FEATURES,
    OBS_NAMES,
    material_features,
    observe,
)
from wrapenv.load import LoadUnit
from wrapenv.material import MATERIALS


def test_every_spread_a_calibration_file_may_hold_is_observed(tmp_path, assert_input_error):
    """CAL.json's loader bounds a friction spread where the observation does, so a policy
    observes any calibration that loads; a wider spread is refused as the file is read."""
    unit = LoadUnit.from_toml("examples/pet_2layer_columnar.toml")
    cal = tmp_path / "cal.json"
    for std in (MAX_FRICTION_STD, MAX_FRICTION_STD + 0.5):
        cal.write_text(json.dumps({"friction": {"bundle_bundle": {
            "static": 0.4, "kinetic": 0.33, "static_std": 0.01, "kinetic_std": std}}}))
        if std > MAX_FRICTION_STD:
            with pytest.raises(InputError) as info:
                Calibration.from_json(cal)
            assert_input_error(info.value, str(cal), "friction.bundle_bundle.kinetic_std")
            continue
        seen = observe(unit, unit.layout(), 0.5, MATERIALS["kraft"], Calibration.from_json(cal))
        i = OBS_NAMES.index("friction_bundle_bundle_kinetic_std")
        assert seen[i] == MAX_FRICTION_STD == OBS_FEATURES[i][1]


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


def test_a_unit_is_observed_over_fixed_scales_a_trained_policy_relies_on():
    """The 2-layer example: 2 of 4 layers; its bundle (0.28 x 0.19 x 0.33 m, 9.3 kg) over
    0.5 m and 20 kg; the EUR pallet over 1.2 m; the load's 0.804 m over 2 m; columnar; its
    friction as given, no spread; the target in g."""
    unit = LoadUnit.from_toml("examples/pet_2layer_columnar.toml")
    calibration = Calibration({"pallet_bundle": CalibratedPair(0.5, 0.42, 0.03, 0.02)})
    seen = dict(zip(OBS_NAMES, observe(unit, unit.layout(), 0.6, MATERIALS["kraft"],
                                       calibration).tolist(), strict=True))
    f = unit.friction
    expected = {
        "layers": 0.5, "bundle_length": 0.28 / 0.5, "bundle_width": 0.19 / 0.5,
        "bundle_height": 0.33 / 0.5, "bundle_mass": 9.3 / 20, "pallet_length": 1.0,
        "pallet_width": 0.8 / 1.2, "pallet_height": 0.144 / 1.2, "load_height": 0.804 / 2,
        "pattern_columnar": 1.0, "pattern_interlocked": 0.0, "target_g": 0.6,
        "friction_sled_pallet_static": f.sled_pallet.static,
        "friction_pallet_bundle_kinetic": f.pallet_bundle.kinetic,
        "friction_pallet_bundle_static_std": 0.03, "friction_pallet_bundle_kinetic_std": 0.02,
        "friction_bundle_bundle_static_std": 0.0}
    assert {k: seen[k] for k in expected} == pytest.approx(expected, rel=1e-6)
