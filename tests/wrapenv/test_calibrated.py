"""Specification of CAL.json: what `wrapbench calibrate` writes and the bench reads back."""

from __future__ import annotations

import copy
import dataclasses
import json
from typing import Any

import pytest

from wrapenv.calibrated import MIN_DRAWN_STATIC, SCALE_RANGE, CalibratedPair, Calibration
from wrapenv.config import MAX_FRICTION_COEFFICIENT, InputError
from wrapenv.load import Friction, FrictionPair, LoadUnit

#: The CAL.json of CONTRACTS.md, with every pair filled in.
CAL: dict[str, Any] = {
    "friction": {
        "sled_pallet": {"static": 0.45, "kinetic": 0.40, "static_std": 0.02, "kinetic_std": 0.01,
                        "identified": True},
        "pallet_bundle": {"static": 0.52, "kinetic": 0.44, "static_std": 0.03,
                          "kinetic_std": 0.02, "identified": True},
        "bundle_bundle": {"static": 0.60, "kinetic": 0.35, "static_std": 0.0,
                          "kinetic_std": 0.04, "identified": False},
    },
    "wrap": {"stiffness_scale": 1.1, "tension_scale": 0.9},
    "residual_rms_m": 0.0015,
    "simulations": 180,
    "method": "cmaes",
}


def load() -> LoadUnit:
    return LoadUnit.from_dict({
        "pallet": {"preset": "EUR"},
        "bundle": {"preset": "PET6x1.5L"},
        "stack": {"layers": 1},
        "friction": {"sled_pallet": {"static": 0.3, "kinetic": 0.2},
                     "pallet_bundle": {"static": 0.31, "kinetic": 0.21},
                     "bundle_bundle": {"static": 0.32, "kinetic": 0.22}},
    })


def edited(**changes) -> dict:
    """CAL with dotted keys (written with '__' for '.') set, or deleted when None."""
    data = copy.deepcopy(CAL)
    for dotted, value in changes.items():
        *parents, last = dotted.split("__")
        node = data
        for part in parents:
            node = node[part]
        if value is None:
            del node[last]
        else:
            node[last] = value
    return data


def write_json(tmp_path, data, name: str = "CAL.json"):
    path = tmp_path / name
    path.write_text(data if isinstance(data, str) else json.dumps(data))
    return path


def test_contracts_calibration_is_parsed():
    cal = Calibration.from_dict(CAL)
    assert cal.friction == {
        "sled_pallet": CalibratedPair(0.45, 0.40, 0.02, 0.01, True),
        "pallet_bundle": CalibratedPair(0.52, 0.44, 0.03, 0.02, True),
        "bundle_bundle": CalibratedPair(0.60, 0.35, 0.0, 0.04, False),
    }
    assert cal.stiffness_scale == 1.1
    assert cal.tension_scale == 0.9


def test_calibration_json_file_is_read(tmp_path):
    assert Calibration.from_json(write_json(tmp_path, CAL)) == Calibration.from_dict(CAL)


def test_fit_diagnostics_are_accepted_and_not_required():
    plain = edited(residual_rms_m=None, simulations=None, method=None)
    assert Calibration.from_dict(plain) == Calibration.from_dict(CAL)


def test_a_fit_accepted_under_a_looser_bound_says_so_to_its_users():
    """`calibrate --max-residual-mm 30` may accept a fit that left a recording 28 mm
    unexplained; whoever simulates with its CAL.json later is told."""
    acceptance = {"max_residual_m": 0.03, "least_explained": "takes/0.45g",
                  "unexplained_rms_m": 0.028, "explained_by": "replay 3", "excused": []}
    loose = Calibration.from_dict(edited(acceptance=acceptance))
    assert loose.unexplained_rms_m == 0.028
    assert loose.warnings() == ("the calibration was accepted with 28.0 mm of a recording "
                                "unexplained, where a default fit refuses more than 10 mm",)
    assert loose.draw(0).warnings() == loose.warnings()
    within = Calibration.from_dict(edited(acceptance=acceptance | {"unexplained_rms_m": 0.004}))
    assert Calibration.from_dict(CAL).warnings() == within.warnings() == ()


def test_a_fit_on_a_take_near_a_threshold_says_so_to_its_users():
    """`calibrate` names the takes whose outcome the fitted values reproduced only now and
    then (a fit can be pulled there); whoever simulates with the CAL.json later is told, and
    a list that is not of paths is refused, naming the field."""
    acceptance = {"max_residual_m": 0.01, "least_explained": "takes/0.35g",
                  "unexplained_rms_m": 0.009, "explained_by": "replay 0", "excused": [],
                  "near_threshold": ["takes/0.45g"]}
    near = Calibration.from_dict(edited(acceptance=acceptance))
    assert near.near_threshold == ("takes/0.45g",)
    assert near.warnings() == (
        "the calibration was fitted to 1 take(s) near a threshold, whose outcome its values "
        "reproduce only now and then: the coefficients deciding it may be off by more than "
        "their standard deviations",)
    assert near.draw(0).warnings() == near.warnings()
    assert Calibration.from_dict(edited(acceptance=acceptance | {"near_threshold": []})
                                 ).warnings() == ()
    with pytest.raises(InputError, match="near_threshold"):
        Calibration.from_dict(edited(acceptance=acceptance | {"near_threshold": [3]}))


def test_std_and_identified_are_optional_with_documented_defaults():
    cal = Calibration.from_dict({"friction": {"sled_pallet": {"static": 0.5, "kinetic": 0.4}}})
    assert cal.friction["sled_pallet"] == CalibratedPair(0.5, 0.4, 0.0, 0.0, True)
    # a file of friction alone leaves the wrap and the load's give as they are, exactly
    assert cal == Calibration({"sled_pallet": CalibratedPair(0.5, 0.4)})
    assert (cal.stiffness_scale, cal.tension_scale, cal.give_scale) == (1.0, 1.0, 1.0)
    assert (cal.stiffness_scale_std, cal.tension_scale_std, cal.give_scale_std) == (0, 0, 0)
    assert cal.unexplained_rms_m == 0.0
    accepted = Calibration.from_dict({"friction": {"sled_pallet": {"static": 0.5,
                                                                   "kinetic": 0.4}},
                                      "acceptance": {"max_residual_m": 0.01}})
    assert accepted.unexplained_rms_m == 0.0


def test_empty_calibration_changes_nothing():
    cal = Calibration()
    assert cal.friction == {}
    assert (cal.stiffness_scale, cal.tension_scale) == (1.0, 1.0)
    assert cal.apply(load()) == load()


@pytest.mark.parametrize("data", [{}, {"friction": {}}, {"residual_rms_m": 0.001},
                                  {"objects": {"L1C1R1": {"t_s": [0.0]}}}])
def test_a_file_that_calibrates_nothing_is_refused(data, tmp_path, assert_input_error):
    """`{}` used to be read as the load's own friction and wrap: a run the user believed
    calibrated, said nowhere to be otherwise. Another file given for CAL.json (a recording's
    truth.json) is told as such, not by its first unknown key."""
    path = write_json(tmp_path, data)
    with pytest.raises(InputError) as info:
        Calibration.from_json(path)
    assert_input_error(info.value, str(path), "friction")
    assert "calibrates nothing" in str(info.value)


def test_apply_replaces_every_calibrated_pair():
    unit = Calibration.from_dict(CAL).apply(load())
    assert unit.friction == Friction(
        FrictionPair(0.45, 0.40), FrictionPair(0.52, 0.44), FrictionPair(0.60, 0.35))


def test_apply_replaces_only_the_pairs_present():
    cal = Calibration.from_dict({"friction": {"pallet_bundle": {"static": 0.7, "kinetic": 0.6}}})
    before = load()
    after = cal.apply(before)
    assert after.friction.pallet_bundle == FrictionPair(0.7, 0.6)
    assert after.friction.sled_pallet == before.friction.sled_pallet == FrictionPair(0.3, 0.2)
    assert after.friction.bundle_bundle == before.friction.bundle_bundle
    # Nothing else of the load changes.
    assert after.with_friction(before.friction) == before


def test_apply_leaves_the_original_load_untouched():
    before = load()
    Calibration.from_dict(CAL).apply(before)
    assert before == load()


def test_apply_uses_the_static_lower_bound_of_an_unidentified_pair():
    unit = Calibration.from_dict(CAL).apply(load())
    assert unit.friction.bundle_bundle.static == 0.60


def test_apply_keeps_the_load_files_pair_above_an_unidentified_bound():
    """A stopped pallet that never slid says only that its sled contact held the braking
    (~0.1 g): the load file's 0.3 stands, where the bound would let the pallet slide."""
    cal = Calibration.from_dict({"friction": {"sled_pallet": {
        "static": 0.11, "kinetic": 0.09, "identified": False}}})
    assert cal.apply(load()).friction.sled_pallet == FrictionPair(0.3, 0.2)
    # a bound above the load file's value is taken, one on it changes nothing
    above = Calibration.from_dict({"friction": {"sled_pallet": {
        "static": 0.35, "kinetic": 0.3, "identified": False}}})
    assert above.apply(load()).friction.sled_pallet == FrictionPair(0.35, 0.3)


BAD_CALS = {
    # id: (CAL.json content, expected dotted field)
    "kinetic above static": (
        edited(friction__sled_pallet__kinetic=0.5), "friction.sled_pallet.kinetic"),
    "missing static": (
        edited(friction__pallet_bundle__static=None), "friction.pallet_bundle.static"),
    "zero static": (edited(friction__pallet_bundle__static=0.0), "friction.pallet_bundle.static"),
    "negative kinetic": (
        edited(friction__bundle_bundle__kinetic=-0.1), "friction.bundle_bundle.kinetic"),
    "implausible static": (
        edited(friction__sled_pallet__static=3.0), "friction.sled_pallet.static"),
    "string static": (edited(friction__sled_pallet__static="0.4"), "friction.sled_pallet.static"),
    "negative std": (edited(friction__sled_pallet__static_std=-0.01),
                     "friction.sled_pallet.static_std"),
    "std past any coefficient": (edited(friction__sled_pallet__kinetic_std=1e6),
                                 "friction.sled_pallet.kinetic_std"),
    "stiffness std past any fit": (edited(wrap__stiffness_scale_std=25.0),
                                   "wrap.stiffness_scale_std"),
    "identified not boolean": (edited(friction__sled_pallet__identified="yes"),
                               "friction.sled_pallet.identified"),
    "unknown pair": (edited(friction__sled_bundle={"static": 0.4, "kinetic": 0.3}),
                     "friction.sled_bundle"),
    "typo in pair": (edited(friction__sled_pallet__kinetik=0.3), "friction.sled_pallet.kinetik"),
    "pair not an object": (edited(friction__sled_pallet=0.4), "friction.sled_pallet"),
    "zero stiffness scale": (edited(wrap__stiffness_scale=0.0), "wrap.stiffness_scale"),
    "tension scaled past any fit": (edited(wrap__tension_scale=100.0), "wrap.tension_scale"),
    "typo in wrap": (edited(wrap__stiffnes_scale=1.0), "wrap.stiffnes_scale"),
    "give scaled to nothing": (edited(wrap__give_scale=0.0), "wrap.give_scale"),
    "give scaled past any fit": (edited(wrap__give_scale=50.0), "wrap.give_scale"),
    "negative give std": (edited(wrap__give_scale_std=-0.1), "wrap.give_scale_std"),
    "give std past any fit": (edited(wrap__give_scale_std=21.0), "wrap.give_scale_std"),
    "known names no wrap scale": (edited(wrap__known=["friction"]), "wrap.known"),
    "known twice": (edited(wrap__known=["give", "give"]), "wrap.known"),
    "known not a list": (edited(wrap__known="give"), "wrap.known"),
    "unknown top-level key": (edited(frictions={}), "frictions"),
    "negative unexplained": (edited(acceptance={"unexplained_rms_m": -0.01}),
                             "acceptance.unexplained_rms_m"),
    "typo in acceptance": (edited(acceptance={"unexplaned_rms_m": 0.01}),
                           "acceptance.unexplaned_rms_m"),
}


@pytest.mark.parametrize("data, field", BAD_CALS.values(), ids=BAD_CALS.keys())
def test_bad_calibration_is_rejected_naming_file_and_field(data, field, tmp_path,
                                                           assert_input_error):
    path = write_json(tmp_path, data)
    with pytest.raises(InputError) as info:
        Calibration.from_json(path)
    assert_input_error(info.value, str(path), field)


def test_a_pair_whose_kinetic_coefficient_equals_its_static_one_is_accepted(tmp_path):
    """No drop from sticking to sliding (a pair the fit found at the ratio's top, 1.0)."""
    path = write_json(tmp_path, edited(friction__sled_pallet__kinetic=0.45))
    pair = Calibration.from_json(path).friction["sled_pallet"]
    assert pair.static == pair.kinetic == 0.45


def test_nan_in_calibration_json_is_rejected(tmp_path, assert_input_error):
    text = json.dumps(CAL).replace("0.45", "NaN", 1)
    path = write_json(tmp_path, text)
    with pytest.raises(InputError) as info:
        Calibration.from_json(path)
    assert_input_error(info.value, str(path), "friction.sled_pallet.static")


@pytest.mark.parametrize("text", ['{"friction": {', "", "friction = 1", "\x00\x01"],
                         ids=["truncated", "empty", "toml not json", "binary"])
def test_malformed_json_is_rejected_naming_the_file(text, tmp_path, assert_input_error):
    path = write_json(tmp_path, text)
    with pytest.raises(InputError, match="malformed JSON") as info:
        Calibration.from_json(path)
    assert_input_error(info.value, str(path), "")


def test_calibration_that_is_not_utf8_is_rejected_naming_the_file(tmp_path, assert_input_error):
    path = tmp_path / "CAL.json"
    path.write_bytes(b'{"method": "\xff"}')
    with pytest.raises(InputError) as info:
        Calibration.from_json(path)
    assert_input_error(info.value, str(path), "")


def test_json_array_instead_of_object_is_rejected(tmp_path, assert_input_error):
    path = write_json(tmp_path, [CAL])
    with pytest.raises(InputError) as info:
        Calibration.from_json(path)
    assert_input_error(info.value, str(path), "")


def test_missing_calibration_file_is_rejected_naming_it(tmp_path, assert_input_error):
    path = tmp_path / "missing.json"
    with pytest.raises(InputError, match="cannot read") as info:
        Calibration.from_json(path)
    assert_input_error(info.value, str(path), "")


def test_a_calibration_written_as_a_dict_reads_back_equal():
    cal = Calibration(
        {"pallet_bundle": CalibratedPair(0.37, 0.30, 0.01, 0.004),
         "sled_pallet": CalibratedPair(0.11, 0.10, identified=False)},
        stiffness_scale=1.3, tension_scale=0.9, stiffness_scale_std=0.1, tension_scale_std=0.05,
        give_scale=0.7, give_scale_std=0.2)
    assert Calibration.from_dict(cal.to_dict()) == cal
    measured = dataclasses.replace(cal, give_scale_std=0.0, known=("give",))
    assert Calibration.from_dict(measured.to_dict()) == measured
    assert "known" not in cal.to_dict()["wrap"]  # files without measured scales are unchanged


def test_the_load_s_give_is_optional_and_one_without_changes_nothing():
    cal = Calibration.from_dict(CAL)
    assert (cal.give_scale, cal.give_scale_std) == (1.0, 0.0)
    assert cal.apply(load()).bundle == load().bundle


def test_apply_scales_the_load_s_give_by_the_calibrated_factor():
    cal = Calibration.from_dict(edited(wrap__give_scale=0.5, wrap__give_scale_std=0.1))
    assert cal.give_scale_std == 0.1
    assert cal.apply(load()).bundle.corner_stiffness_n_per_m2 == pytest.approx(
        0.5 * load().bundle.corner_stiffness_n_per_m2)


def test_a_draw_spreads_each_value_by_its_standard_deviation():
    """Over many draws each fitted value keeps its mean and spreads by its standard deviation
    (3-sigma tolerance of the sample's mean and std for n = 4000); kinetic never exceeds
    static; a pair that was not identified keeps its bound."""
    cal = dataclasses.replace(Calibration.from_dict(CAL), stiffness_scale_std=0.2,
                              give_scale=0.8, give_scale_std=0.1)
    draws = [cal.draw(seed) for seed in range(4000)]
    n = len(draws)
    for values, mean, std in [
            ([d.friction["sled_pallet"].static for d in draws], 0.45, 0.02),
            ([d.friction["pallet_bundle"].kinetic for d in draws], 0.44, 0.02),
            ([d.stiffness_scale for d in draws], 1.1, 0.2),
            ([d.give_scale for d in draws], 0.8, 0.1)]:
        assert abs(sum(values) / n - mean) < 3 * std / n**0.5
        sample_std = (sum((v - mean) ** 2 for v in values) / n) ** 0.5
        assert abs(sample_std - std) < 3 * std / (2 * n) ** 0.5
    assert all(p.kinetic <= p.static for d in draws for p in d.friction.values())
    assert all(d.friction["bundle_bundle"] == cal.friction["bundle_bundle"] for d in draws)
    assert {d.tension_scale for d in draws} == {0.9}          # no standard deviation given


def test_the_widest_spread_a_file_may_give_draws_within_what_a_file_may_give():
    """A spread as wide as a coefficient's whole range still draws friction pairs and scales
    that the bench would accept from a file (coefficients up to 2, scales up to 20)."""
    pair = {"static": 1.9, "kinetic": 1.8, "static_std": 2.0, "kinetic_std": 2.0}
    cal = Calibration.from_dict({"friction": {"sled_pallet": pair},
                                 "wrap": {"stiffness_scale": 19.0, "stiffness_scale_std": 20.0}})
    draws = [cal.draw(seed) for seed in range(200)]
    statics = [d.friction["sled_pallet"].static for d in draws]
    assert max(statics) == MAX_FRICTION_COEFFICIENT and min(statics) >= MIN_DRAWN_STATIC
    assert max(d.stiffness_scale for d in draws) == SCALE_RANGE[1]
    # 19 +- 20 falls below zero a sixth of the time: such draws stop at a tenth of the value
    assert min(d.stiffness_scale for d in draws) == pytest.approx(1.9)


def test_a_draw_is_fixed_by_its_seed_and_a_calibration_without_spread_is_its_own_draw():
    cal = Calibration.from_dict(CAL)
    assert cal.draw(3) == cal.draw(3) != cal.draw(4)
    exact = Calibration({"pallet_bundle": CalibratedPair(0.5, 0.4)}, stiffness_scale=1.3)
    assert exact.draw(7) == exact
