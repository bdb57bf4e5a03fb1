"""The fit's acceptance test: replays that explain a recording up to their own scatter and one
body in a rare mode are accepted; values that move bodies the same way in every replay are
refused, by hand on made-up residuals and on real replays of a sliding unit."""

from __future__ import annotations

import dataclasses
import math
import types

import numpy as np
import pytest

from calibration import acceptance
from calibration.acceptance import NOISE_VAR_M2, body_unexplained, judge
from calibration.fit import FitSettings, _failure, _Fitted, _unphysical
from calibration.recording import Recording, Truth
from calibration.replay import observe, replay, resettled
from calibration.track import track
from wrapenv.bench import SimSettings
from wrapenv.load import Friction, FrictionPair

LIMIT_M = FitSettings().max_residual_m


def test_a_body_is_unexplained_by_what_its_scatter_and_the_tracker_do_not_cover():
    """Three replays of a body with two features miss the recording by 20 +- 10 mm (sample
    standard deviation 10 mm in each feature). By hand: mean square 0.02^2 = 4e-4, minus the
    scatter 0.01^2 (1 + 1/3) = 1.333e-4 and the tracker's 2 x 0.002^2 = 8e-6: 2.587e-4."""
    r = np.array([[0.01, 0.01], [0.02, 0.02], [0.03, 0.03]])
    assert body_unexplained(r) == pytest.approx(4e-4 - 1e-4 * 4 / 3 - 8e-6)
    assert NOISE_VAR_M2 == pytest.approx(8e-6)
    assert body_unexplained(np.array([[0.001, -0.001]])) == 0.0   # within the tracker's noise


def test_one_replay_has_no_scatter_to_count_and_two_have_their_sample_variance():
    """One replay 20 mm off: 4e-4 less the tracker's 8e-6. Two replays 10 and 30 mm off: the
    same mean, less their sample variance 2e-4 x (1 + 1/2) as well."""
    assert body_unexplained(np.array([[0.02, 0.02]])) == pytest.approx(4e-4 - 8e-6)
    two = np.array([[0.01, 0.01], [0.03, 0.03]])
    assert body_unexplained(two) == pytest.approx(4e-4 - 2e-4 * 1.5 - 8e-6)


def test_a_single_body_s_unexplained_rms_is_its_own():
    assert judge({"pallet": 0.02**2}).rms_m == pytest.approx(0.02)


def test_the_nearest_replay_is_judged_by_its_own_squared_residuals():
    """Of three replays of one body (two features), one 12 mm off, two 40 mm: by their mean
    30.7 mm less their scatter (sample variance 2.613e-4 x 4/3) and the tracker's they leave
    sqrt(5.84e-4) = 24.2 mm; the nearest replay alone sqrt(0.012^2 - 8e-6) = 11.7 mm, which
    is the verdict."""
    r = np.array([[0.012, 0.012], [0.040, 0.040], [0.040, 0.040]])
    assert body_unexplained(r) == pytest.approx(5.84e-4, rel=1e-3)
    verdict = acceptance.by_residuals(r, {"L1C1R1": np.arange(2)}, "rec")
    assert verdict.by == "replay 0"
    assert verdict.rms_m == pytest.approx(math.sqrt(0.012**2 - NOISE_VAR_M2))


def test_one_body_of_nine_in_a_mode_the_replays_never_visited_is_excused():
    """Eight bodies reproduced, one 50 mm off in every replay: the rare mode is excused."""
    bodies = {f"B{k}": 0.0 for k in range(8)} | {"rare": 0.05**2}
    verdict = judge(bodies, "rec")
    assert verdict.excused == ("rare",) and verdict.rms_m == 0.0


def test_values_that_move_several_bodies_alike_are_refused():
    """Three of nine bodies 30 mm off in every replay: one excused, by hand
    sqrt(2 x (0.03^2 - 8e-6) / 9) = 14.1 mm unexplained > 10 mm."""
    off = 0.03**2 - NOISE_VAR_M2
    bodies = {f"B{k}": 0.0 for k in range(6)} | {f"S{k}": off for k in range(3)}
    verdict = judge(bodies, "rec")
    assert verdict.rms_m == pytest.approx(math.sqrt(2 * off / 9))
    assert verdict.rms_m > LIMIT_M and len(verdict.excused) == 1


def _unit_mode(monkeypatch, replays_in_mode: int, replays: int = 6):
    """Nine bodies of one frame each (a slip and a turn feature apiece); a replay either in the
    recording's mode (residual 0) or in another, where four bodies (a layer) miss by 30 mm."""
    monkeypatch.setattr(acceptance, "residuals", lambda obs, run: run["r"])
    obs = dataclasses.make_dataclass("Obs", ["source", "frames"])(
        "rec", {f"B{k}": 1 for k in range(9)})
    other = np.zeros(18)
    other[:8] = 0.03
    runs = [{"r": np.zeros(18) if k < replays_in_mode else other} for k in range(replays)]
    return acceptance.recording(obs, runs[::-1])


def test_a_mode_of_the_whole_unit_that_one_replay_visited_explains_the_recording(monkeypatch):
    """Five replays of six leave the bottom layer (four bodies) 30 mm off, one reproduces the
    recording. By hand, per off body: mean 25 mm, sample variance 1.5e-4 m^2, so the mean
    leaves 6.25e-4 - 1.5e-4 x 7/6 - 8e-6 = 4.42e-4 m^2, and with one body excused
    sqrt(3 x 4.42e-4 / 9) = 12.1 mm > 10 mm; the nearest replay (index 5, the list being
    reversed) leaves nothing."""
    verdict = _unit_mode(monkeypatch, replays_in_mode=1)
    assert verdict.rms_m == 0.0 and verdict.by == "replay 5"
    by_mean = judge({f"B{k}": 4.42e-4 if k < 4 else 0.0 for k in range(9)})
    assert by_mean.rms_m == pytest.approx(0.0121, abs=1e-4) and by_mean.rms_m > LIMIT_M


def test_values_whose_replays_never_visit_the_recordings_mode_are_refused(monkeypatch):
    """All six replays leave four bodies 30 mm off, no scatter: one excused, by hand
    sqrt(3 x (0.03^2 - 8e-6) / 9) = 17.2 mm unexplained by the mean (each replay alike)."""
    verdict = _unit_mode(monkeypatch, replays_in_mode=0)
    assert verdict.rms_m == pytest.approx(math.sqrt(3 * (0.03**2 - NOISE_VAR_M2) / 9))
    assert verdict.rms_m > LIMIT_M


def test_a_replay_that_became_unphysical_leaves_its_recording_unexplained():
    """A blown-up replay is no prediction: whatever the others did, the recording counts as
    unexplained (infinitely), as it does with no replay at all."""
    take = types.SimpleNamespace(source="take")
    sound = {"pallet": (np.zeros(3), np.zeros((3, 3)))}
    assert acceptance.recording(take, [sound, None]).rms_m == math.inf
    assert acceptance.recording(take, []).rms_m == math.inf


def test_small_units_excuse_no_body():
    verdict = judge({"pallet": 0.0, "A": 0.0, "B": 0.03**2}, "rec")
    assert verdict.excused == () and verdict.rms_m == pytest.approx(0.03 / math.sqrt(3))


def test_a_refusal_names_the_recording_and_the_excused_body():
    verdict = acceptance.Unexplained("rec-0.45g", 0.0237, ("L2C2R1",))
    reason = _failure(0.05, verdict, 24, 300, _Fitted(Friction()), FitSettings(), {})
    assert reason.startswith("its values do not reproduce rec-0.45g, which is left 23.7 mm "
                             "unexplained > 10 mm by the scatter of "
                             "its 24 replays")
    assert "L2C2R1" in reason
    explained = dataclasses.replace(verdict, rms_m=0.009)
    assert _failure(0.05, explained, 24, 300, _Fitted(Friction()), FitSettings(), {}) == ""


def test_a_search_most_of_whose_replays_blew_up_is_refused():
    """Counted in replays: with two recordings a design point is two replays, one of which
    may blow up alone."""
    explained = acceptance.Unexplained("rec", 0.001)
    half = _Fitted(Friction(), replays=200, unphysical=100)
    most = _Fitted(Friction(), replays=200, unphysical=101)
    assert _failure(0.005, explained, 6, 240, half, FitSettings(), {}) == ""
    assert _failure(0.005, explained, 6, 240, most, FitSettings(), {}) == (
        "101 of the search's 200 replays became unphysical")


def test_a_fit_whose_final_replays_blew_up_names_the_recordings_and_how_often():
    """A whole unit can blow the bench up at the fitted values in one replay of several: the
    fit is not trusted, and the engineer learns which take did it."""
    blown = {"one-layer-0.5g": (1, 6), "three-layer-0.32g": (2, 6)}
    reason = _failure(math.inf, acceptance.Unexplained("one-layer-0.5g", math.inf), 6, 480,
                      _Fitted(Friction()), FitSettings(), blown)
    assert reason == ("the fitted values' replays became unphysical: one-layer-0.5g in 1 of 6; "
                      "three-layer-0.32g in 2 of 6")
    takes = [types.SimpleNamespace(source=name) for name in ("two-layer-0.3g", *blown)]
    run: dict = {}
    replays = [[run] * 6, [run, None, run, run, run, run], [None, run, None, run, run, run]]
    assert _unphysical(takes, replays) == blown


@pytest.fixture(scope="module")
def slide(slide_dir):
    rec = Recording.read(slide_dir)
    truth = Truth.read(slide_dir).params["friction"]
    friction = Friction(**{k: FrictionPair(v["static"], v["kinetic"]) for k, v in truth.items()})
    return observe(rec, track(rec).trajectories), friction


@pytest.mark.parametrize("static, kinetic, accepted",
                         [(0.0, 0.0, True), (+0.1, 0.0, False), (-0.1, -0.1, False)])
def test_replays_of_the_true_friction_are_accepted_and_friction_off_by_a_tenth_is_not(
        slide, static, kinetic, accepted):
    """Two bundles sliding apart on the pallet, replayed 3 times: with the friction they were
    recorded with the recording is explained; with the sliding pair's static coefficient 0.1
    higher (they start late) or the whole pair 0.1 lower (they slide further) it is not. (The
    static coefficient alone 0.1 lower is not refused: they start sooner, but slide past the
    pallet's edge within 15 frames, and the slip left by then differs by 5 mm RMS.)"""
    obs, friction = slide
    pair = friction.pallet_bundle
    shifted = dataclasses.replace(friction, pallet_bundle=FrictionPair(
        pair.static + static, pair.kinetic + kinetic))
    runs = [replay(obs, shifted, None, resettled(SimSettings(), k)) for k in range(3)]
    verdict = acceptance.worst([obs], [runs])
    assert (verdict.rms_m <= LIMIT_M) == accepted, verdict
