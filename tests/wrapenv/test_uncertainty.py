"""What the bench does not know: draws of every uncertain parameter, how a draw changes a
load and a wrap, and the pass probability's interval."""

from __future__ import annotations

import numpy as np
import pytest

from wrapenv.calibrated import Calibration
from wrapenv.load import LoadUnit
from wrapenv.material import MATERIALS
from wrapenv.uncertainty import (
    DEFAULT_FRICTION_STD,
    DEFAULT_GIVE_STD,
    DEFAULT_SCALE_STD,
    MASS_SPREAD,
    PassProbability,
    Uncertainty,
)
from wrapenv.wrap import Band, WrapFormat

LOAD = LoadUnit.from_dict({"name": "x", "pallet": {"preset": "EUR"},
                           "bundle": {"preset": "PET6x1.5L"},
                           "stack": {"layers": 1, "pattern": "columnar"}})
FILM = WrapFormat(MATERIALS["lldpe"], 0.5, (Band(0.0, 0.4, 2, 70.0),), "lldpe")


def test_a_seed_fixes_every_draw():
    u = Uncertainty.of(None, 16.0)
    assert u.draw(LOAD, 3) == u.draw(LOAD, 3) != u.draw(LOAD, 4)


def test_draws_spread_as_stated():
    draws = [Uncertainty.of(None, 0.0).draw(LOAD, seed) for seed in range(400)]
    stiffness = np.array([d.stiffness_scale for d in draws])
    assert abs(stiffness.mean() - 1.0) < 0.02
    assert stiffness.std() == pytest.approx(DEFAULT_SCALE_STD, rel=0.15)
    assert all(abs(d.mass_scale - 1) <= MASS_SPREAD for d in draws)
    assert all(d.friction["pallet_bundle"].kinetic <= d.friction["pallet_bundle"].static
               for d in draws)


def test_a_calibration_sets_the_wrap_s_scales_and_their_spread():
    cal = Calibration(stiffness_scale=1.4, stiffness_scale_std=0.02)
    u = Uncertainty.of(cal, 0.0)
    stiffness = np.array([u.draw(LOAD, s).stiffness_scale for s in range(200)])
    assert abs(stiffness.mean() - 1.4) < 0.01 and stiffness.std() < 0.03
    assert u.tension_scale_std == DEFAULT_SCALE_STD  # not calibrated: the default spread


def test_a_calibration_s_friction_spreads_replace_the_default_pair_by_pair():
    """Both of a calibrated pair's spreads are its own; a pair it gives no spread for (0: a
    value measured elsewhere) or does not name keeps the default."""
    cal = Calibration.from_dict({"friction": {
        "pallet_bundle": {"static": 0.3, "kinetic": 0.25, "static_std": 0.1, "kinetic_std": 0.08},
        "bundle_bundle": {"static": 0.4, "kinetic": 0.3}}})
    std = Uncertainty.of(cal, 0.0).friction_std
    assert std["pallet_bundle"] == (0.1, 0.08)
    assert std["bundle_bundle"] == std["sled_pallet"] == (DEFAULT_FRICTION_STD,) * 2


def test_the_load_s_give_is_drawn_round_the_load_s_own():
    """Uncalibrated, the bundles' edge stiffness spreads by the assumed 25 %; a calibration's
    relative standard deviation replaces it (the calibrated give is already in the load)."""
    corner = LOAD.bundle.corner_stiffness_n_per_m2
    draws = [Uncertainty.of(None, 0.0).draw(LOAD, s) for s in range(400)]
    given = np.array([d.load(LOAD).bundle.corner_stiffness_n_per_m2 for d in draws]) / corner
    assert given == pytest.approx([d.give_scale for d in draws])
    assert abs(given.mean() - 1.0) < 0.04
    assert given.std() == pytest.approx(DEFAULT_GIVE_STD, rel=0.15)
    cal = Calibration(give_scale=2.0, give_scale_std=0.1)
    assert Uncertainty.of(cal, 0.0).give_std == pytest.approx(0.05)


def test_a_sample_relaxes_the_wrap_by_its_material_law_scaled_by_its_draw():
    u = Uncertainty.of(None, 720.0)  # 30 days: LLDPE keeps 74 % (Dunno & Symanski 2021)
    sample = u.draw(LOAD, 0)
    laid = sample.wrap(FILM)
    lost = (1 - 0.74 - 0.08 * np.exp(-10)) * sample.relaxation_scale
    expected = 70.0 * sample.tension_scale * (1 - lost)
    assert laid.bands[0].tension_n == pytest.approx(expected, rel=1e-6)
    assert laid.material.stiffness_n_per_m == pytest.approx(2500.0 * sample.stiffness_scale)
    assert u.nominal(FILM).bands[0].tension_n == pytest.approx(70.0 * 0.74, rel=1e-3)


@pytest.mark.parametrize("passed, samples, low, high", [
    (8, 8, 0.6756, 1.0),      # Wilson: all passed still leaves a third of doubt at n = 8
    (4, 8, 0.2152, 0.7848),
    (0, 8, 0.0, 0.3244),
    (95, 100, 0.8883, 0.9785),
])
def test_pass_probability_carries_its_wilson_95_interval(passed, samples, low, high):
    p = PassProbability(passed, samples)
    assert p.estimate == passed / samples
    assert p.interval == pytest.approx((low, high), abs=2e-4)
    assert p.to_json()["low95"] == pytest.approx(low, abs=2e-4)


def test_a_sample_s_load_carries_its_drawn_mass_and_friction():
    sample = Uncertainty.of(None, 0.0).draw(LOAD, 5)
    drawn = sample.load(LOAD)
    assert sample.mass_scale != 1.0
    assert drawn.bundle.mass_kg == pytest.approx(LOAD.bundle.mass_kg * sample.mass_scale)
    assert drawn.pallet == LOAD.pallet
    for name, pair in sample.friction.items():
        assert drawn.friction.pair(name) == pair


def test_no_sample_knows_nothing_of_the_probability():
    none = PassProbability(0, 0)
    assert np.isnan(none.estimate) and none.interval == (0.0, 1.0)
