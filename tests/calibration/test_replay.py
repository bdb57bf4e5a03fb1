"""Reading a recording for the fit (calibration/replay.py): when the sled stopped, a path
relative to the sled, and the bench replaying a recording (its run stubbed)."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from calibration import features
from calibration import replay as replay_module
from calibration.recording import Truth
from calibration.replay import MIN_FRAMES, stop_s
from calibration.synth import synthesize
from calibration.trajectories import ObjectPath, Trajectories
from wrapenv.bench import SimSettings
from wrapenv.config import InputError
from wrapenv.load import Friction, FrictionPair, LoadUnit
from wrapenv.profile import MeasuredProfile, PulseProfile
from wrapenv.wrap import WrapFormat

T = np.arange(0.0, 3.0, 0.01)


def pulse() -> np.ndarray:
    """A 4.4 m/s^2 pulse until 0.5 s, then braking at 1.1 m/s^2 until 1.5 s."""
    return np.where(T < 0.5, 4.4, np.where(T < 1.5, -1.1, 0.0))


def test_an_ideal_profile_stops_after_its_braking():
    assert stop_s(T, pulse()) == T[149]


def test_a_measured_profile_stops_although_its_noise_never_does():
    noise = np.random.default_rng(0).normal(0.0, 0.05, len(T))   # 1 % of the peak
    assert abs(stop_s(T, pulse() + noise) - 1.49) <= 0.01


def test_a_profile_without_motion_stopped_at_once():
    assert stop_s(T, np.zeros_like(T)) == 0.0


# --- a tracked path relative to the sled, and the bench's replay of it ------------------------

ROOT = Path(__file__).resolve().parents[2]
FRAMES = np.arange(0.0, 0.6, 0.05)       # 12 frames at 20 fps


def _recording(sled_mps: float) -> SimpleNamespace:
    """A recording whose profile.csv puts the sled at `sled_mps` x t."""
    return SimpleNamespace(profile=SimpleNamespace(position_m=lambda t: sled_mps * t))


def _path(x_m: np.ndarray, n: int = len(FRAMES)) -> ObjectPath:
    """An object at world x_m, 0.5 m up and turned 0.01 rad when first seen, as tracked."""
    return ObjectPath(FRAMES[:n], x_m[:n], np.full(n, 0.5), np.full(n, 0.01))


def test_a_path_is_taken_relative_to_the_tracked_sled_from_its_first_frame():
    """A bundle at 1.2 m riding a sled tracked at 0.2 m + 0.5 m/s x t, 3 mm/s slower: relative
    to the sled it slips back 3 mm/s from zero; its height and angle count from their first
    values. profile.csv's sled (1 m/s here) is not used while the sled is tracked."""
    sled = _path(0.2 + 0.5 * FRAMES)
    xza = replay_module._relative(_path(1.2 + 0.497 * FRAMES), sled, _recording(1.0))
    assert xza[0].tolist() == [0.0, 0.0, 0.0]
    assert xza[:, 0] == pytest.approx(-0.003 * FRAMES)
    assert np.abs(xza[:, 1:]).max() == 0.0


@pytest.mark.parametrize("sled_frames", [0, MIN_FRAMES - 1])
def test_a_sled_tracked_too_briefly_is_taken_from_profile_csv(sled_frames):
    sled = _path(0.2 + 0.5 * FRAMES, sled_frames) if sled_frames else None
    xza = replay_module._relative(_path(1.2 + 0.497 * FRAMES), sled, _recording(0.4985))
    assert xza[:, 0] == pytest.approx(-0.0015 * FRAMES)


def _observation(wrap: WrapFormat | None) -> replay_module.Observation:
    """The 2-layer example, its pallet seen for 8 frames of 20 fps, the profile sampled at
    100 Hz from 0.2 s before the first frame."""
    load = LoadUnit.from_toml(ROOT / "examples" / "pet_2layer_columnar.toml")
    t = np.arange(-20, 200) * 0.01
    states = {"pallet": (FRAMES[:8], np.zeros((8, 3)))}
    bodies = features.bodies(load.layout(), {"pallet"})
    profile = MeasuredProfile(t, np.where(t < 0.5, 3.0, 0.0))
    return replay_module.Observation("rec", load, wrap, profile, states, bodies, {"pallet": 8},
                                     np.zeros(16), frozenset(), (0.31, 0.0))


def _fake_level(seen: dict, valid: bool = True):
    """A bench run in which the pallet slides 10 mm/s along x on the sled and turns 0.1 rad/s
    about -y (the sense of the tracker's angles); it notes what it was asked to run."""
    def run_level(layout, profile, settings, wrap):
        seen.update(layout=layout, profile=profile, settings=settings, wrap=wrap)
        t = profile.t_s - profile.t_s[0]
        c, s = np.cos(0.1 * t), np.sin(0.1 * t)
        rot = np.zeros((len(t), 3, 3))
        rot[:, 0, 0], rot[:, 0, 2], rot[:, 1, 1], rot[:, 2, 0], rot[:, 2, 2] = c, -s, 1, s, c
        pos = np.column_stack([0.01 * t, np.zeros_like(t), np.full_like(t, 0.072)])
        return SimpleNamespace(valid=valid, names=(), t_s=t, pallet_pos_m=pos, pallet_rot=rot,
                               bundle_pos_m=np.zeros((len(t), 0, 3)),
                               bundle_rot=np.zeros((len(t), 0, 3, 3)))
    return run_level


def test_a_replay_runs_the_recording_s_profile_to_its_last_window_and_one_frame_more(
        monkeypatch):
    seen: dict = {}
    monkeypatch.setattr(replay_module, "run_level", _fake_level(seen))
    obs = _observation(None)
    simulated = replay_module.replay(obs, obs.load.friction)
    assert obs.end_s == pytest.approx(0.35)
    assert seen["profile"].t_s[[0, -1]] == pytest.approx([-0.2, 0.36])  # 0.35 s and a sample
    assert seen["settings"].max_rest_wait_s == 0.0               # no wait for rest after it
    assert seen["wrap"] is None
    # the pallet's path from its first frame: x, z, and its angle
    assert simulated["pallet"][:, 0] == pytest.approx(0.01 * FRAMES[:8])
    assert simulated["pallet"][:, 2] == pytest.approx(0.1 * FRAMES[:8])
    assert np.abs(simulated["pallet"][:, 1]).max() < 1e-12
    # simulated less recorded, the recording still: the pallet's slip at its underside, its
    # centre's 10 mm/s and what turning moves the underside (h / 2 sin angle), then its turn
    half_h = obs.load.layout().pallet_size_m[2] / 2
    angle = 0.1 * FRAMES[:8]
    assert replay_module.residuals(obs, simulated) == pytest.approx(np.concatenate(
        [0.01 * FRAMES[:8] + half_h * np.sin(angle), half_h * angle]))


def test_a_wrapped_replay_runs_the_wrap_and_load_as_the_scales_correct_them(monkeypatch):
    seen: dict = {}
    monkeypatch.setattr(replay_module, "run_level", _fake_level(seen))
    wrap = WrapFormat.from_toml(ROOT / "examples" / "wrap_kraft_2layer.toml")
    obs = _observation(wrap)
    replay_module.replay(obs, obs.load.friction, {"stiffness": 1.5, "tension": 0.5})
    assert seen["wrap"].material.stiffness_n_per_m == pytest.approx(
        1.5 * wrap.material.stiffness_n_per_m)
    assert [b.tension_n for b in seen["wrap"].bands] == pytest.approx(
        [0.5 * b.tension_n for b in wrap.bands])
    replay_module.replay(obs, obs.load.friction, {"give": 2.0})
    assert seen["wrap"] == wrap


def test_a_replay_runs_a_fit_s_values_to_a_millionth_and_gives_residuals_to_a_nanometre(
        monkeypatch):
    """Below those, the digits are the processor's arithmetic (`replay.VALUE_DECIMALS`): a
    surrogate's points 6e-13 apart were another run on the bench, its tracked slips 1e-16 m
    apart another fit."""
    seen: dict = {}
    monkeypatch.setattr(replay_module, "run_level", _fake_level(seen))
    wrap = WrapFormat.from_toml(ROOT / "examples" / "wrap_kraft_2layer.toml")
    obs = _observation(wrap)
    friction = Friction(pallet_bundle=FrictionPair(0.41 + 6e-13, 0.33 - 6e-13))
    simulated = replay_module.replay(obs, friction, {"stiffness": 1.5 + 4e-13})
    assert seen["layout"].friction == Friction(pallet_bundle=FrictionPair(0.41, 0.33))
    assert seen["wrap"] == wrap.scaled(stiffness_scale=1.5)
    r = replay_module.residuals(obs, simulated)
    assert np.abs(r).max() > 1e-3
    assert np.array_equal(r, r.round(replay_module.RESIDUAL_DECIMALS))


def test_a_replay_that_became_unphysical_is_no_prediction(monkeypatch):
    monkeypatch.setattr(replay_module, "run_level", _fake_level({}, valid=False))
    obs = _observation(None)
    assert replay_module.replay(obs, obs.load.friction) is None


class _FakeUnit:
    """A `BenchUnit` that notes each level it is asked to run and runs the take as
    `_fake_level` does."""

    def __init__(self, seen: dict, layout, settings, wrap) -> None:
        self.seen, self.settings = seen, settings
        seen.update(levels=[], wrap=wrap)

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.seen["closed"] = True

    def level(self, profile, push=None, max_rest_wait_s=None):
        if isinstance(profile, PulseProfile):   # a level before the take
            self.seen["levels"].append((profile.level_g, max_rest_wait_s))
            return SimpleNamespace(valid=True)
        self.seen["levels"].append(("take", max_rest_wait_s))
        return _fake_level(self.seen)(None, profile, self.settings, self.seen["wrap"])


def test_a_take_of_a_unit_that_ran_levels_before_is_replayed_after_them(monkeypatch):
    """A lab's unit runs the levels in order; the replay runs those before the take, each to
    rest (the unit's settings), then the take to its last compared frame, in one unit."""
    seen: dict = {}
    monkeypatch.setattr(replay_module, "BenchUnit", lambda *a: _FakeUnit(seen, *a))
    obs = dataclasses.replace(_observation(None), levels_before_g=(0.2, 0.3))
    simulated = replay_module.replay(obs, obs.load.friction)
    assert seen["levels"] == [(0.2, None), (0.3, None), ("take", 0.0)] and seen["closed"]
    assert seen["profile"].t_s[[0, -1]] == pytest.approx([-0.2, 0.36])
    assert simulated["pallet"][:, 0] == pytest.approx(0.01 * FRAMES[:8])


def test_a_carried_take_is_reproduced_by_its_history_and_not_by_a_fresh_unit(tmp_path):
    """The Kraft-wrapped 2-layer example filmed at 0.5 g after 0.2, 0.3 and 0.4 g, replayed
    at its true values from its true paths: with the levels before, to a twentieth of a
    millimetre (the same bench, the same settings); as a fresh unit, the web never
    tightened by the levels before lets it move 2-3 mm further (benchmarks/carried_takes.py:
    1.0 mm carried, 3.1 mm fresh)."""
    load = LoadUnit.from_toml(ROOT / "examples" / "pet_2layer_columnar.toml")
    wrap = WrapFormat.from_toml(ROOT / "examples" / "wrap_kraft_2layer.toml")
    rec = synthesize(load, tmp_path / "take", wrap=wrap, level_g=0.5, size=(480, 300),
                     fps=10.0, levels_before_g=(0.2, 0.3, 0.4))
    assert rec.levels_before_g == (0.2, 0.3, 0.4)
    truth = Truth.read(rec.folder)
    obs = replay_module.observe(rec, Trajectories({
        name: ObjectPath(o.t_s, o.x_m, o.z_m, o.angle_rad) for name, o in truth.objects.items()}))

    def rms_mm(o: replay_module.Observation) -> float:
        simulated = replay_module.replay(o, load.friction)
        assert simulated is not None
        return 1000 * float(np.sqrt(np.mean(replay_module.residuals(obs, simulated) ** 2)))

    assert rms_mm(obs) < 0.1
    assert rms_mm(dataclasses.replace(obs, levels_before_g=())) > 0.5


def test_repeated_replays_settle_a_step_longer_each():
    base = SimSettings()
    assert [replay_module.resettled(base, k).settle_s for k in range(3)] == pytest.approx(
        [base.settle_s + k * replay_module.SETTLE_STEP_S for k in range(3)])


def _tracked(frames: dict[str, int]) -> Trajectories:
    """The sled and the named objects, each standing still and seen in its number of frames."""
    t = np.arange(40) * 0.05
    return Trajectories({name: ObjectPath(t[:n], np.zeros(n), np.full(n, 0.3), np.zeros(n))
                         for name, n in ({"sled": 40} | frames).items()})


def test_a_recording_is_observed_for_the_load_s_objects_seen_in_ten_frames_or_more(tmp_path):
    """A bundle seen in 9 frames and an object the load does not hold are not compared; the
    sled's peaks, forwards and backwards, are in g."""
    load = LoadUnit.from_toml(ROOT / "examples" / "pet_2layer_columnar.toml")
    t = np.arange(40) * 0.05
    accel = np.where(t < 0.5, 3.924, np.where(t < 1.0, -0.981, 0.0))
    recording = SimpleNamespace(folder=tmp_path, load=load, wrap=None, profile=SimpleNamespace(
        t_s=t, accel_mps2=accel, position_m=lambda s: np.zeros_like(s)), levels_before_g=())
    obs = replay_module.observe(recording, _tracked(
        {"pallet": 40, "L1C1R1": MIN_FRAMES, "L1C2R1": MIN_FRAMES - 1, "tape measure": 40}))
    assert set(obs.frames) == {"pallet", "L1C1R1"}
    assert obs.peak_accel_g == pytest.approx((0.4, 0.1))
    with pytest.raises(InputError, match="no object of the load tracked in 10 frames"):
        replay_module.observe(recording, _tracked({"L1C1R1": MIN_FRAMES - 1}))
