"""setup.toml (calibration/camera_setup.py): what synth writes reads back the same, and the
marker size may be left out."""

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


def test_a_marker_id_beyond_its_dictionary_is_named_with_the_dictionary_s_range():
    load = LoadUnit.from_toml(Path(__file__).resolve().parents[2] / "examples"
                              / "pet_2layer_columnar.toml")
    beyond = MarkerSpec("DICT_4X4_50", 0.05, (MarkerPlacement(50, "pallet", (0.5, 0.0)),))
    with pytest.raises(InputError, match=r"^setup\.toml: markers\.placement\[0\]\.id: "
                                         r"DICT_4X4_50 has ids 0 to 49 \(got 50\)$"):
        check_markers(beyond, load, "setup.toml")
    check_markers(MarkerSpec("DICT_4X4_50", None, (MarkerPlacement(49, "sled", (0.0, 0.0)),)),
                  load, "setup.toml")
