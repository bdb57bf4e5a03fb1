"""What the search's tests share: a small load and the cheapest search settings."""

from __future__ import annotations

from typing import Any

import pytest

from recommender.problem import SearchSettings
from wrapenv.load import LoadUnit

#: Two layers of four PET bundles on a EUR pallet, against the stop bar: each bench run takes
#: a fraction of a second.
TWO_LAYERS_OF_FOUR: dict[str, Any] = {
    "name": "small",
    "pallet": {"preset": "EUR"},
    "bundle": {"preset": "PET6x1.5L"},
    "stack": {"layers": 2, "pattern": "explicit",
              "positions": [[-0.15, -0.1], [0.15, -0.1], [-0.15, 0.1], [0.15, 0.1]]},
    "fixture": {"pallet_stopper": True},
}
#: A CAL.json `calibrate --max-residual-mm 30` wrote, 28 mm of a recording unexplained, and the
#: warning every command given it says.
LOOSE_CALIBRATION: dict[str, Any] = {
    "friction": {"pallet_bundle": {"static": 0.5, "kinetic": 0.4}},
    "acceptance": {"max_residual_m": 0.03, "least_explained": "takes/0.45g",
                   "unexplained_rms_m": 0.028, "explained_by": "replay 3", "excused": []}}
LOOSE_WARNING = ("warning: the calibration was accepted with 28.0 mm of a recording unexplained, "
                 "where a default fit refuses more than 10 mm")
#: One orientation, no relaxation: the search's own behaviour, at the least cost.
FAST = SearchSettings(targets=(("long", 0.5),), samples=2, popsize=4, max_candidates=8,
                      workers=2, hours_since_wrapping=0.0)


@pytest.fixture
def two_layers_of_four() -> LoadUnit:
    return LoadUnit.from_dict(TWO_LAYERS_OF_FOUR)
