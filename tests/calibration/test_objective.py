"""The fit's objective (calibration/objective.py): a point of the unit box is friction pairs
and wrap scales, and its replays of every recording; the objective counts the replays that
became unphysical one by one, keeps the best point and counts simulations by purpose, and
knows where each pair's features lie in a residual vector."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

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


# --- the unit box ----------------------------------------------------------------------------

def test_a_coefficient_is_linear_in_its_coordinate_and_a_scale_is_a_power_of_two():
    """A halving and a doubling of a wrap scale lie equally far from 1; outside the box a
    coordinate is clipped to it."""
    static = Param("static", "pallet_bundle", 0.2, 0.8)
    assert [static.value(u) for u in (0.0, 0.5, 1.0, 1.5)] == pytest.approx([0.2, 0.5, 0.8, 0.8])
    assert [static.unit(v) for v in (0.35, 0.8, 0.9)] == pytest.approx([0.25, 1.0, 1.0])
    stiffness = Param("stiffness", "", -1.0, 1.0)
    assert [stiffness.value(u) for u in (0.0, 0.5, 1.0)] == pytest.approx([0.5, 1.0, 2.0])
    assert [stiffness.unit(v) for v in (0.5, 1.0, 2.0)] == pytest.approx([0.0, 0.5, 1.0])


#: Pallet-bundle by its static coefficient (0.2-0.8) and ratio (0.5-1), bundle-bundle by its
#: kinetic one (0.1-0.5) and ratio, and the film's stiffness scale (1/2 to 2).
MODEL = Model((Param("static", "pallet_bundle", 0.2, 0.8),
               Param("ratio", "pallet_bundle", 0.5, 1.0),
               Param("kinetic", "bundle_bundle", 0.1, 0.5),
               Param("ratio", "bundle_bundle", 0.5, 1.0),
               Param("stiffness", "", -1.0, 1.0)),
              Friction(), {"tension": 0.8})


def test_a_point_is_friction_pairs_kinetic_at_most_static_and_wrap_scales():
    """(0.5, 0.6, 0.25, 0.8, 0.75): pallet-bundle static 0.5, kinetic 0.5 x 0.8 = 0.4;
    bundle-bundle kinetic 0.2, static 0.2 / 0.9 = 0.222; stiffness 2^0.5; the tension scale
    not fitted stays 0.8, sled-pallet the base's."""
    friction, scales = MODEL.decode(np.array([0.5, 0.6, 0.25, 0.8, 0.75]))
    assert (friction.pallet_bundle.static, friction.pallet_bundle.kinetic) == pytest.approx(
        (0.5, 0.4))
    assert (friction.bundle_bundle.static, friction.bundle_bundle.kinetic) == pytest.approx(
        (0.2 / 0.9, 0.2))
    assert friction.sled_pallet == Friction().sled_pallet
    assert scales == pytest.approx({"tension": 0.8, "stiffness": 2**0.5})


def test_encoding_a_decoded_point_gives_the_point_back():
    u = np.array([0.1, 0.9, 0.7, 0.3, 0.2])
    assert MODEL.encode(*MODEL.decode(u)) == pytest.approx(u)


def test_the_best_point_is_the_first_with_the_lowest_loss():
    progress = Progress()
    progress.record([np.zeros(2), np.ones(2)], [0.2, 0.2], 2)
    progress.record([np.full(2, 0.5)], [0.3], 1)
    assert progress.best_u.tolist() == [0.0, 0.0] and progress.best_loss == 0.2


def test_simulations_are_counted_by_what_they_were_for():
    progress = Progress()
    for sims, part in ((4, "search"), (2, "probe"), (0, "validate"), (3, "probe")):
        progress.spend(sims, part)
    assert progress.simulations == 9
    assert progress.parts == {"search": 4, "probe": 5}


def _observation(frames: dict[str, int], pairs: dict[str, str]) -> SimpleNamespace:
    return SimpleNamespace(frames=frames,
                           bodies={name: SimpleNamespace(pair=p) for name, p in pairs.items()})


def test_each_pair_s_features_are_those_of_the_bodies_resting_on_it_in_every_recording(
        inline_pool):
    """Residual vectors hold every recording's features one after the other, each body's
    slip then turn over its tracked frames, bodies by name: the first recording's L1C1R1
    (3 frames) at 0-5, L2C1R1 (2 frames) at 6-9; the second's L1C1R1 (4 frames) at 10-17."""
    first = _observation({"L2C1R1": 2, "L1C1R1": 3},
                         {"L1C1R1": "pallet_bundle", "L2C1R1": "bundle_bundle"})
    second = _observation({"L1C1R1": 4}, {"L1C1R1": "pallet_bundle"})
    obj = Objective([first, second], MODEL, inline_pool, SimSettings())
    features = obj.pair_features()
    assert features["pallet_bundle"].tolist() == [0, 1, 2, 3, 4, 5] + list(range(10, 18))
    assert features["bundle_bundle"].tolist() == [6, 7, 8, 9]
    assert [idx.tolist() for idx in obj.shared_noise] == [
        [0, 1, 2], [3, 4, 5], [6, 7], [8, 9], [10, 11, 12, 13], [14, 15, 16, 17]]
