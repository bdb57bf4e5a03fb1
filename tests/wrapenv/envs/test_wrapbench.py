"""The Gymnasium environments (wrapenv/envs): registration, spaces, API checkers, seeding,
actions, reward, info, rendering, the random variant, vector envs and resource use.

Most tests use a tiny unit (one layer of two bundles) and only the target level, so a step
costs about 0.3-0.5 s.
"""

from __future__ import annotations

import importlib
import warnings
from dataclasses import replace
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import wrapenv
from tests.conftest import TINY_LOAD, rss_kb, to_toml
from wrapenv.bench import SimSettings, run_levels
from wrapenv.calibrated import CalibratedPair, Calibration
from wrapenv.config import InputError
from wrapenv.design import N_PARAMS
from wrapenv.envs import OBS_NAMES, WrapBenchEnv, WrapBenchRandomEnv
from wrapenv.envs.random_units import outside
from wrapenv.load import Friction, FrictionPair, LoadUnit

ENV_ID = "wrapenv/WrapBench-v3"
RANDOM_ID = "wrapenv/WrapBenchRandom-v3"
#: One bottom and one top wrap (the least of the space), a touching spiral, every tension at
#: the lowest; everything at its maximum.
CHEAP = -np.ones(N_PARAMS, np.float32)
EXPENSIVE = np.ones(N_PARAMS, np.float32)
#: The machine's default program: 3 bottom and 3 top wraps (of 1-6), a 50 % spiral (0.5 / 0.75
#: of the overlap range), no reinforcement, every tension at half the yield force (the range's
#: top).
DEFAULT = np.array([-0.2, -0.2, -1, 1 / 3, 0, 1, 1, 1, 1], np.float32)
INFO_KEYS = {"format", "verdict", "material_used", "cycle_time_s", "passed", "margin", "valid",
             "reward_terms"}


@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("env") / "LOAD.toml"
    path.write_text(to_toml(TINY_LOAD))
    return path


def make(tiny: Path, **kwargs) -> WrapBenchEnv:
    kwargs = {"load": tiny, "levels": "target", "target_g": 0.3, **kwargs}
    return WrapBenchEnv(**kwargs)


def test_import_registers_both_ids_and_reimport_is_silent():
    assert ENV_ID in gym.registry and RANDOM_ID in gym.registry
    assert gym.registry[ENV_ID].entry_point == "wrapenv.envs:WrapBenchEnv"
    assert gym.registry[RANDOM_ID].entry_point == "wrapenv.envs:WrapBenchRandomEnv"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        importlib.reload(wrapenv)


@pytest.mark.parametrize("old", ["wrapenv/WrapBench-v2", "wrapenv/WrapBench-v1",
                                 "wrapenv/WrapBenchRandom-v0"])
def test_an_earlier_version_names_the_current_one(old):
    """v2's bottom wraps covered the fork entries; v1's actions meant other programs (no bottom
    or top wrap needed); v0 laid bands."""
    with pytest.raises(gym.error.DeprecatedEnv, match="-v3"), warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        gym.make(old)


@pytest.mark.parametrize("env_id", [ENV_ID, "wrapenv:" + ENV_ID])
def test_gym_make_steps_one_step_episode(tiny, env_id):
    env = gym.make(env_id, load=str(tiny), levels="target", target_g=0.3)
    obs, info = env.reset(seed=1)
    assert env.observation_space.contains(obs)
    obs, reward, terminated, truncated, info = env.step(np.zeros(N_PARAMS, np.float32))
    assert terminated is True and truncated is False
    assert isinstance(reward, float) and info["passed"]
    env.close()


def test_default_kwargs_use_the_bundled_example():
    env = gym.make(ENV_ID)
    unit = env.unwrapped.unit
    assert unit == LoadUnit.from_toml("examples/pet_2layer_columnar.toml")
    assert env.unwrapped.levels == "eumos" and env.unwrapped.target_g == 0.5
    env.close()


def test_spaces_and_observation_features(tiny):
    env = make(tiny, material="lldpe")
    assert env.action_space == gym.spaces.Box(-1, 1, (9,), np.float32)
    space = env.observation_space
    assert space.dtype == np.float32 and space.shape == (len(OBS_NAMES),) == (31,)
    obs, _ = env.reset(seed=0)
    assert space.contains(obs)
    named = dict(zip(OBS_NAMES, obs.tolist(), strict=True))
    assert named["layers"] == pytest.approx(1 / 4)
    assert named["bundle_length"] == pytest.approx(0.28 / 0.5)
    assert named["bundle_mass"] == pytest.approx(9.3 / 20)
    assert named["pallet_length"] == pytest.approx(1.0)
    assert named["load_height"] == pytest.approx((0.144 + 0.33) / 2)
    assert (named["pattern_columnar"], named["pattern_interlocked"],
            named["pattern_explicit"]) == (0, 0, 1)
    assert named["friction_pallet_bundle_static"] == pytest.approx(0.30)
    assert named["friction_sled_pallet_kinetic"] == pytest.approx(0.34)
    assert named["target_g"] == pytest.approx(0.3)
    assert named["friction_bundle_bundle_static_std"] == 0.0
    # the web by its card's figures (LLDPE as applied, docs/materials.md card 2b)
    assert named["material_grammage"] == pytest.approx(0.0184 / 3.5 / 0.1)
    assert named["material_log_stiffness"] == pytest.approx(np.log10(2500) / 6)
    assert (named["material_yield_strain"], named["material_break_strain"]) == pytest.approx(
        (0.15, 0.55))
    assert named["material_break_force"] == pytest.approx(0.13)
    assert named["material_is_paper"] == 0.0
    kraft, _ = make(tiny, material="kraft").reset(seed=0)
    assert dict(zip(OBS_NAMES, kraft.tolist(), strict=True))["material_is_paper"] == 1.0


def test_calibration_sets_friction_and_its_std(tiny, tmp_path):
    cal = tmp_path / "CAL.json"
    cal.write_text('{"friction": {"pallet_bundle": {"static": 0.5, "kinetic": 0.4, '
                   '"static_std": 0.03, "kinetic_std": 0.02}}, '
                   '"wrap": {"stiffness_scale": 1.0, "tension_scale": 1.0}}')
    obs, _ = make(tiny, calibration=str(cal)).reset()
    named = dict(zip(OBS_NAMES, obs.tolist(), strict=True))
    assert named["friction_pallet_bundle_static"] == pytest.approx(0.5)
    assert named["friction_pallet_bundle_static_std"] == pytest.approx(0.03)
    assert named["friction_pallet_bundle_kinetic_std"] == pytest.approx(0.02)
    assert named["friction_sled_pallet_static_std"] == 0.0


def test_numpy_numbers_are_taken_as_numbers(tiny):
    """An RL config's sampled values are NumPy scalars; a bool is no number."""
    env = make(tiny, target_g=np.float32(0.3), material_weight=np.int64(1))
    assert env.target_g == pytest.approx(0.3) and env.material_weight == 1.0
    env.close()
    with pytest.raises(InputError, match="target_g"):
        make(tiny, target_g=True)


@pytest.mark.parametrize("kwargs", [
    {"material": "paper"}, {"target_g": 1.5}, {"target_g": 0.5, "start_g": 0.7},
    {"levels": "all"}, {"material_weight": -1.0}, {"render_mode": "human"},
    {"load": "/nonexistent/LOAD.toml"}, {"material_weight": np.float32("nan")},
    {"target_g": np.bool_(True)}, {"orientation": "diagonal"}, {"hours_since_wrapping": -1.0},
    {"hours_since_wrapping": float("nan")}, {"uncertain": "yes"},
    {"tests_per_episode": 0, "uncertain": True}, {"tests_per_episode": 17, "uncertain": True},
    {"tests_per_episode": 2.0, "uncertain": True}, {"tests_per_episode": True, "uncertain": True},
    {"tests_per_episode": 2},   # nothing drawn: every test the same run
])
def test_bad_kwargs_raise_at_construction(tiny, kwargs):
    with pytest.raises(ValueError) as err:
        make(tiny, **kwargs)
    assert isinstance(err.value, InputError)
    assert "\n" not in str(err.value)
    if "load" in kwargs:
        assert err.value.source == "/nonexistent/LOAD.toml"
    else:  # named as gym.make's argument, also where a check is shared with the input files
        assert err.value.source == "arguments" and err.value.field in kwargs


@pytest.mark.parametrize("kwargs, says", [
    ({"load": 3}, "load must be a LOAD.toml path or a LoadUnit"),
    ({"calibration": {"friction": {}}}, "calibration must be a CAL.json path"),
    ({"settings": {"timestep_s": 0.01}}, "settings must be a wrapenv.bench.SimSettings"),
])
def test_an_argument_of_the_wrong_type_is_a_type_error_saying_what_it_takes(tiny, kwargs, says):
    """A programming error, not bad input: Python's TypeError, naming the types taken."""
    with pytest.raises(TypeError, match=says):
        make(tiny, **kwargs)


def test_a_unit_beyond_the_observation_s_range_is_refused_naming_the_feature(
        assert_input_error):
    """One 250 kg drum on a pallet is a valid load, but its bundle mass is 12.5 times the
    observation's 20 kg scale, beyond the space's bound of 10: no observation may leave it."""
    drum = LoadUnit.from_dict({
        "name": "drum", "pallet": {"preset": "EUR"},
        "bundle": {"length_m": 0.6, "width_m": 0.6, "height_m": 0.9, "mass_kg": 250.0},
        "stack": {"layers": 1, "pattern": "explicit", "positions": [[0.0, 0.0]]}})
    with pytest.raises(InputError, match=r"feature 4 \(bundle_mass\) is 12.500, outside "
                                         r"\[0, 10\]") as info:
        WrapBenchEnv(load=drum)
    assert_input_error(info.value, "drum", "load")


@pytest.mark.parametrize("levels", ["target", "eumos"])
def test_a_target_below_the_usual_start_starts_there(tiny, levels):
    """start_g is the standard's 0.2 g unless the target is lower: a 0.15 g target is valid."""
    env = make(tiny, target_g=0.15, levels=levels)
    assert env.unwrapped._sequence == [0.15]
    env.close()


def test_unknown_material_message_names_the_choices(tiny):
    with pytest.raises(InputError, match="material: must be one of 'kraft', 'lldpe'"):
        make(tiny, material="paper")


def test_gymnasium_check_env(tiny):
    env = gym.make(ENV_ID, load=str(tiny), levels="target", target_g=0.3)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        gym_check_env(env.unwrapped, skip_render_check=False)
    assert not [str(w.message) for w in caught]
    env.close()


def test_sb3_check_env(tiny):
    env = make(tiny)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sb3_check_env(env)
    assert not [str(w.message) for w in caught]
    env.close()


def test_same_seed_and_action_give_identical_results(tiny):
    action = np.random.default_rng(3).uniform(-1, 1, N_PARAMS).astype(np.float32)
    results = []
    for _ in range(2):
        env = make(tiny)
        obs0, info0 = env.reset(seed=42)
        obs, reward, terminated, truncated, info = env.step(action)
        results.append((obs0, info0, obs, reward, info))
        env.close()
    (a0, ai0, a, ra, ia), (b0, bi0, b, rb, ib) = results
    np.testing.assert_array_equal(a0, b0)
    np.testing.assert_array_equal(a, b)
    assert ai0 == bi0 and ra == rb and ia == ib


def test_out_of_range_actions_are_clipped_and_nan_raises(tiny):
    env = make(tiny)
    env.reset(seed=0)
    wild = np.array([5.0, -7.0, 1.5, 3.0, -2.0, 9.0, -9.0, 1.0, 4.0], np.float32)
    assert env.decode(wild) == env.decode(np.clip(wild, -1, 1))
    _, r_wild, _, _, i_wild = env.step(wild)
    _, r_clip, _, _, i_clip = env.step(np.clip(wild, -1, 1))
    assert r_wild == r_clip and i_wild == i_clip
    bad = np.zeros(N_PARAMS, np.float32)
    bad[2] = np.nan
    with pytest.raises(ValueError, match="finite"):
        env.step(bad)
    with pytest.raises(ValueError, match="9 values"):
        env.step(np.zeros(5, np.float32))
    with pytest.raises(ValueError, match="9 values"):
        env.step(np.zeros((3, 3), np.float32))   # nine values, but not one program


def test_cheaper_passing_program_scores_higher(tiny):
    env = make(tiny)
    env.reset(seed=0)
    _, r_cheap, _, _, cheap = env.step(CHEAP)
    _, r_dear, _, _, dear = env.step(EXPENSIVE)
    assert cheap["passed"] and dear["passed"]
    assert cheap["material_used"]["mass_kg"] < dear["material_used"]["mass_kg"]
    assert r_cheap > r_dear
    for info, reward in ((cheap, r_cheap), (dear, r_dear)):
        terms = info["reward_terms"]
        assert reward == pytest.approx(terms["verdict"] + terms["material"])
        assert terms["verdict"] == pytest.approx(1 + min(info["margin"], 0.5))
        ratio = info["material_used"]["mass_kg"] / env.reference_mass_kg
        assert terms["material"] == pytest.approx(-ratio)
    # the machine's default program is the reference; on this 0.474 m unit the bottom wraps lie
    # where the top wraps' web (5 cm above the load) starts: 0.474 + 0.05 - 0.5 m
    default = env.step(DEFAULT)[4]
    assert default["format"]["program"] == {
        "bottom_wraps": 3, "bottom_from_m": 0.024, "bottom_tension_n": 800.0, "up_overlap": 0.5,
        "middle_tension_n": 800.0, "top_wraps": 3, "top_overhang_m": 0.05,
        "top_tension_n": 800.0}
    assert default["reward_terms"]["material"] == pytest.approx(-1)


def test_the_screening_settings_keep_the_reward_of_a_pass(tiny):
    """`SimSettings.screening()` (a level ends at its first rest, or once failed) judges a pass
    as the defaults do: same verdict, the margin within 0.002."""
    default, screening = (make(tiny, settings=s) for s in (SimSettings(),
                                                           SimSettings.screening()))
    for action in (CHEAP, EXPENSIVE):
        default.reset(seed=0)
        screening.reset(seed=0)
        _, full, *_, a = default.step(action)
        _, screened, *_, b = screening.step(action)
        assert a["passed"] and b["passed"]
        assert b["margin"] == pytest.approx(a["margin"], abs=0.002)
        assert screened == pytest.approx(full, abs=0.002)


def test_the_training_settings_judge_a_pass_as_a_pass(tiny):
    """`SimSettings.training()` (PPO's: the screening fidelity at a 1.5 x longer step, its
    rest held half as long) gives the same verdicts, the margin within the bench's own
    reproducibility (0.15). Its limit: the space's heaviest program squeezes these two bundles
    into each other (174 mm) at that step; the random units of training fill a pallet, and
    rarely blow up (benchmarks/bench_train.py and a training run's log.csv count them)."""
    fine, coarse = SimSettings(), SimSettings.training()
    assert coarse.timestep_s == pytest.approx(1.5 * fine.timestep_s)
    assert coarse.rest_hold_s == pytest.approx(fine.rest_hold_s / 2)
    assert replace(coarse, timestep_s=fine.timestep_s, rest_hold_s=fine.rest_hold_s) == \
        SimSettings.screening()
    default, training = (make(tiny, settings=s) for s in (SimSettings(),
                                                          SimSettings.training()))
    for action in (CHEAP, DEFAULT):
        default.reset(seed=0)
        training.reset(seed=0)
        a, b = default.step(action)[4], training.step(action)[4]
        assert a["passed"] and b["passed"]
        assert b["margin"] == pytest.approx(a["margin"], abs=0.15)


def test_material_weight_scales_the_material_term(tiny):
    env = make(tiny, material_weight=0.0)
    env.reset()
    assert env.step(CHEAP)[4]["reward_terms"]["material"] == 0.0


def test_info_keys_and_verdict_json(tiny):
    env = make(tiny, levels="eumos", target_g=0.3)
    env.reset()
    *_, info = env.step(np.zeros(N_PARAMS, np.float32))
    assert INFO_KEYS <= set(info)
    assert set(info["verdict"]) == {"sequence", "valid", "load_height_m", "levels",
                                    "highest_passed_g"}
    assert [lv["level_g"] for lv in info["verdict"]["levels"]] == [0.2, 0.3]
    level = info["verdict"]["levels"][-1]
    assert {"level_g", "passed", "elastic_max_m", "permanent_max_m", "permanent_low20_m",
            "pallet_slip_m", "damage", "criteria", "bodies", "wrap"} <= set(level)
    assert {"area_m2", "mass_kg"} <= set(info["material_used"])
    assert info["format"]["material"] == "kraft" and info["format"]["bands"]
    assert info["format"]["program"]["up_overlap"] == 0.38  # 0 .. 0.75 halfway, in whole %
    assert info["cycle_time_s"] > 0
    assert info["valid"] is True and isinstance(info["margin"], float)


def test_render_frames_and_close_twice(tiny):
    env = make(tiny, render_mode="rgb_array")
    env.reset()
    before = env.render()
    env.step(EXPENSIVE)
    after = env.render()
    for frame in (before, after):
        assert frame.shape == (300, 480, 3) and frame.dtype == np.uint8
    assert not np.array_equal(before, after)  # the wrap is drawn over the tested unit
    env.close()
    env.close()
    with pytest.warns(UserWarning, match="render_mode"):
        assert make(tiny).render() is None  # no render_mode


def test_random_env_units_follow_the_seed():
    env = WrapBenchRandomEnv(levels="target")
    with pytest.raises(gym.error.ResetNeeded):
        env.step(np.zeros(N_PARAMS, np.float32))
    obs = {seed: env.reset(seed=seed)[0] for seed in range(6)}
    again, _ = env.reset(seed=3)
    np.testing.assert_array_equal(obs[3], again)
    assert len({o.tobytes() for o in obs.values()}) == 6
    for o in obs.values():
        assert env.observation_space.contains(o)
    units = [env.sample_unit(np.random.default_rng(s)) for s in range(40)]
    assert all(1 <= u.stack.layers <= 3 and u.stack.pattern in ("columnar", "interlocked")
               for u in units)
    assert {u.stack.pattern for u in units} == {"columnar", "interlocked"}
    for u in units:
        for pair in ("sled_pallet", "pallet_bundle", "bundle_bundle"):
            f, base = u.friction.pair(pair), env.base_friction.pair(pair)
            assert abs(f.static / base.static - 1) <= 0.15 + 1e-2
            assert f.kinetic == pytest.approx(0.8 * f.static, abs=1e-3)
    with pytest.raises(TypeError):
        WrapBenchRandomEnv(load="x.toml")
    env.close()


def test_random_units_take_a_calibration_as_the_fixed_env_does():
    """A pair that never slipped is only bounded (0.10 g held is no friction of 0.10), and the
    calibrated give scales the units' edges: as `Calibration.apply` takes them."""
    cal = Calibration({"sled_pallet": CalibratedPair(0.10, 0.08, identified=False),
                       "pallet_bundle": CalibratedPair(0.62, 0.52)}, give_scale=0.5)
    env = WrapBenchRandomEnv(levels="target", calibration=cal)
    assert env.base_friction.sled_pallet == Friction().sled_pallet
    assert env.base_friction.pallet_bundle == FrictionPair(0.62, 0.52)
    drawn = env.sample_unit(np.random.default_rng(1))
    plain = WrapBenchRandomEnv(levels="target").sample_unit(np.random.default_rng(1))
    assert drawn.bundle.corner_stiffness_n_per_m2 == pytest.approx(
        0.5 * plain.bundle.corner_stiffness_n_per_m2)
    env.close()


def test_units_outside_the_random_distribution_say_how():
    """What a policy trained on random units never saw: every drawn unit and the paper's
    units at the bench's default friction lie inside; the half-pallet example is named by its
    pallet and by the examples' friction (pallet-bundle 0.50 where the units draw 0.30 +- 15 %);
    a free explicit stack of heavy bundles by each of those."""
    env = WrapBenchRandomEnv(levels="target")
    rng = np.random.default_rng(0)
    assert all(outside(env.sample_unit(rng)) == () for _ in range(20))
    env.close()
    for name in ("pet_2layer_columnar", "pet_3layer_columnar", "pet_3layer_interlocked"):
        unit = LoadUnit.from_toml(f"examples/{name}.toml")
        assert outside(unit.with_friction(Friction())) == ()
    half = LoadUnit.from_toml("examples/pet_3layer_half_pallet.toml")
    assert outside(half) == (
        "a 0.8 x 0.6 m pallet, not the EUR pallet's 1.2 x 0.8",
        "pallet_bundle static 0.5, not 0.255-0.345", "pallet_bundle kinetic 0.42, not 0.204-0.276",
        "bundle_bundle static 0.4, not 0.255-0.345", "bundle_bundle kinetic 0.33, not 0.204-0.276")
    # units drawn about the examples' friction (a calibration's, say) take theirs in
    assert outside(half, base=half.friction) == (
        "a 0.8 x 0.6 m pallet, not the EUR pallet's 1.2 x 0.8",)
    odd = LoadUnit.from_dict({
        "pallet": {"preset": "EUR"}, "stack": {"layers": 4, "pattern": "explicit",
                                               "positions": [[0.0, 0.0]]},
        "bundle": {"preset": "PET6x1.5L", "mass_kg": 20.0}})
    assert outside(odd) == ("4 layers, not 1-3", "the explicit pattern, not columnar or "
                            "interlocked", "bundle mass_kg 20, not 4-14",
                            "no stop bar behind the pallet")


def test_random_env_via_gym_make():
    env = gym.make(RANDOM_ID, levels="target", target_g=0.3)
    obs, info = env.reset(seed=5)
    assert env.observation_space.contains(obs) and info["load"].startswith("random")
    env.close()


def test_async_vector_env_steps_and_closes(tiny):
    envs = gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="async", load=str(tiny),
                        levels="target", target_g=0.3)
    try:
        obs, _ = envs.reset(seed=0)
        assert obs.shape == (2, 31)
        obs, reward, terminated, truncated, info = envs.step(np.stack([CHEAP, EXPENSIVE]))
        assert terminated.tolist() == [True, True] and truncated.tolist() == [False, False]
        assert reward[0] > reward[1]
    finally:
        envs.close()


def test_many_steps_do_not_grow_memory(tiny):
    env = make(tiny, render_mode="rgb_array")
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    env.step(np.zeros(N_PARAMS, np.float32))
    env.render()
    before = rss_kb()
    for i in range(30):
        env.reset(seed=i)
        env.step(rng.uniform(-1, 1, N_PARAMS).astype(np.float32))
        if i % 10 == 0:
            env.render()
    grown_mb = (rss_kb() - before) / 1024
    env.close()
    assert grown_mb < 50


@pytest.mark.slow
def test_random_env_passes_the_checkers():
    env = gym.make(RANDOM_ID, levels="target", target_g=0.3)
    gym_check_env(env.unwrapped, skip_render_check=False)
    sb3_check_env(env.unwrapped)
    env.close()


# -- the test a program is verified on: either side, relaxed, in a sample ------------------------

@pytest.mark.parametrize("side", ["long", "short"])
def test_a_side_asked_for_is_the_side_tested(tiny, side):
    """The env's verdict is the bench's own run of that side (the tiny unit's two bundles stand
    along x: turned, they meet the motion side by side)."""
    env = make(tiny, orientation=side)
    _, info0 = env.reset(seed=0)
    *_, info = env.step(DEFAULT)
    unit, wrap = env.tested(env.decode(DEFAULT))
    expected = run_levels(unit, [0.3], orientation=side, stop_at_failure=True, wrap=wrap)
    assert info0["orientation"] == info["orientation"] == side
    assert info["verdict"] == expected.verdict.to_json()
    env.close()


def test_a_random_side_is_drawn_at_every_reset_and_follows_the_seed(tiny):
    def sides(seed: int) -> list[str]:
        env = make(tiny, orientation="random")
        drawn = [env.reset(seed=seed)[1]["orientation"]] + [
            env.reset()[1]["orientation"] for _ in range(15)]
        env.close()
        return drawn

    assert sides(5) == sides(5) != sides(6)
    assert set(sides(5)) == {"long", "short"}


def test_a_relaxed_wrap_is_tested_at_the_tension_its_material_keeps(tiny):
    """16 h after wrapping Kraft keeps 88.5 % of its tension (docs/materials.md, relaxation);
    the program, and so the web costed, is the one entered into the machine."""
    fresh, relaxed = make(tiny), make(tiny, hours_since_wrapping=16.0)
    for env in (fresh, relaxed):
        env.reset(seed=0)
    program = fresh.decode(DEFAULT)
    (_, as_laid), (_, after) = fresh.tested(program), relaxed.tested(program)
    kept = [b.tension_n / a.tension_n for a, b in zip(as_laid.bands, after.bands, strict=True)]
    assert kept == pytest.approx([0.885] * len(kept), abs=5e-4)
    assert as_laid == program  # no calibration, fresh: the program as it is
    _, _, _, _, info = relaxed.step(DEFAULT)
    assert info["material_used"] == fresh.step(DEFAULT)[4]["material_used"]
    for env in (fresh, relaxed):
        env.close()


def test_an_uncertain_env_tests_one_unobserved_sample_per_reset(tiny):
    nominal, env = make(tiny), make(tiny, uncertain=True, hours_since_wrapping=16.0)
    obs_nominal, _ = nominal.reset(seed=1)
    obs, info0 = env.reset(seed=1)
    np.testing.assert_array_equal(obs, obs_nominal)  # the sample is not observed
    sample = env.uncertainty.draw(env.unit, 0)  # any draw: how a sample changes what is tested
    unit, wrap = env.tested(env.decode(DEFAULT), sample)
    assert unit == sample.load(env.unit) and wrap == sample.wrap(env.decode(DEFAULT))
    assert unit.friction != env.unit.friction and unit.bundle.mass_kg != env.unit.bundle.mass_kg
    _, again = env.reset(seed=1)
    assert again["sample"] == info0["sample"] != env.reset()[1]["sample"]
    *_, info = env.step(DEFAULT)
    assert info["sample"]["hours_since_wrapping"] == 16.0
    nominal.close()
    env.close()


def test_several_tests_an_episode_are_judged_by_the_worst(tiny):
    """Each test is the bench's own run of its drawn side and sample; the step's verdict,
    reward and shown side and sample are those of the test with the smallest margin (a failure
    before any pass)."""
    env = make(tiny, orientation="random", uncertain=True, hours_since_wrapping=16.0,
               tests_per_episode=4)
    env.reset(seed=2)
    program = env.decode(CHEAP)
    runs = []
    for side, sample in env._tests:
        unit, wrap = env.tested(program, sample)
        runs.append(run_levels(unit, [0.3], orientation=side, stop_at_failure=True, wrap=wrap))
    *_, info = env.step(CHEAP)
    margins = [r.verdict.margin for r in runs]
    worst = min(range(4), key=lambda i: (runs[i].verdict.passed, margins[i]))
    assert len(set(margins)) > 1   # the samples differ: which one judges matters
    assert info["verdict"] == runs[worst].verdict.to_json()
    assert info["tests_passed"] == sum(r.verdict.passed for r in runs)
    assert info["passed"] == all(r.verdict.passed for r in runs)
    assert (info["orientation"], info["sample"]) == (env._tests[worst][0],
                                                     env._tests[worst][1].to_json())
    env.close()


def test_the_first_of_several_tests_is_the_one_test_of_the_same_seed(tiny):
    """Tests are drawn test by test, side then sample, so one test an episode draws what it
    always drew and more tests add draws after it."""
    infos = []
    for k in (1, 3):
        env = make(tiny, orientation="random", uncertain=True, tests_per_episode=k)
        infos.append(env.reset(seed=7)[1])
        assert len(env._tests) == k
        env.close()
    assert infos[0] == infos[1]


@pytest.mark.parametrize("kwargs", [{}, {"orientation": "random"}, {"uncertain": True}])
def test_an_episode_needs_a_reset_before_the_first_step(tiny, kwargs):
    """Gymnasium's order, in every mode (the fixed unit's env stepped without one)."""
    env = make(tiny, **kwargs)
    with pytest.raises(gym.error.ResetNeeded, match="call reset"):
        env.step(DEFAULT)
    env.close()


def test_a_new_unit_is_drawn_by_a_renderer_of_its_own_and_the_old_one_closed():
    env = WrapBenchRandomEnv(levels="target", render_mode="rgb_array")
    env.reset(seed=1)
    first_frame, first = env.render(), env._renderer
    env.reset(seed=2)
    second_frame = env.render()
    assert first is not None and first.world.closed and env._renderer is not first
    assert first_frame.shape == second_frame.shape and not np.array_equal(first_frame,
                                                                          second_frame)
    env.close()


def test_the_short_side_renders_turned(tiny):
    long_env = make(tiny, orientation="long", render_mode="rgb_array")
    short_env = make(tiny, orientation="short", render_mode="rgb_array")
    frames = []
    for env in (long_env, short_env):
        env.reset(seed=0)
        frames.append(env.render())
        env.close()
    assert not np.array_equal(*frames)


def test_the_readme_s_example_runs_as_pasted_in_a_new_interpreter():
    """The README's Gymnasium block, run on its own: a new user pasted it without the import
    that registers the environments and got `NamespaceNotFound`."""
    import subprocess
    import sys

    root = Path(__file__).resolve().parents[3]
    readme = (root / "README.md").read_text()
    start = readme.index("    import gymnasium as gym\n")
    block = readme[start:readme.index("\n\n", start)]
    code = "\n".join(line.removeprefix("    ") for line in block.splitlines())
    assert "env.step(" in code and "env.close()" in code
    done = subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
