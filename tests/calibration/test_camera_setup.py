"""setup.toml (calibration/camera_setup.py): what synth writes reads back the same, and the
marker size and dictionary may be left out."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from calibration.camera_setup import (
    MarkerPlacement,
    MarkerSpec,
    Setup,
    check_markers,
    setup_toml,
)
from wrapenv.config import InputError
from wrapenv.load import LoadUnit

SPEC = MarkerSpec("DICT_5X5_100", 0.05, (MarkerPlacement(7, "pallet", (0.5, 0.0)),
                                         MarkerPlacement(9, "L2C1R1", (-0.1, 0.12))))


def test_setup_round_trips_markers_and_template():
    data = tomllib.loads(setup_toml(25.0, 412.0, (960.5, 1001.0), SPEC, "t.png"))
    assert data["template"] == "t.png" and data["recording"]["fps"] == 25.0
    assert data["camera"] == {"px_per_m": 412.0, "origin_px": [960.5, 1001.0]}
    assert data["markers"]["placement"][1] == {"id": 9, "object": "L2C1R1",
                                               "offset_m": [-0.1, 0.12]}
    setup = Setup.parse(data, "setup.toml")
    assert setup.markers == SPEC and setup.template == "t.png"
    assert (setup.fps, setup.px_per_m, setup.origin_px) == (25.0, 412.0, (960.5, 1001.0))


def test_marker_size_may_be_left_out():
    spec = MarkerSpec(SPEC.dictionary, None, SPEC.placements)
    data = tomllib.loads(setup_toml(25.0, 412.0, (960.5, 1001.0), spec))
    assert "size_m" not in data["markers"]
    assert Setup.parse(data, "setup.toml").markers == spec


def test_a_markers_table_that_names_no_dictionary_means_dict_4x4_50():
    data = tomllib.loads(setup_toml(25.0, 412.0, (960.5, 1001.0), SPEC))
    del data["markers"]["dictionary"]
    assert Setup.parse(data, "setup.toml").markers == MarkerSpec("DICT_4X4_50", SPEC.size_m,
                                                                 SPEC.placements)


def test_a_marker_id_beyond_its_dictionary_is_named_with_the_dictionary_s_range():
    load = LoadUnit.from_toml(Path(__file__).resolve().parents[2] / "examples"
                              / "pet_2layer_columnar.toml")
    beyond = MarkerSpec("DICT_4X4_50", 0.05, (MarkerPlacement(50, "pallet", (0.5, 0.0)),))
    with pytest.raises(InputError, match=r"^setup\.toml: markers\.placement\[0\]\.id: "
                                         r"DICT_4X4_50 has ids 0 to 49 \(got 50\)$"):
        check_markers(beyond, load, "setup.toml")
    check_markers(MarkerSpec("DICT_4X4_50", None, (MarkerPlacement(49, "sled", (0.0, 0.0)),)),
                  load, "setup.toml")


def test_the_levels_a_unit_ran_before_its_take_round_trip_and_a_fresh_unit_writes_none():
    """A lab runs one unit through the EUMOS levels; a take of its 0.4 g level says so."""
    data = tomllib.loads(setup_toml(20.0, 500.0, (960.0, 900.0), None, None, (0.2, 0.3)))
    assert data["recording"]["levels_before_g"] == [0.2, 0.3]
    assert Setup.parse(data, "setup.toml").levels_before_g == (0.2, 0.3)
    fresh = tomllib.loads(setup_toml(20.0, 500.0, (960.0, 900.0)))
    assert "levels_before_g" not in fresh["recording"]
    assert Setup.parse(fresh, "setup.toml").levels_before_g == ()


@pytest.mark.parametrize("levels, says", [
    ("[0.2, 3.0]", r"item 1 must be in \(0, 1\.019\] g, the bench's 10 m/s² \(got 3\.0\)"),
    ("[0.2, 'nan']", r"must be levels in g \(item 1: 'nan'\)"),
    ("0.3", r"must be an array \(got 0\.3\)"),
    ("[" + ", ".join(["0.2"] * 21) + "]", r"at most 20 levels \(got 21\)"),
])
def test_levels_before_a_take_the_bench_cannot_run_are_refused_naming_the_key(levels, says):
    data = tomllib.loads(setup_toml(20.0, 500.0, (960.0, 900.0)).replace(
        "fps = 20.0", f"fps = 20.0\nlevels_before_g = {levels}"))
    with pytest.raises(InputError, match=r"^setup\.toml: recording\.levels_before_g: " + says):
        Setup.parse(data, "setup.toml")
