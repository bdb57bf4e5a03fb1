"""The fit's objective (calibration/objective.py): a point is its replays of every recording,
and the objective counts the replays that became unphysical one by one."""

from __future__ import annotations

import numpy as np

import calibration.objective as objective
from calibration.objective import Model, Objective, Param, Progress
from wrapenv.bench import SimSettings
from wrapenv.load import Friction


def test_a_point_is_unphysical_if_one_of_its_replays_is_and_each_replay_counts(monkeypatch,
                                                                              inline_pool):
    # two recordings; the second blows up wherever pallet-bundle's static coefficient > 0.5
    def replay_task(obs, friction, scales, sim):
        blown = obs == "rec-2" and friction.pallet_bundle.static > 0.5
        return None if blown else np.array([friction.pallet_bundle.static])

    monkeypatch.setattr(objective, "_replay_task", replay_task)
    model = Model((Param("static", "pallet_bundle", 0.2, 0.8),
                   Param("ratio", "pallet_bundle", 0.5, 1.0)), Friction())
    obj = Objective(["rec-1", "rec-2"], model, inline_pool, SimSettings())
    out = obj.residuals([np.array([0.25, 1.0]), np.array([0.75, 1.0]), np.array([1.0, 1.0])])
    assert out[0] is not None and np.allclose(out[0], [0.35, 0.35])
    assert out[1] is None and out[2] is None
    assert (obj.replays, obj.unphysical) == (6, 2)


def test_the_loss_curve_starts_again_with_each_stage():
    """The wrap stage's losses (wrapped takes) are not compared with the friction stage's best
    (bare takes): CAL-loss.png would show the wrap stage flat."""
    progress = Progress()
    progress.record([np.zeros(2)], [0.1], 2)
    progress.record([np.ones(2)], [0.3], 2)
    progress.new_stage()
    progress.record([np.zeros(1)], [0.5], 3)
    progress.record([np.ones(1)], [0.4], 3)
    assert progress.curve == [(2, 0.1), (4, 0.1), (7, 0.5), (10, 0.4)]
