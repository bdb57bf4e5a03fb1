"""The PPO policy (recommender/policy.py): training writes the policy, checkpoints and an episode
log; a policy proposes a valid program for any unit; a policy file says what it was trained on
and is refused by a bench it does not fit, without unpickling anything; held-out units are
reproducible and differ from the training envs'; and (slow) a short training run beats random
actions on held-out units.

Every step of `wrapenv/WrapBenchRandom-v3` simulates a random unit of 1-3 layers, about 1-3 s
each on one core, so the fast training test runs only 8 timesteps (about 20-30 s).
"""

from __future__ import annotations

import csv
import io
import json
import math
import tempfile
import time
import zipfile
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from stable_baselines3.common.env_util import make_vec_env

import recommender.policy
from recommender.cli import main
from recommender.episodes import PooledVecEnv
from recommender.policy import (
    CHECKPOINT_DIR,
    LOG_COLUMNS,
    MAKE_ID,
    MAX_ROLLOUT_STEPS,
    POLICY_META,
    Checkpoints,
    EpisodeLog,
    TimeBudget,
    TrainSettings,
    env_kwargs,
    evaluate,
    held_out_loads,
    last_checkpoint,
    load_policy,
    new_model,
    pass_rate,
    policy_meta,
    propose,
    read_meta,
    run_trial,
    stamp,
    train,
)
from tests.cli import one_line
from tests.conftest import TINY_LOAD
from tests.recommender.conftest import LOOSE_CALIBRATION, LOOSE_WARNING
from wrapenv.bench import SimSettings
from wrapenv.calibrated import Calibration
from wrapenv.config import InputError
from wrapenv.design import MAX_REINFORCEMENT_WRAPS, MAX_WRAPS, N_PARAMS, NAMES, ProgramSpace
from wrapenv.envs import OBS_NAMES, WrapBenchRandomEnv
from wrapenv.envs.wrapbench import MAX_TESTS_PER_EPISODE
from wrapenv.load import LoadUnit
from wrapenv.pool import most_workers
from wrapenv.uncertainty import TRANSPORT_HOURS
from wrapenv.wrap import WrapFormat

#: Its trained run is made once, in one test process (`--dist loadgroup`).
pytestmark = pytest.mark.xdist_group("policy")

#: TINY_LOAD's bundle, heavier (14 kg, not 9.3 kg).
HEAVY_BUNDLE = {"length_m": 0.28, "width_m": 0.19, "height_m": 0.33, "mass_kg": 14.0}
TINY = TrainSettings(timesteps=8, n_envs=1, n_steps=4, batch_size=4, checkpoint_every=4,
                     progress_bar=False)


@pytest.fixture(scope="module")
def trained(tmp_path_factory) -> tuple[Path, Path]:
    """A barely trained policy (two PPO updates on 4 episodes each) and its output folder."""
    out = tmp_path_factory.mktemp("policy")
    return train(TINY, out), out


def test_default_settings_are_a_sane_short_run():
    s = TrainSettings()
    assert s.timesteps >= s.n_steps * s.n_envs  # at least one PPO update
    assert (s.n_steps * s.n_envs) % s.batch_size == 0  # minibatches split the rollout evenly
    assert 0 < s.checkpoint_every <= s.timesteps
    assert s.levels == "target" and s.material == "kraft" and s.target_g == 0.5
    assert 0 < s.learning_rate < 1e-2
    assert s.sim == SimSettings.training()  # the envs' fidelity; proposals run at the defaults
    s.check()


@pytest.mark.parametrize("field, value", [("timesteps", 0), ("n_envs", 0), ("workers", 0),
                                          ("batch_size", 1.5),
                                          ("learning_rate", float("nan")),
                                          ("learning_rate", float("inf")),
                                          ("learning_rate", 0.0),
                                          ("max_minutes", -1.0), ("max_minutes", float("nan")),
                                          ("test", "easy"), ("material_weight", -0.1),
                                          ("material_weight", float("inf")),
                                          ("log_std_init", float("nan")),
                                          ("log_std_init", 1.5), ("log_std_init", -5.5),
                                          ("tests_per_episode", 0),
                                          ("tests_per_episode", 17),
                                          ("tests_per_episode", 2.0)])
def test_bad_settings_are_rejected_before_any_process_starts(tmp_path, field, value):
    with pytest.raises(ValueError, match=field):
        train(TrainSettings(**{field: value}), tmp_path / "out")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("field, value", [("log_std_init", -5.0), ("log_std_init", 1.0),
                                          ("max_minutes", 0.0), ("material_weight", 0.0),
                                          ("tests_per_episode", MAX_TESTS_PER_EPISODE)])
def test_settings_at_the_edge_of_what_they_accept_are_taken(field, value):
    TrainSettings(**{field: value}).check()


def test_the_nominal_test_is_the_unit_freshly_wrapped_on_its_long_side_and_known_exactly():
    """Training's two tests as the envs are given them: "verified" is what `recommend --method
    ppo` verifies a proposal on (a random side, a sample, the wrap relaxed by transport)."""
    nominal = env_kwargs(replace(TINY, test="nominal"))
    assert (nominal["orientation"], nominal["hours_since_wrapping"], nominal["uncertain"]) == (
        None, 0.0, False)
    verified = env_kwargs(TINY)
    assert (verified["orientation"], verified["hours_since_wrapping"], verified["uncertain"]) == (
        "random", TRANSPORT_HOURS, True)


def test_training_runs_whole_rollouts():
    """SB3 collects a rollout (n_steps per env) whole before it checks the total: 1 timestep
    asked with 2 envs of 64 steps trains 128, and says so (`wrapbench train`)."""
    assert TrainSettings(timesteps=1, n_envs=2, n_steps=64).rollout_timesteps == 128
    assert TrainSettings(timesteps=128, n_envs=2, n_steps=64).rollout_timesteps == 128
    assert TrainSettings(timesteps=129, n_envs=2, n_steps=64).rollout_timesteps == 256
    assert TINY.rollout_timesteps == TINY.timesteps


@pytest.mark.parametrize("log_std_init", [0.0, -1.0])
def test_a_new_policy_explores_with_the_noise_asked(log_std_init):
    """Every action dimension starts with standard deviation exp(log_std_init) in [-1, 1]: at
    SB3's 0 about a third of the samples clip at a bound, at -1 (0.37) under 1 %."""
    env = make_vec_env(MAKE_ID, n_envs=1, env_kwargs=env_kwargs(TINY))
    try:
        model = new_model(replace(TINY, log_std_init=log_std_init), env)
        std = model.policy.log_std.exp().detach().numpy()
    finally:
        env.close()
    assert std.shape == (len(NAMES),)
    assert std == pytest.approx(math.exp(log_std_init))


def _trained_by_cli(tmp_path: Path, monkeypatch, flags: tuple[str, ...]) -> TrainSettings:
    """The settings `wrapbench train --timesteps 1 FLAGS` hands to training (not run)."""
    trained: list[TrainSettings] = []

    def train(settings: TrainSettings, folder: Path, resume: bool = False) -> Path:
        trained.append(settings)
        return folder / "policy.zip"

    monkeypatch.setattr(recommender.policy, "train", train)
    assert main(["train", "--out", str(tmp_path / "run"), "--timesteps", "1", *flags]) == 0
    (settings,) = trained
    return settings


def test_wrapbench_train_warns_of_a_calibration_accepted_under_a_looser_bound(
        tmp_path, monkeypatch, capsys):
    """As `simulate` and `recommend` do; training then goes on with it, and says where it
    wrote the policy and its log."""
    cal = tmp_path / "cal.json"
    cal.write_text(json.dumps(LOOSE_CALIBRATION))
    settings = _trained_by_cli(tmp_path, monkeypatch, ("--calibration", str(cal)))
    assert settings.calibration is not None
    out, err = capsys.readouterr()
    assert err.splitlines() == [f"wrapbench train: {LOOSE_WARNING}"]
    run = tmp_path / "run"
    assert out.splitlines()[-1] == (f"policy written to {run / 'policy.zip'} "
                                    f"(log: {run / 'log.csv'})")


@pytest.mark.parametrize("flags, log_std_init", [((), 0.0), (("--log-std-init", "-1"), -1.0)])
def test_wrapbench_train_explores_with_the_noise_asked(tmp_path, monkeypatch, flags,
                                                       log_std_init):
    assert _trained_by_cli(tmp_path, monkeypatch, flags).log_std_init == log_std_init


def test_wrapbench_train_says_when_whole_rollouts_train_more_than_asked(tmp_path, monkeypatch,
                                                                        capsys):
    """PPO collects n_steps x n_envs episodes before it counts (test_training_runs_whole_rollouts):
    one timestep asked trains a whole rollout, and the user is told so; a whole rollout asked is
    trained as asked, without a word."""
    settings = _trained_by_cli(tmp_path, monkeypatch, ())
    rollout = settings.n_steps * settings.n_envs
    assert settings.rollout_timesteps == rollout > 1
    assert (f"training {rollout} timesteps: PPO collects whole rollouts of {rollout} episodes"
            in capsys.readouterr().out)
    whole = _trained_by_cli(tmp_path / "whole", monkeypatch, ("--timesteps", str(rollout)))
    assert whole.timesteps == whole.rollout_timesteps == rollout
    assert "PPO collects whole rollouts" not in capsys.readouterr().out


def test_wrapbench_train_takes_as_many_envs_as_it_allows_and_half_a_minute(tmp_path,
                                                                          monkeypatch):
    most = most_workers()
    settings = _trained_by_cli(tmp_path, monkeypatch, ("--envs", str(most), "--minutes", "0.5"))
    assert (settings.workers, settings.max_minutes) == (most, 0.5)


def _weights(policy: Path) -> bytes:
    with zipfile.ZipFile(policy) as archive:
        return archive.read("policy.pth")


def test_train_writes_the_policy_checkpoints_and_one_log_row_per_episode(trained):
    path, out = trained
    assert path == out / "policy.zip" and path.is_file()
    # saved between updates (after the first rollout's), and the final policy as the last
    checkpoints = sorted(p.name for p in (out / CHECKPOINT_DIR).iterdir())
    assert checkpoints == ["policy_4_steps.zip", "policy_8_steps.zip"]
    assert _weights(out / CHECKPOINT_DIR / "policy_8_steps.zip") == _weights(path)
    assert not list(out.glob(".*partial*")) and not list(out.glob("*/.*partial*"))
    with (out / "log.csv").open() as f:
        rows = list(csv.reader(f))
    assert tuple(rows[0]) == LOG_COLUMNS
    assert [int(r[0]) for r in rows[1:]] == list(range(1, TINY.timesteps + 1))
    for _, reward, passed, margin, material_kg, valid in rows[1:]:
        assert passed in ("0", "1") and valid in ("0", "1")
        assert np.isfinite([float(reward), float(margin)]).all()
        assert 0 < float(material_kg) < 5
        if valid == "0":
            assert passed == "0"  # a blown-up run is logged as a failure


class _Counted:
    """All the callbacks below read of the model: its count of timesteps."""

    def __init__(self, num_timesteps: int) -> None:
        self.num_timesteps = num_timesteps


def _episode(passed: bool, valid: bool) -> dict:
    return {"passed": passed, "valid": valid, "margin": -1.5 if not valid else 0.25,
            "material_used": {"mass_kg": 0.4}}


def test_the_log_writes_each_finished_episode_with_its_own_count_and_a_blown_up_one_as_invalid(
        tmp_path):
    """One vector step of three envs, counted 10 timesteps after it: the episodes are timesteps
    8-10 in env order; a step that ends no episode (or carries no verdict) writes nothing; a
    blown-up run is logged valid 0, a failure."""
    log = EpisodeLog(tmp_path / "log.csv")
    log.init_callback(_Counted(10))
    log.on_training_start({}, {})
    log.update_locals({"infos": [_episode(True, True), {}, _episode(False, False)],
                       "dones": np.array([True, True, True]),
                       "rewards": np.array([1.25, 0.0, -2.0])})
    log.on_step()
    log.update_locals({"infos": [_episode(True, True)], "dones": np.array([False]),
                       "rewards": np.array([0.5])})
    log.on_step()
    log.close()
    rows = list(csv.reader((tmp_path / "log.csv").read_text().splitlines()))
    assert rows == [list(LOG_COLUMNS), ["8", "1.25", "1", "0.25", "0.4", "1"],
                    ["10", "-2", "0", "-1.5", "0.4", "0"]]


def test_a_training_run_leaves_nothing_of_its_own_in_the_temp_folder(tmp_path, monkeypatch):
    """Many runs (tests, trials of settings) must not fill /tmp with SB3's empty log folders,
    one per run. (torch keeps one cache folder there, shared by every run.)"""
    temp = tmp_path / "temp"
    temp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(temp))
    short = replace(TINY, timesteps=4, checkpoint_every=4)
    train(short, tmp_path / "first")
    after_one = sorted(temp.iterdir())
    train(short, tmp_path / "second")
    assert sorted(temp.iterdir()) == after_one
    assert not [p for p in after_one if p.name.startswith("SB3-")]


def test_a_training_that_fails_to_start_closes_its_envs_and_gives_torch_its_threads_back(
        tmp_path, monkeypatch):
    """A log that cannot be opened (a full disk) after the env workers started: they are
    closed, and torch's thread count, lowered to one for training, is the caller's again."""
    torch = pytest.importorskip("torch")
    closed = []
    close = PooledVecEnv.close
    monkeypatch.setattr(PooledVecEnv, "close", lambda self: (closed.append(self), close(self)))

    def full_disk(*args, **kwargs):
        raise OSError("No space left on device")

    monkeypatch.setattr(recommender.policy, "EpisodeLog", full_disk)
    threads = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        with pytest.raises(OSError):
            train(TINY, tmp_path)
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(threads)
    assert len(closed) == 1


@pytest.mark.filterwarnings("ignore:rich is experimental")  # tqdm's, SB3's bar silences it
def test_an_interrupted_training_closes_its_progress_bar(tmp_path, monkeypatch):
    """Left open to the interpreter's exit, the bar's refresh thread could be stopped holding
    its lock, and the exit waited for it for ever (a SIGTERM'd `wrapbench train`)."""
    closed = []
    close = recommender.policy.close_bar
    monkeypatch.setattr(recommender.policy, "close_bar",
                        lambda bar: (close(bar), closed.append(bar.pbar.disable)))
    monkeypatch.setattr(EpisodeLog, "_on_step", lambda self: _raise(KeyboardInterrupt()))
    with pytest.raises(KeyboardInterrupt):
        train(replace(TINY, progress_bar=True), tmp_path)
    assert closed == [True]


def _raise(exc: BaseException) -> bool:
    raise exc


def test_a_time_budget_ends_training_early_and_still_writes_the_policy(tmp_path):
    """A budget that has passed by the first step still lets PPO learn from the rollout it
    ends in, then stops it at the next one's first step (SB3 ends `learn` when a callback
    returns False); the policy learned so far is written as a finished run's."""
    settings = TrainSettings(timesteps=64, n_envs=1, n_steps=8, batch_size=8,
                             checkpoint_every=64, progress_bar=False, max_minutes=0.0)
    path = train(settings, tmp_path)
    assert path.is_file()
    assert load_policy(path)._n_updates > 0   # learned from its one rollout: not untrained
    with (tmp_path / "log.csv").open() as f:
        assert [int(r["timesteps"]) for r in csv.DictReader(f)] == list(range(1, 10))
    # the ninth episode was logged, not learned from: the policy counts the eight it learned
    assert last_checkpoint(tmp_path) == (tmp_path / CHECKPOINT_DIR / "policy_8_steps.zip", 8)
    with zipfile.ZipFile(path) as archive:
        assert json.loads(archive.read("data"))["num_timesteps"] == 8


@pytest.mark.parametrize("start, saved", [(0, [8, 16]), (8, [16]), (6, [14])])
def test_a_checkpoint_is_saved_once_its_timesteps_have_passed_since_the_last(
        monkeypatch, tmp_path, start, saved):
    """Every 8 timesteps, rollouts of 4, checked at each rollout's start: a run from 0 saves at
    8 and 16; one resumed from a checkpoint at 8 saves next at 16, one from 6 at 14: counted
    from the checkpoint."""
    written: list[int] = []
    monkeypatch.setattr(recommender.policy, "save_stamped",
                        lambda model, path, meta: written.append(model.num_timesteps))
    model = _Counted(start)
    checkpoints = Checkpoints({}, 8, tmp_path)
    checkpoints.init_callback(model)
    checkpoints.on_training_start({}, {})
    for steps in range(start + 4, 17, 4):
        model.num_timesteps = steps
        checkpoints.on_rollout_start()
    assert written == saved


def test_a_time_budget_is_spent_at_the_end_of_the_rollout_in_which_its_minutes_pass(
        monkeypatch):
    """A minute's budget: a rollout ending at 59 s trains on; the one ending at 60 s is learned
    from (its timesteps recorded) and the next one's first step stops training."""
    now = [1000.0]
    monkeypatch.setattr(recommender.policy.time, "monotonic", lambda: now[0])
    model = _Counted(128)
    budget = TimeBudget(minutes=1.0)
    budget.init_callback(model)
    budget.on_training_start({}, {})
    now[0] += 59.0
    budget.on_rollout_end()
    assert budget.on_step() and budget.learned is None
    now[0] += 1.0
    model.num_timesteps = 256
    budget.on_rollout_end()
    assert not budget.on_step() and budget.learned == 256


def test_a_policy_trained_on_a_calibration_observes_its_uncertainty_and_says_so(tmp_path,
                                                                               monkeypatch):
    """Its random units spread about the calibrated friction and show its standard deviations
    (observation features 19-24), which a policy trained without one only ever saw as 0."""
    cal = Calibration.from_dict({"friction": {"pallet_bundle": {
        "static": 0.3, "kinetic": 0.25, "static_std": 0.04, "kinetic_std": 0.03}}})
    settings = TrainSettings(timesteps=2, n_envs=1, n_steps=2, batch_size=2, checkpoint_every=2,
                             progress_bar=False, calibration=cal)
    made = recommender.policy.make_vec_env
    env_kwargs = []
    monkeypatch.setattr(recommender.policy, "make_vec_env",
                        lambda *a, **k: env_kwargs.append(k["env_kwargs"]) or made(*a, **k))
    path = train(settings, tmp_path)
    assert [k["calibration"] for k in env_kwargs] == [cal]   # what the training envs are given
    with zipfile.ZipFile(path) as archive:
        assert json.loads(archive.read(POLICY_META))["calibrated"] is True
    assert policy_meta(TrainSettings())["calibrated"] is False
    env = WrapBenchRandomEnv(levels="target", calibration=cal)
    obs, _ = env.reset(seed=0)
    env.close()
    assert obs[OBS_NAMES.index("friction_pallet_bundle_static_std")] > 0


def test_a_policy_trained_on_the_verified_test_is_judged_as_recommend_verifies(tmp_path,
                                                                               monkeypatch):
    """Each episode (by default): a side drawn at random, one sample of what the bench does
    not know, the wrap relaxed as on the road (16 h); the policy file says so."""
    settings = TrainSettings(timesteps=2, n_envs=1, n_steps=2, batch_size=2, checkpoint_every=2,
                             progress_bar=False)
    made = recommender.policy.make_vec_env
    env_kwargs = []
    monkeypatch.setattr(recommender.policy, "make_vec_env",
                        lambda *a, **k: env_kwargs.append(k["env_kwargs"]) or made(*a, **k))
    path = train(settings, tmp_path)
    (kwargs,) = env_kwargs
    assert (kwargs["orientation"], kwargs["hours_since_wrapping"], kwargs["uncertain"]) == (
        "random", 16.0, True)
    with zipfile.ZipFile(path) as archive:
        assert json.loads(archive.read(POLICY_META))["test"] == "verified"
    assert policy_meta(TrainSettings(test="nominal"))["test"] == "nominal"
    with (tmp_path / "log.csv").open() as f:
        assert len(list(csv.DictReader(f))) == 2


@pytest.mark.parametrize("flags, test", [((), "verified"), (("--test", "nominal"), "nominal")])
def test_wrapbench_train_judges_episodes_by_the_test_asked(tmp_path, monkeypatch, flags, test):
    assert _trained_by_cli(tmp_path, monkeypatch, flags).test == test


@pytest.mark.parametrize("flags, weight", [((), TrainSettings().material_weight),
                                           (("--material-weight", "1"), 1.0),
                                           (("--material-weight", "0.3"), 0.3),
                                           (("--material-weight", "0"), 0.0)])
def test_wrapbench_train_prices_web_as_asked_and_the_policy_records_it(tmp_path, monkeypatch,
                                                                       flags, weight):
    """The weight reaches every training env's reward and the policy's record, so a run is
    resumed only at the weight it was started with; without the flag, training's default."""
    settings = _trained_by_cli(tmp_path, monkeypatch, flags)
    assert env_kwargs(settings)["material_weight"] == weight
    assert policy_meta(settings)["material_weight"] == weight


@pytest.mark.parametrize("flags, tests", [((), 1), (("--tests-per-episode", "4"), 4)])
def test_wrapbench_train_judges_each_episode_by_its_worst_test_as_asked(tmp_path, monkeypatch,
                                                                         flags, tests):
    """K tests reach every training env and the policy's record (a run resumes only with the
    K it was started with); K = 1, one sample an episode, unless asked."""
    settings = _trained_by_cli(tmp_path, monkeypatch, flags)
    assert env_kwargs(settings)["tests_per_episode"] == tests
    assert policy_meta(settings)["tests_per_episode"] == tests


def test_several_tests_an_episode_need_a_test_that_draws(tmp_path, capsys):
    """The nominal test draws no side or sample: its K tests would be one run K times."""
    with pytest.raises(ValueError, match="tests_per_episode"):
        TrainSettings(test="nominal", tests_per_episode=2).check()
    run = tmp_path / "run"
    assert main(["train", "--out", str(run), "--test", "nominal", "--tests-per-episode",
                 "2"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "--tests-per-episode" in err and not run.exists()


def test_train_with_two_worker_processes(tmp_path):
    """The default: the episodes simulated by worker processes, logged in the envs' order."""
    settings = TrainSettings(timesteps=4, n_envs=2, workers=2, n_steps=1, batch_size=2,
                             checkpoint_every=2, seed=7, progress_bar=False)
    path = train(settings, tmp_path)
    assert path.is_file()
    # two rollouts of a vector step: the checkpoint between their updates, then the final
    # policy (policy.zip, kept as the last checkpoint too)
    assert sorted(p.name for p in (tmp_path / CHECKPOINT_DIR).iterdir()) == [
        "policy_2_steps.zip", "policy_4_steps.zip"]
    with (tmp_path / "log.csv").open() as f:
        assert [int(r["timesteps"]) for r in csv.DictReader(f)] == [1, 2, 3, 4]


def test_propose_returns_a_program_for_the_unit(trained):
    path, _ = trained
    load = held_out_loads(1, seed=3)[0]
    wrap = propose(path, load, "kraft", 0.5)  # no simulation: the caller verifies
    assert isinstance(wrap, WrapFormat) and wrap.material_key == "kraft"
    program = wrap.program
    assert program is not None
    assert 1 <= program.bottom_wraps <= MAX_WRAPS and 1 <= program.top_wraps <= MAX_WRAPS
    assert all(r.wraps <= MAX_REINFORCEMENT_WRAPS for r in program.reinforcements)
    assert max(b.to_m for b in wrap.bands) <= load.layout().load_height_m + 1e-9
    # deterministic, and the same with the policy already loaded
    assert propose(path, load, "kraft", 0.5) == wrap
    assert propose(load_policy(path), load, "kraft", 0.5) == wrap


def test_every_policy_file_says_what_it_was_trained_on(trained):
    path, out = trained
    for file in [path, *sorted((out / CHECKPOINT_DIR).iterdir())]:
        with zipfile.ZipFile(file) as archive:
            meta = json.loads(archive.read(POLICY_META))
        assert meta["material"] == "kraft" and meta["env_id"] == "wrapenv/WrapBenchRandom-v3"
        assert len(meta["observation"]) == 31 and len(meta["action"]) == N_PARAMS


def test_a_policy_is_refused_for_another_material(trained, assert_input_error):
    path, _ = trained
    with pytest.raises(InputError) as info:
        propose(path, held_out_loads(1, seed=3)[0], "lldpe", 0.5)
    assert_input_error(info.value, str(path), "material")


def _rewritten(path: Path, out: Path, meta: object = None, data: dict | None = None) -> Path:
    """A copy of a policy zip with its metadata (any JSON) or SB3 data replaced."""
    with zipfile.ZipFile(path) as src, zipfile.ZipFile(out, "w") as dst:
        for item in src.namelist():
            content = src.read(item)
            if item == POLICY_META and meta is not None:
                content = json.dumps(meta).encode()
            if item == "data" and data is not None:
                content = json.dumps(data).encode()
            dst.writestr(item, content)
    return out


def _without_meta(path: Path, out: Path) -> Path:
    """A copy of a policy zip without wrapbench's record: SB3's own file, say."""
    with zipfile.ZipFile(path) as src, zipfile.ZipFile(out, "w") as dst:
        for item in src.namelist():
            if item != POLICY_META:
                dst.writestr(item, src.read(item))
    return out


def _not_a_zip(path: Path, out: Path) -> Path:
    out.write_bytes(b"PK not a zip at all")
    return out


@pytest.mark.parametrize("make", [
    _not_a_zip,
    lambda path, out: _rewritten(path, out, meta=[1, 2]),
    _without_meta,
], ids=["not a zip", "its record a list", "no record"])
def test_a_file_that_is_no_policy_of_wrapbench_is_refused_in_one_line(make, trained, tmp_path,
                                                                     assert_input_error):
    path, _ = trained
    other = make(path, tmp_path / "other.zip")
    with pytest.raises(InputError, match="not a policy written by `wrapbench train`") as info:
        load_policy(other)
    assert_input_error(info.value, str(other), "policy")


def test_a_policy_of_another_observation_is_refused_in_one_line(trained, tmp_path,
                                                               assert_input_error):
    path, _ = trained
    with zipfile.ZipFile(path) as archive:
        meta = json.loads(archive.read(POLICY_META))
    old = _rewritten(path, tmp_path / "old.zip", meta={**meta, "observation": meta[
        "observation"][:27]})
    with pytest.raises(InputError) as info:
        load_policy(old)
    assert_input_error(info.value, str(old), "observation")


def test_a_policy_of_an_earlier_env_version_is_refused_in_one_line(trained, tmp_path,
                                                                  assert_input_error):
    """v2's actions had the same names and meant other programs (bottom wraps from the sled
    surface)."""
    path, _ = trained
    with zipfile.ZipFile(path) as archive:
        meta = json.loads(archive.read(POLICY_META))
    v2 = _rewritten(path, tmp_path / "v2.zip", meta={**meta,
                                                     "env_id": "wrapenv/WrapBenchRandom-v2"})
    with pytest.raises(InputError) as info:
        load_policy(v2)
    assert_input_error(info.value, str(v2), "env_id")


def test_a_policy_trained_on_a_card_whose_figures_have_since_changed_is_refused(
        trained, tmp_path, assert_input_error):
    """The card's figures are part of what a policy observes (the LLDPE card's grammage
    changed on 2026-11-27); a policy records them, and one without the record is taken."""
    path, _ = trained
    with zipfile.ZipFile(path) as archive:
        meta = json.loads(archive.read(POLICY_META))
    assert meta["material_features"][0] == pytest.approx(0.090 / 0.1)  # kraft's 90 g/m²
    other = list(meta["material_features"])
    other[0] = 0.098
    changed = _rewritten(path, tmp_path / "changed.zip", meta={**meta,
                                                              "material_features": other})
    with pytest.raises(InputError) as info:
        load_policy(changed)
    assert_input_error(info.value, str(changed), "material_features")
    unrecorded = {k: v for k, v in meta.items() if k != "material_features"}
    load_policy(_rewritten(path, tmp_path / "unrecorded.zip", meta=unrecorded))


def test_recommend_refuses_such_a_policy_before_warning_about_its_proposal(trained, tmp_path,
                                                                         capsys):
    """One line, the refusal: not first a warning that the unit lies outside what it learned
    (the half pallet would be)."""
    path, _ = trained
    with zipfile.ZipFile(path) as archive:
        meta = json.loads(archive.read(POLICY_META))
    v2 = _rewritten(path, tmp_path / "v2.zip", meta={**meta,
                                                     "env_id": "wrapenv/WrapBenchRandom-v2"})
    assert main(["recommend", "examples/pet_3layer_half_pallet.toml", "--method", "ppo",
                 "--policy", str(v2)]) == 2
    assert "env_id" in one_line(capsys.readouterr().err)


def test_a_policy_file_is_read_once_and_loaded_from_the_bytes_that_were_checked(
        trained, monkeypatch):
    """Checked from one read and loaded from another, a file replaced in between would be
    loaded unchecked."""
    path, _ = trained
    reads: list[Path] = []
    read = recommender.policy._read
    monkeypatch.setattr(recommender.policy, "_read", lambda p: reads.append(p) or read(p))
    given: list[object] = []
    load = recommender.policy.PPO.load
    monkeypatch.setattr(recommender.policy.PPO, "load",
                        lambda source, **kw: given.append(source) or load(source, **kw))
    load_policy(path)
    assert reads == [path] and len(given) == 1 and isinstance(given[0], io.BytesIO)
    assert given[0].getvalue() == path.read_bytes()


def test_a_policy_is_loaded_without_unpickling_what_the_file_holds(trained, tmp_path):
    path, _ = trained
    with zipfile.ZipFile(path) as archive:
        data = json.loads(archive.read("data"))
    # a pickled entry the loader does not know: refused, never unpickled
    data["exploit"] = {":type:": "<class 'x'>", ":serialized:": "gASVAAAAAAAAAAB9lC4="}
    evil = _rewritten(path, tmp_path / "evil.zip", data=data)
    with pytest.raises(InputError, match="exploit"):
        load_policy(evil)
    not_a_zip = tmp_path / "bad.zip"
    not_a_zip.write_bytes(b"PK not really")
    with pytest.raises(InputError, match="not a policy"):
        load_policy(not_a_zip)


@pytest.mark.parametrize("entry, value, field", [
    ("n_steps", "abc", "data.n_steps"),
    ("n_steps", 10**15, "data.n_steps"),        # a buffer of 10^15 steps: refused, not allocated
    ("n_envs", 0, "data.n_envs"),
    ("policy_kwargs", "x", "policy"),
])
def test_a_malformed_policy_is_refused_in_one_line(trained, tmp_path, assert_input_error,
                                                   entry, value, field):
    path, _ = trained
    with zipfile.ZipFile(path) as archive:
        data = json.loads(archive.read("data"))
    bad = _rewritten(path, tmp_path / "bad.zip", data={**data, entry: value})
    with pytest.raises(InputError) as info:
        load_policy(bad)
    assert_input_error(info.value, str(bad), field)


def test_a_policy_file_may_ask_for_a_rollout_buffer_of_at_most_max_rollout_steps(trained,
                                                                                 tmp_path):
    """n_steps x n_envs is what SB3 allocates on loading: at the bound the file is read, one
    step past it (in a product of two) refused before anything is allocated."""
    path, _ = trained
    with zipfile.ZipFile(path) as archive:
        data = json.loads(archive.read("data"))
    at_bound = _rewritten(path, tmp_path / "at.zip",
                          data={**data, "n_steps": MAX_ROLLOUT_STEPS, "n_envs": 1})
    assert read_meta(at_bound)["material"] == "kraft"
    past = _rewritten(path, tmp_path / "past.zip",
                      data={**data, "n_steps": MAX_ROLLOUT_STEPS // 2 + 1, "n_envs": 2})
    with pytest.raises(InputError, match="data.n_steps"):
        read_meta(past)


def test_a_policy_with_weights_that_are_not_numbers_is_refused(trained, tmp_path,
                                                               assert_input_error):
    import torch

    path, _ = trained
    model = load_policy(path)
    with torch.no_grad():
        next(model.policy.parameters()).fill_(float("nan"))
    model.save(tmp_path / "nan")
    with zipfile.ZipFile(path) as archive:
        stamp(tmp_path / "nan.zip", json.loads(archive.read(POLICY_META)))
    with pytest.raises(InputError) as info:
        load_policy(tmp_path / "nan.zip")
    assert_input_error(info.value, str(tmp_path / "nan.zip"), "policy")


def test_held_out_loads_are_reproducible_random_units_unseen_in_training():
    loads = held_out_loads(4, seed=0)
    assert loads == held_out_loads(4, seed=0)
    assert loads != held_out_loads(4, seed=1)
    assert all(isinstance(u, LoadUnit) and u.name.startswith("random:") for u in loads)
    assert len({u.name for u in loads}) == 4
    # a training env seeded with 0 (make_vec_env's env 0 of seed 0) draws other units
    env = WrapBenchRandomEnv(levels="target")
    trained_on = [env.reset(seed=0)[1]["load"]] + [env.reset()[1]["load"] for _ in range(3)]
    env.close()
    assert not {u.name for u in loads} & set(trained_on)


def test_pass_rate_is_the_share_of_trials_passed_an_invalid_one_failing(monkeypatch):
    trials = [SimpleNamespace(passed=True, valid=True), SimpleNamespace(passed=False, valid=True),
              SimpleNamespace(passed=False, valid=False)]
    monkeypatch.setattr(recommender.policy, "evaluate", lambda *args: trials)
    assert pass_rate(None, [], "kraft", 0.3, seed=0) == pytest.approx(1 / 3)
    monkeypatch.setattr(recommender.policy, "evaluate", lambda *args: [])
    assert math.isnan(pass_rate(None, [], "kraft", 0.3, seed=0))


def test_pass_rate_counts_passes_of_random_or_policy_actions(trained):
    loads = [LoadUnit.from_dict(TINY_LOAD), LoadUnit.from_dict({**TINY_LOAD, "name": "heavy",
                                                                "bundle": HEAVY_BUNDLE})]
    trials = evaluate(None, loads, "kraft", 0.3, seed=1)
    assert [t.load for t in trials] == ["tiny", "heavy"]
    assert all(t.valid and 0 < t.material_kg < 5 for t in trials)
    # the random actions are one uniform draw per unit from default_rng(seed), in order
    rng = np.random.default_rng(1)
    space = ProgramSpace.for_layout(loads[0].layout(), "kraft")
    assert trials[0].wrap == space.decode(rng.uniform(-1, 1, N_PARAMS))
    assert pass_rate(None, loads, "kraft", 0.3, seed=1) == sum(t.passed for t in trials) / 2
    path, _ = trained
    mine = evaluate(path, loads, "kraft", 0.3, seed=1)
    assert [t.wrap for t in mine] == [propose(path, u, "kraft", 0.3) for u in loads]
    assert pass_rate(path, loads, "kraft", 0.3, seed=99) == sum(t.passed for t in mine) / 2


def test_a_trial_tests_the_action_chosen_from_the_units_observation():
    load = LoadUnit.from_dict(TINY_LOAD)
    seen = []
    least_web = np.array([-1, -1, -1, -1, 0, 0, 0, 0, 1.5], np.float32)

    def choose(obs: np.ndarray) -> np.ndarray:
        seen.append(obs)
        return least_web

    trial = run_trial(load, choose, "kraft", 0.3)
    assert len(seen) == 1 and seen[0].shape == (len(OBS_NAMES),)
    space = ProgramSpace.for_layout(load.layout(), "kraft")
    assert trial.wrap == space.decode(least_web)
    assert trial.wrap.program is not None and trial.wrap.program.bottom_wraps == 1
    assert trial.load == "tiny" and trial.valid and trial.material_kg > 0
    assert trial.action == (-1, -1, -1, -1, 0, 0, 0, 0, 1)   # as the env clips it


#: The slow test's run: 384 timesteps = 6 PPO updates of 64 episodes (32 per env, 2 envs), at
#: a higher learning rate than the default so that a run short enough for a test (~11 min) moves
#: the policy. (Defaults, lr 3e-4 and 128 episodes per update: -13 % material after 512 timesteps,
#: -29 % after 1024, which take 28 min.)
SHORT_RUN = TrainSettings(timesteps=384, n_envs=2, n_steps=32, batch_size=32,
                          learning_rate=1e-3, checkpoint_every=128, progress_bar=False)
HELD_OUT = 12
MATERIAL_SAVING = 0.25  # at least this fraction less material than random actions
#: Issue 15's bar for a trained policy: at least this share of held-out units pass.
POLICY_PASS_RATE = 0.9


@pytest.mark.slow
def test_short_training_beats_random_actions_on_held_out_units(tmp_path):
    """Kraft at 0.5 g: random actions already pass every held-out unit (a few layers of paper
    hold these units against the stopper, at 4 x the web the search answers), so "better" is
    what PPO is trained on, a higher mean reward, with at least 25 % less material, and the
    issue's 90 % of the units passing.

    Measured (2026-11-27, commit 57cb490, environments -v3, a quiet machine; training 142 s):
    pass rate policy 11/12, random 12/12; mean material policy 0.388 kg, random 1.594 kg; the
    unit that failed (1 layer of 13.9 kg bundles, margin -0.30) is the one the search needs
    0.651 kg for, twice the least web, which the 45-minute policy passes (docs/recommend.md).
    Until that commit the test asked for no lower pass rate than random actions'; on -v3 this
    192-episode run misses that by the one unit, whose programs -v3 did not change (it is too
    low for the bottom wraps to move).

    Measured (2026-11-24, commit 602edac, 2 cores shared with other tests; training 299 s,
    1.29 simulations/s with 2 envs, evaluation 39 s): pass rate policy 12/12, random 12/12;
    mean material policy 0.415 kg, random 1.639 kg (-75 %); no invalid run; the same verdict
    in a second run that day. Marked xfail in commit 9c40d73 (this run then learnt programs too
    light to hold: 7 of 12 passed); the slow suite found it passing at 06a24c3 (not bisected:
    the program space, its first generation and the training envs' settings changed since).
    2026-11-21: -29 %.
    """
    t0 = time.perf_counter()
    policy = train(SHORT_RUN, tmp_path)
    t_train = time.perf_counter() - t0
    loads = held_out_loads(HELD_OUT, seed=0)
    t0 = time.perf_counter()
    mine = evaluate(policy, loads, "kraft", 0.5, seed=0)
    chance = evaluate(None, loads, "kraft", 0.5, seed=0)
    t_eval = time.perf_counter() - t0
    rate = {k: sum(t.passed for t in v) / HELD_OUT for k, v in (("policy", mine),
                                                                ("random", chance))}
    kg = {k: float(np.mean([t.material_kg for t in v])) for k, v in (("policy", mine),
                                                                    ("random", chance))}
    print(f"train {t_train:.0f} s ({SHORT_RUN.timesteps / t_train:.2f} simulations/s), "
          f"evaluation {t_eval:.0f} s; pass rate {rate}; mean material kg {kg}; "
          f"policy kg {[round(t.material_kg, 3) for t in mine]}, "
          f"random kg {[round(t.material_kg, 3) for t in chance]}; "
          f"invalid {sum(not t.valid for t in mine + chance)}")
    reward = {k: float(np.mean([t.reward for t in v])) for k, v in (("policy", mine),
                                                                   ("random", chance))}
    assert reward["policy"] > reward["random"], reward
    assert rate["policy"] >= POLICY_PASS_RATE
    assert kg["policy"] <= (1 - MATERIAL_SAVING) * kg["random"]


def test_an_interrupted_training_names_its_last_checkpoint(tmp_path, monkeypatch, capsys):
    """Ctrl-C during `wrapbench train` writes no policy.zip, but the checkpoints already saved
    are usable: the one line says which is the last, instead of "nothing written"."""
    import recommender.policy

    def interrupted(settings: TrainSettings, out: Path, resume: bool = False) -> Path:
        (out / CHECKPOINT_DIR).mkdir()
        for steps in (512, 1024):
            (out / CHECKPOINT_DIR / f"policy_{steps}_steps.zip").write_bytes(b"")
            time.sleep(0.01)  # distinct modification times
        raise KeyboardInterrupt

    monkeypatch.setattr(recommender.policy, "train", interrupted)
    code = main(["train", "--out", str(tmp_path / "run")])
    err = capsys.readouterr().err.strip()
    assert code == 130 and "\n" not in err
    assert "policy_1024_steps.zip" in err and "no policy.zip" in err and "--resume" in err


def _log_timesteps(out: Path) -> list[int]:
    with (out / "log.csv").open() as f:
        rows = list(csv.reader(f))
    assert tuple(rows[0]) == LOG_COLUMNS
    return [int(r[0]) for r in rows[1:]]


def test_an_interrupted_run_resumes_from_its_last_checkpoint_to_the_whole_run(tmp_path,
                                                                              monkeypatch):
    """Killed in its third rollout of two episodes, a run keeps the checkpoint of the two it
    learned from; resumed, it learns the two it lacks: the log holds each of the 8 episodes
    once (the dropped one played anew), and the policy counts 8 timesteps."""
    settings = replace(TINY, timesteps=8, n_steps=2, batch_size=2, checkpoint_every=2)
    out = tmp_path / "run"
    real = EpisodeLog._on_step

    def killed_at_the_fifth_episode(self: EpisodeLog) -> bool:
        result = real(self)
        if self.num_timesteps >= 5:
            raise KeyboardInterrupt
        return result

    monkeypatch.setattr(EpisodeLog, "_on_step", killed_at_the_fifth_episode)
    with pytest.raises(KeyboardInterrupt):
        train(settings, out)
    monkeypatch.undo()
    assert not (out / "policy.zip").exists() and _log_timesteps(out) == [1, 2, 3, 4, 5]
    assert last_checkpoint(out) == (out / CHECKPOINT_DIR / "policy_4_steps.zip", 4)

    path = train(settings, out, resume=True)
    assert _log_timesteps(out) == list(range(1, 9))
    with zipfile.ZipFile(path) as archive:
        assert json.loads(archive.read("data"))["num_timesteps"] == 8
    assert sorted(p.name for p in (out / CHECKPOINT_DIR).iterdir()) == [
        "policy_2_steps.zip", "policy_4_steps.zip", "policy_6_steps.zip", "policy_8_steps.zip"]
    load_policy(path, "kraft")


def test_a_finished_run_is_trained_on_to_a_larger_total(tmp_path):
    """Resumed with a larger total, a finished run continues from its final policy as if it
    had been started for that total: the log holds each episode once and the policy counts
    them all. (`wrapbench train` refuses a total it has reached:
    `test_resume_needs_a_run_to_continue`.)"""
    out = tmp_path / "run"
    first = replace(TINY, timesteps=4, n_steps=2, batch_size=2, checkpoint_every=2)
    train(first, out)
    before = _weights(out / "policy.zip")
    path = train(replace(first, timesteps=8), out, resume=True)
    assert _log_timesteps(out) == list(range(1, 9))
    with zipfile.ZipFile(path) as archive:
        assert json.loads(archive.read("data"))["num_timesteps"] == 8
    assert _weights(path) != before
    assert last_checkpoint(out) == (out / CHECKPOINT_DIR / "policy_8_steps.zip", 8)


def test_a_run_is_resumed_only_as_it_was_started(trained, tmp_path, assert_input_error):
    _, out = trained
    run = tmp_path / "run"
    (run / CHECKPOINT_DIR).mkdir(parents=True)
    for name in ("log.csv", f"{CHECKPOINT_DIR}/policy_4_steps.zip"):
        (run / name).write_bytes((out / name).read_bytes())
    for settings, field in ((replace(TINY, material="lldpe"), "material"),
                            (replace(TINY, target_g=0.8), "target_g"),
                            (replace(TINY, test="nominal"), "test"),
                            (replace(TINY, material_weight=0.5), "material_weight"),
                            (replace(TINY, tests_per_episode=2), "tests_per_episode")):
        with pytest.raises(InputError) as info:
            train(settings, run, resume=True)
        assert_input_error(info.value, str(run / CHECKPOINT_DIR / "policy_4_steps.zip"), field)


def test_a_checkpoint_from_before_its_test_and_weight_were_recorded_resumes_as_it_was_trained(
        trained, tmp_path):
    """Checkpoints written before the test (2026-11-28), web's price and tests an episode
    (2026-12-01) were recorded were trained on the nominal test, web priced at 1, one test an
    episode: they resume so, and only so."""
    _, out = trained
    run = tmp_path / "run"
    (run / CHECKPOINT_DIR).mkdir(parents=True)
    (run / "log.csv").write_bytes((out / "log.csv").read_bytes())
    checkpoint = out / CHECKPOINT_DIR / "policy_4_steps.zip"
    with zipfile.ZipFile(checkpoint) as archive:
        meta = json.loads(archive.read(POLICY_META))
    old = {k: v for k, v in meta.items()
           if k not in ("test", "material_weight", "tests_per_episode")}
    _rewritten(checkpoint, run / CHECKPOINT_DIR / "policy_4_steps.zip", meta=old)
    then = replace(TINY, test="nominal", material_weight=1.0)
    for settings, field in ((replace(then, test="verified"), "test"),
                            (replace(then, material_weight=0.6), "material_weight")):
        with pytest.raises(InputError, match=field):
            train(settings, run, resume=True)
    path = train(then, run, resume=True)
    assert path == run / "policy.zip"
    with zipfile.ZipFile(path) as archive:
        assert json.loads(archive.read("data"))["num_timesteps"] == TINY.timesteps


@pytest.mark.parametrize("files, needle", [
    ((), "no run to resume"),
    (("log.csv",), "no run to resume"),
    # 128: one rollout of `wrapbench train`'s, which --timesteps 4 rounds up to
    (("log.csv", "policy.zip", f"{CHECKPOINT_DIR}/policy_128_steps.zip"), "above 128"),
])
def test_resume_needs_a_run_to_continue(files, needle, tmp_path, capsys):
    run = tmp_path / "run"
    (run / CHECKPOINT_DIR).mkdir(parents=True)
    for name in files:
        (run / name).write_bytes(b"")
    assert main(["train", "--out", str(run), "--resume", "--timesteps", "4"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "--resume" in err and needle in err


@pytest.mark.parametrize("files", [
    ("log.csv", f"{CHECKPOINT_DIR}/policy_128_steps.zip"),                 # interrupted
    ("log.csv", "policy.zip", f"{CHECKPOINT_DIR}/policy_128_steps.zip"),   # finished
])
def test_resume_goes_on_from_an_interrupted_run_or_a_finished_one_asked_for_more(
        files, tmp_path, monkeypatch):
    """What the refusals above leave: a run with its log and a checkpoint is resumed, finished
    or not, while --timesteps asks for more than its last checkpoint holds."""
    run = tmp_path / "run"
    (run / CHECKPOINT_DIR).mkdir(parents=True)
    for name in files:
        (run / name).write_bytes(b"")
    resumed: list[tuple[Path, bool]] = []

    def train(settings: TrainSettings, folder: Path, resume: bool = False) -> Path:
        resumed.append((folder, resume))
        return folder / "policy.zip"

    monkeypatch.setattr(recommender.policy, "train", train)
    assert main(["train", "--out", str(run), "--resume", "--timesteps", "256"]) == 0
    assert resumed == [(run, True)]


def test_resume_into_a_folder_that_does_not_exist_is_refused_leaving_none(tmp_path, capsys):
    assert main(["train", "--out", str(tmp_path / "never"), "--resume"]) == 2
    assert "no run to resume" in capsys.readouterr().err
    assert not (tmp_path / "never").exists()


def test_a_new_run_into_a_folder_holding_one_names_resume(trained, capsys):
    _, out = trained
    assert main(["train", "--out", str(out)]) == 2
    assert "--resume" in capsys.readouterr().err


def test_a_training_interrupted_before_its_first_checkpoint_leaves_nothing(tmp_path,
                                                                          monkeypatch, capsys):
    """It left its log and an empty checkpoints/: a folder --resume refused (no checkpoint)
    and a new run refused (an earlier run's log), so the user went in a circle (a user,
    2026-11-26). Nothing to resume is kept, and the same command starts again."""
    def interrupted(settings: TrainSettings, out: Path, resume: bool = False) -> Path:
        (out / "checkpoints").mkdir()
        (out / "log.csv").write_text(",".join(LOG_COLUMNS) + "\n")
        raise KeyboardInterrupt

    monkeypatch.setattr(recommender.policy, "train", interrupted)
    for out in (tmp_path / "run", tmp_path):     # a folder the run made, and one it was given
        assert main(["train", "--out", str(out)]) == 130
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and "before the first checkpoint: nothing written" in err
        assert not (tmp_path / "run").exists() and list(tmp_path.iterdir()) == []
    assert tmp_path.is_dir()
