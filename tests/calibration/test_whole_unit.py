"""Issue 13's acceptance, small: a whole unit whose top layer slides (and, at the higher level,
a bundle falls off the back), recorded at two levels with its friction drawn at random and
hidden from the fit, tracked, calibrated, then proved on a third level it was not fitted to.

The unit is the paper's columnar 2-layer stack cut down to 2 x 2 bundles a layer on a
0.6 x 0.4 m pallet against the stopper, so a replay takes a fraction of a second."""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor

import pytest

from calibration.fit import FitSettings, fit
from calibration.recording import Recording, Truth
from calibration.replay import observe
from calibration.synth import synthesize
from calibration.track import track
from calibration.validate import validate
from wrapenv.load import LoadUnit

UNIT = {
    "name": "small columnar 2-layer unit",
    "pallet": {"length_m": 0.6, "width_m": 0.4, "height_m": 0.12, "mass_kg": 10.0},
    "bundle": {"length_m": 0.28, "width_m": 0.19, "height_m": 0.33, "mass_kg": 9.3},
    "stack": {"layers": 2, "pattern": "columnar"},
    "friction": {"sled_pallet": {"static": 0.45, "kinetic": 0.40},
                 "pallet_bundle": {"static": 0.50, "kinetic": 0.42},
                 "bundle_bundle": {"static": 0.40, "kinetic": 0.33}},
    "fixture": {"pallet_stopper": True},
}
FITTED, HELD_OUT = (0.35, 0.45), 0.40


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    load = LoadUnit.from_dict(UNIT)
    out = {}
    for level in (*FITTED, HELD_OUT):
        folder = tmp_path_factory.mktemp("unit") / f"at{level}"
        synthesize(load, folder, level_g=level, seed=0, size=(480, 300), friction_jitter=0.1)
        rec = Recording.read(folder)
        out[level] = (observe(rec, track(rec).trajectories), Truth.read(folder))
    return out


def test_calibration_of_a_sliding_unit_finds_its_hidden_friction_and_predicts_a_third_level(
        recordings):
    fitted = [recordings[level][0] for level in FITTED]
    assert {"bundle_bundle"} == set().union(*(o.slipped for o in fitted))
    result = fit(fitted, FitSettings(budget=150, workers=2))
    truth = recordings[FITTED[0]][1].params["friction"]["bundle_bundle"]
    pair = result.calibration.friction["bundle_bundle"]
    assert result.converged, result.reason
    assert abs(pair.kinetic - truth["kinetic"]) <= 0.03
    assert abs(pair.static - truth["static"]) <= 0.05
    assert 0 < pair.kinetic_std < 0.05
    assert not result.calibration.friction["pallet_bundle"].identified
    assert "pallet_bundle" in result.advice and "sled_pallet" in result.advice
    assert result.simulations <= 150
    with ProcessPoolExecutor(2) as pool:
        (check,) = validate([recordings[HELD_OUT][0]], result.calibration, pool)
    layer, slide = check.largest
    assert layer == 2 and slide.recorded_m < -0.05
    assert abs(slide.error_pct) <= 15, check
