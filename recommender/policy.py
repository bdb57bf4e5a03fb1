"""A PPO policy that proposes a wrapping program for a load unit at once, trained on random units.

The robust search (`recommender.search`) spends hundreds of simulations on one unit; a policy
trained once on `wrapenv/WrapBenchRandom-v3` (a new random unit every one-step episode) answers
for any unit in milliseconds, and the caller then verifies its proposal in simulation. The
episode is a contextual bandit: the observation describes the unit, the action is a program of
`wrapenv.design.ProgramSpace`, the reward is the env's (pass, margin, web laid).

Every policy file (the final one and each checkpoint) carries `POLICY_META` inside its zip: the
env, material, target and the names of the observation's and the action's entries it was
trained on. A policy is refused, in one line, by a bench that observes or acts otherwise or for
another material; and it is loaded without unpickling anything from the file (SB3 keeps its
spaces and schedules pickled: `load_policy` supplies them itself).

`train` writes into one folder: ``policy.zip`` (the final policy), ``checkpoints/`` (the
policy every `TrainSettings.checkpoint_every` timesteps, saved between PPO updates so that each
holds what was learned from every episode it counts: a long run that is stopped still leaves a
usable policy, and `train(..., resume=True)` continues from the last one, which for a finished
run is its final policy) and ``log.csv`` (one
row per episode, flushed as it goes, so progress can be followed and plotted while training
runs).
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import math
import os
import re
import time
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, NoReturn

import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.buffers import RolloutBuffer
from stable_baselines3.common.callbacks import BaseCallback, CallbackList, ProgressBarCallback
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.logger import configure as configure_logger
from stable_baselines3.common.policies import ActorCriticPolicy
from stable_baselines3.common.vec_env import VecEnv

import wrapenv  # noqa: F401  (registers the env ids used by gym.make)
from recommender.episodes import PooledVecEnv
from wrapenv.bench import SimSettings
from wrapenv.calibrated import Calibration
from wrapenv.config import InputError, is_finite_number, is_whole_number, write_atomic
from wrapenv.design import N_PARAMS, NAMES
from wrapenv.envs import WrapBenchEnv, WrapBenchRandomEnv
from wrapenv.envs.observation import OBS_NAMES, material_features
from wrapenv.envs.wrapbench import MAX_TESTS_PER_EPISODE
from wrapenv.load import LoadUnit
from wrapenv.material import MATERIALS
from wrapenv.uncertainty import TRANSPORT_HOURS
from wrapenv.wrap import WrapFormat

ENV_ID = "wrapenv/WrapBenchRandom-v3"
#: The file inside every policy zip that says what the policy was trained on.
POLICY_META = "wrapbench.json"
#: What the envs pass to gym.make: the "module:id" form imports wrapenv (which registers the id)
#: in a SubprocVecEnv worker too (`benchmarks/bench_train.py` compares them), whose fresh
#: interpreter has not imported it when the parent's main module is not ours.
MAKE_ID = f"wrapenv:{ENV_ID}"
POLICY_FILE = "policy.zip"
CHECKPOINT_DIR = "checkpoints"
CHECKPOINT_PREFIX = "policy"  # named policy_<timesteps>_steps.zip, as SB3 names its own
CHECKPOINT_NAME = re.compile(rf"{CHECKPOINT_PREFIX}_(\d+)_steps\.zip")
LOG_FILE = "log.csv"
LOG_COLUMNS = ("timesteps", "reward", "passed", "margin", "material_kg", "valid")
#: Second word of the held-out units' seed: the training envs are seeded with plain integers
#: (seed, seed + 1, ...), whose streams a two-word seed sequence with a non-zero second word
#: never reproduces, so held-out units are never units the policy was trained on.
HELD_OUT_STREAM = 40509
#: The tests an episode's program can be judged by, as the env's keywords. "verified" (the
#: default): the test `recommend --method ppo` verifies a proposal on, one episode at a time: a
#: side drawn at random, one sample of what the bench does not know, the wrap relaxed as it is
#: on the road (the verification asks both sides, every sample and a margin at once; the
#: reward's margin term asks for one). On 60 held-out film units its proposals held the
#: verification on 29, where a policy trained on "nominal" (the nominal unit's long side,
#: freshly wrapped; policies trained before 2026-11-28 record no test and were trained so) held
#: on 2 of 12; Kraft's answers were the same (docs/recommend.md).
TESTS: dict[str, dict[str, Any]] = {
    "nominal": {"orientation": None, "hours_since_wrapping": 0.0, "uncertain": False},
    "verified": {"orientation": "random", "hours_since_wrapping": TRANSPORT_HOURS,
                 "uncertain": True},
}


#: `TrainSettings.log_std_init`'s bounds: a standard deviation of 0.007 to 2.7 (actions in [-1, 1]).
LOG_STD_INIT_RANGE = (-5.0, 1.0)


@dataclass(frozen=True)
class TrainSettings:
    """PPO training run. Each episode is one random unit at the target level, 0.14-1.2 s of CPU
    (1-3 layers; docs/speed.md); throughput of the training envs: benchmarks/bench_train.py."""

    timesteps: int = 2048
    #: Envs of the vector env, each stepped once per vector step: with `n_steps` 1, a rollout
    #: is `n_envs` one-step episodes, which `workers` processes simulate as they come free
    #: (`recommender.episodes.PooledVecEnv`).
    n_envs: int = 128
    workers: int = 2               # processes that simulate the episodes (1: this one)
    material: str = "kraft"
    target_g: float = 0.5
    levels: str = "target"         # env levels mode: "target" is 3-4x faster than "eumos"
    #: The calibration the random units spread about, whose uncertainty the policy observes
    #: (features 19-24, 0 without one): a policy proposes for what it was trained on.
    calibration: Calibration | None = None
    #: The bench's settings in the training envs (why a reward bears them: its docstring). As
    #: it stops once decided, a failure still scores in [-2, -1] below every pass, -2 when
    #: damaged, but a level stopped once its elastic displacement passes the limit scores about
    #: -1 however far it would have gone. Held-out evaluations (`evaluate`) and proposals run
    #: at the defaults.
    sim: SimSettings = SimSettings.training()
    #: The test each episode's program is judged by (a key of `TESTS`).
    test: str = "verified"
    #: The reward's price on web (`WrapBenchEnv`'s `material_weight`): lower asks a proposal
    #: to pass more of the samples it may meet, for more web. 0.6 since 2026-12-01: on film,
    #: 1 proposed too little web to hold its verification and 0.3 one strong program for every
    #: unit; on Kraft 0.6 and 1 train the same policy (docs/recommend.md).
    material_weight: float = 0.6
    #: Log of the exploration noise's initial standard deviation in the action space's [-1, 1]
    #: (SB3's `log_std_init`; 0, SB3's default, is a noise as wide as the space). At 0 a film
    #: policy's means drift past the bounds, where every sample clips alike and no gradient
    #: brings them back: nearly every unit gets 6 bottom wraps at full tension. At -1 its
    #: proposals differ by unit but hold no more often (36 of 60 against 38), so 0 stays the
    #: default (docs/recommend.md, "Exploration noise").
    log_std_init: float = 0.0
    #: Tests of each episode's program (the env's `tests_per_episode`; "verified" only), each
    #: with its own side and sample, the episode judged by the worst as the verification judges
    #: (every sample must hold). Each costs a simulation: K tests, K x the time per episode.
    #: At 4 a film policy trained for an hour learned from 5248 episodes and held its
    #: verification on 34 of 60 held-out units (31 after as many at 1) without yet designing
    #: by unit, so 1 stays the default (docs/recommend.md, "Judged by the worst of four tests").
    tests_per_episode: int = 1
    seed: int = 0
    checkpoint_every: int = 512    # timesteps between policy checkpoints
    n_steps: int = 1               # PPO rollout length per env (one-step episodes)
    batch_size: int = 64
    learning_rate: float = 3e-4
    progress_bar: bool = True
    #: Wall-clock budget in minutes (None: none): training ends after learning from the
    #: rollout that passes it (`TimeBudget`), and the policy learned so far is written like a
    #: finished run's, so "train for an hour" keeps the last hour's learning, not only the last
    #: checkpoint's.
    max_minutes: float | None = None

    @property
    def rollout_timesteps(self) -> int:
        """The timesteps PPO trains for: `timesteps` rounded up to whole rollouts (`n_steps`
        per env), since SB3 collects a rollout whole before it checks the total."""
        rollout = self.n_steps * self.n_envs
        return -(-self.timesteps // rollout) * rollout

    def check(self) -> None:
        """Reject settings SB3 would fail on late (or silently misuse), before any process
        is started: an `InputError` naming the field (`train` names its flag)."""
        for name in ("timesteps", "n_envs", "workers", "checkpoint_every", "n_steps",
                     "batch_size", "tests_per_episode"):
            if not (is_whole_number(value := getattr(self, name)) and value >= 1):
                _refuse(name, f"must be a whole number >= 1 (got {value!r})")
        if not (math.isfinite(self.learning_rate) and self.learning_rate > 0):
            _refuse("learning_rate", f"must be > 0 (got {self.learning_rate!r})")
        if self.test not in TESTS:
            _refuse("test", f"must be one of {', '.join(TESTS)} (got {self.test!r})")
        if not 1 <= self.tests_per_episode <= MAX_TESTS_PER_EPISODE:
            _refuse("tests_per_episode", f"must be from 1 to {MAX_TESTS_PER_EPISODE} "
                                         f"(got {self.tests_per_episode!r})")
        if self.tests_per_episode > 1 and self.test != "verified":
            _refuse("tests_per_episode", "above 1 needs the test 'verified': the nominal test "
                                         "draws no side or sample")
        if self.max_minutes is not None and not (math.isfinite(self.max_minutes)
                                                 and self.max_minutes >= 0):
            _refuse("max_minutes", f"must be >= 0 or None (got {self.max_minutes!r})")
        low, high = LOG_STD_INIT_RANGE
        if not low <= self.log_std_init <= high:   # NaN fails too
            _refuse("log_std_init", f"must be between {low:g} and {high:g} "
                                    f"(got {self.log_std_init!r})")
        if not (math.isfinite(self.material_weight) and self.material_weight >= 0):
            _refuse("material_weight", f"must be >= 0 (got {self.material_weight!r})")


def _refuse(field: str, message: str) -> NoReturn:
    raise InputError("settings", field, message)


class EpisodeLog(BaseCallback):
    """Writes one CSV row per finished episode from the step infos (every step ends an episode
    here), flushing after each vector step so the file is readable while training runs.
    Resuming from `kept` timesteps, the rows of the run so far up to them are kept: those after
    them were episodes the checkpoint did not learn from, which the resumed run plays anew."""

    def __init__(self, path: Path, kept: int | None = None) -> None:
        super().__init__()
        self.path, self.kept = path, kept
        self._file: IO[str] | None = None
        self._writer: Any = None

    def _on_training_start(self) -> None:
        if self.kept is None:
            self._file = self.path.open("w", newline="")
            self._writer = csv.writer(self._file)
            self._writer.writerow(LOG_COLUMNS)
        else:
            self._keep_rows(self.kept)
            self._file = self.path.open("a", newline="")
            self._writer = csv.writer(self._file)
        self._file.flush()

    def _keep_rows(self, timesteps: int) -> None:
        """Rewrite the log with the rows of the first `timesteps` only."""
        with self.path.open(newline="") as f:
            rows = list(csv.reader(f))
        kept = [rows[0]] + [r for r in rows[1:] if r and r[0].isdigit() and int(r[0]) <= timesteps]
        text = io.StringIO()
        csv.writer(text).writerows(kept)
        write_atomic(self.path, text.getvalue().encode())

    def _on_step(self) -> bool:
        infos, dones, rewards = self.locals["infos"], self.locals["dones"], self.locals["rewards"]
        n = len(infos)
        for i, (info, done) in enumerate(zip(infos, dones, strict=True)):
            if not done or "passed" not in info:
                continue
            self._writer.writerow([
                self.num_timesteps - n + i + 1,  # this episode's own count of timesteps
                f"{float(rewards[i]):.6g}",
                int(bool(info["passed"])),
                f"{float(info['margin']):.6g}",
                f"{float(info['material_used']['mass_kg']):.6g}",
                int(bool(info["valid"])),  # a blown-up run: a failure, logged as one
            ])
        assert self._file is not None
        self._file.flush()
        return True

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None

    def _on_training_end(self) -> None:
        self.close()


class TimeBudget(BaseCallback):
    """Ends training once `minutes` have passed since it started, at the end of the rollout
    in which they did: PPO learns from that rollout, then the next one's first vector step
    returns False (SB3 stops when a callback does; no callback runs before a rollout's first
    step can stop it, so that step's episodes are simulated and logged unlearned: at the
    defaults the whole next rollout, 128 episodes, half a minute). Stopped inside a rollout,
    PPO would drop what it had collected of it, and a budget that ended in the first one would
    write the untrained policy."""

    def __init__(self, minutes: float) -> None:
        super().__init__()
        self.seconds = 60.0 * minutes
        self._deadline = math.inf
        self._spent = False
        #: The timesteps of the last rollout PPO learned from, once the budget is spent (None
        #: before): the episodes logged after it were not learned from.
        self.learned: int | None = None

    def _on_training_start(self) -> None:
        self._deadline = time.monotonic() + self.seconds

    def _on_rollout_end(self) -> None:
        self._spent = time.monotonic() >= self._deadline
        if self._spent:
            self.learned = self.model.num_timesteps

    def _on_step(self) -> bool:
        return not self._spent


def train(settings: TrainSettings, out_dir: Path, resume: bool = False) -> Path:
    """Train PPO on wrapenv/WrapBenchRandom-v3 for `settings.timesteps` (or until its
    `max_minutes`); writes out_dir/policy.zip (final), periodic
    out_dir/checkpoints/policy_<steps>_steps.zip (`Checkpoints`), and out_dir/log.csv (one row
    per episode: timesteps, reward, passed, margin, material_kg, valid — via a small callback
    reading infos; written incrementally, flushed). `resume`: continue the interrupted run in
    `out_dir` from its last checkpoint, up to the same total of timesteps (its random units
    drawn anew: the envs are seeded past the ones it started with), or a finished run on to a
    larger total. The final policy is also kept as the last checkpoint, counting only the
    episodes it learned from (not those a time budget logged after its last update), so that
    a finished run can be trained on. Returns the policy path."""
    settings.check()
    out_dir = Path(out_dir)
    checkpoints = out_dir / CHECKPOINT_DIR
    checkpoints.mkdir(parents=True, exist_ok=True)
    start = last_checkpoint(out_dir) if resume else None
    if resume and start is None:
        raise InputError(str(checkpoints), "--resume", "no checkpoint to resume from")
    done = start[1] if start else 0
    meta = policy_meta(settings)
    trusted = _trusted_objects() if start else {}
    # the checkpoint read once: what is checked is what is loaded
    resumed = _read(start[0]) if start else b""
    if start:
        _check_resumable(start[0], resumed, meta, trusted)   # before any env process starts
    # The policy is a small MLP: one thread avoids oversubscribing the cores the env workers
    # simulate on (and thread start-up costs more than it saves on a 64-unit layer).
    with contextlib.ExitStack() as cleanup:  # undone in reverse, also when a step fails
        cleanup.callback(torch.set_num_threads, torch.get_num_threads())
        torch.set_num_threads(1)
        vec_env = _training_envs(settings, seed=settings.seed + done)
        cleanup.callback(vec_env.close)
        log = EpisodeLog(out_dir / LOG_FILE, kept=done if start else None)
        cleanup.callback(log.close)
        # a run checkpointed before 2026-11-28 collected 64 steps of 2 envs a rollout
        model = (_load(start[0], resumed, trusted, vec_env, n_steps=settings.n_steps)
                 if start else
                 new_model(settings, vec_env))
        # SB3's default logger makes an empty folder in the system's temp dir per run, even
        # writing nothing: ours writes nothing either, in the run's folder
        model.set_logger(configure_logger(str(out_dir), []))
        callbacks: list[BaseCallback] = [Checkpoints(meta, settings.checkpoint_every,
                                                     checkpoints), log]
        budget = None if settings.max_minutes is None else TimeBudget(settings.max_minutes)
        if budget is not None:
            callbacks.append(budget)
        if settings.progress_bar:
            bar = ProgressBarCallback()
            callbacks.append(bar)
            cleanup.callback(close_bar, bar)
        model.learn(max(0, settings.rollout_timesteps - done), callback=CallbackList(callbacks),
                    reset_num_timesteps=start is None)
        if budget is not None and budget.learned is not None:
            model.num_timesteps = budget.learned
        final = checkpoints / f"{CHECKPOINT_PREFIX}_{model.num_timesteps}_steps.zip"
        if not final.exists():
            save_stamped(model, final, meta)
        path = out_dir / POLICY_FILE
        save_stamped(model, path, meta)
        return path


def close_bar(bar: ProgressBarCallback) -> None:
    """Close the progress bar, also of an interrupted training (SB3 closes it only when
    training ends). Left to the interpreter's exit, rich's refresh thread, a daemon, can be
    stopped holding the bar's lock, and the exit then waits for that lock for ever: `wrapbench
    train` ended by SIGTERM once hung so (2026-11-28)."""
    pbar = getattr(bar, "pbar", None)   # made when training starts
    if pbar is not None:
        pbar.close()


def new_model(settings: TrainSettings, vec_env: VecEnv) -> PPO:
    """An untrained PPO model as `settings` ask, on the CPU (the policy is a small MLP)."""
    return PPO("MlpPolicy", vec_env, n_steps=settings.n_steps, batch_size=settings.batch_size,
               learning_rate=settings.learning_rate, seed=settings.seed, device="cpu",
               verbose=0, policy_kwargs={"log_std_init": settings.log_std_init})


def env_kwargs(settings: TrainSettings) -> dict[str, Any]:
    """What each training env is made with (`gym.make(MAKE_ID, **env_kwargs(settings))`)."""
    return {"material": settings.material, "target_g": settings.target_g,
            "levels": settings.levels, "settings": settings.sim,
            "calibration": settings.calibration, "material_weight": settings.material_weight,
            "tests_per_episode": settings.tests_per_episode, **TESTS[settings.test]}


def _training_envs(settings: TrainSettings, seed: int) -> VecEnv:
    """`settings.n_envs` random-unit envs, stepped by `settings.workers` processes."""
    return make_vec_env(MAKE_ID, n_envs=settings.n_envs, seed=seed,
                        env_kwargs=env_kwargs(settings), vec_env_cls=PooledVecEnv,
                        vec_env_kwargs={"workers": settings.workers})


def policy_meta(settings: TrainSettings) -> dict[str, Any]:
    """What a policy was trained on, as `POLICY_META` records it."""
    return {"env_id": ENV_ID, "material": settings.material, "target_g": settings.target_g,
            "observation": list(OBS_NAMES), "action": list(NAMES),
            "calibrated": settings.calibration is not None,
            "material_features": material_features(MATERIALS[settings.material]),
            "test": settings.test, "material_weight": settings.material_weight,
            "tests_per_episode": settings.tests_per_episode}


def stamp(path: Path, meta: dict[str, Any]) -> None:
    """Add `POLICY_META` to a policy zip SB3 has written."""
    with zipfile.ZipFile(path, "a") as archive:
        archive.writestr(POLICY_META, json.dumps(meta))


class Checkpoints(BaseCallback):
    """The policy saved once `every` timesteps have passed since the last save, at the start of
    a rollout: after PPO learned from the last one, so a checkpoint holds what was learned from
    every episode it counts (SB3's CheckpointCallback saves within a rollout, before the update
    that learns from it). Each is stamped with what the policy was trained on, and written
    whole or not at all."""

    def __init__(self, meta: dict[str, Any], every: int, folder: Path) -> None:
        super().__init__()
        self.meta, self.every, self.folder = meta, every, folder
        self._saved_at = 0

    def _on_training_start(self) -> None:
        self._saved_at = self.model.num_timesteps

    def _on_rollout_start(self) -> None:
        steps = self.model.num_timesteps
        if steps - self._saved_at >= self.every:
            save_stamped(self.model, self.folder / f"{CHECKPOINT_PREFIX}_{steps}_steps.zip",
                         self.meta)
            self._saved_at = steps

    def _on_step(self) -> bool:
        return True


def save_stamped(model: BaseAlgorithm, path: Path, meta: dict[str, Any]) -> None:
    """Save the policy stamped with `meta`, never half-written."""
    partial = path.with_name(f".{path.name}.partial.zip")
    model.save(partial)
    stamp(partial, meta)
    os.replace(partial, path)


def last_checkpoint(out_dir: Path) -> tuple[Path, int] | None:
    """The checkpoint of the most timesteps in a run's folder, and its timesteps."""
    found = [(int(m.group(1)), p) for p in (Path(out_dir) / CHECKPOINT_DIR).glob("*.zip")
             if (m := CHECKPOINT_NAME.fullmatch(p.name))]
    if not found:
        return None
    steps, path = max(found)
    return path, steps


def _trusted_objects() -> dict[str, Any]:
    """SB3 pickles these entries of a policy zip; `load_policy` supplies them instead, so
    nothing from the file is unpickled (the weights are read by torch's weights_only loader)."""
    env = WrapBenchEnv(levels="target")
    try:
        return {"policy_class": ActorCriticPolicy, "rollout_buffer_class": RolloutBuffer,
                "observation_space": env.observation_space, "action_space": env.action_space,
                "lr_schedule": _constant(0.0), "clip_range": _constant(0.2),
                # training state: not needed to predict, and rebuilt by a resumed run
                **dict.fromkeys(("_last_obs", "_last_original_obs", "_last_episode_starts",
                                 "ep_info_buffer", "ep_success_buffer"))}
    finally:
        env.close()


def _constant(value: float) -> Any:
    return lambda _progress: value


def _read(path: Path) -> bytes:
    """A policy file's bytes, read once: it is checked and loaded from these, so a file
    replaced in between is never loaded unchecked."""
    try:
        return Path(path).read_bytes()
    except OSError as exc:
        raise InputError(str(path), "policy", f"cannot be read ({exc.strerror})") from None


def read_meta(path: Path, content: bytes | None = None) -> dict[str, Any]:
    """The policy's `POLICY_META` (from `content`, the file's bytes, when given), or a
    one-line error for anything else."""
    try:
        with zipfile.ZipFile(io.BytesIO(_read(path) if content is None else content)) as archive:
            meta = json.loads(archive.read(POLICY_META))
            data = json.loads(archive.read("data"))
    except (OSError, zipfile.BadZipFile, KeyError, ValueError) as exc:
        raise InputError(str(path), "policy", f"not a policy written by `wrapbench train` "
                                              f"({exc})") from None
    if not isinstance(meta, dict) or not isinstance(data, dict):
        raise InputError(str(path), "policy", "not a policy written by `wrapbench train`")
    _check_sizes(path, data)
    meta["_pickled"] = sorted(k for k, v in data.items()
                              if isinstance(v, dict) and ":serialized:" in v)
    return meta


#: Most rollout steps a policy file may ask SB3 to allocate a buffer for on loading
#: (n_steps x n_envs; `wrapbench train` writes 1 x 128).
MAX_ROLLOUT_STEPS = 1 << 20


def _check_sizes(path: Path, data: dict[str, Any]) -> None:
    """The sizes SB3 allocates from on loading: whole numbers, and not absurd (a file asking
    for 10^15 rollout steps would exhaust the memory instead of failing)."""
    sizes: dict[str, int] = {}
    for key in ("n_steps", "n_envs", "batch_size"):
        value = data.get(key)
        if not (is_whole_number(value) and value >= 1):
            raise InputError(str(path), f"data.{key}", f"must be a whole number >= 1 (got "
                                                      f"{value!r})")
        sizes[key] = value
    if sizes["n_steps"] * sizes["n_envs"] > MAX_ROLLOUT_STEPS:
        raise InputError(str(path), "data.n_steps", f"n_steps x n_envs must be at most "
                                                    f"{MAX_ROLLOUT_STEPS}")


def load_policy(policy_path: Path, material: str | None = None) -> PPO:
    """The trained policy, on the CPU, if it was trained for this bench (and `material`)."""
    return load_policy_and_meta(policy_path, material)[0]


def load_policy_and_meta(policy_path: Path, material: str | None = None
                         ) -> tuple[PPO, dict[str, Any]]:
    """`load_policy`, and the `POLICY_META` it was checked against, from one read of the file
    (what is checked is what is loaded)."""
    path = Path(policy_path)
    trusted = _trusted_objects()
    content = _read(path)
    meta = read_meta(path, content)
    _check_meta(path, meta, material, trusted)
    return _load(path, content, trusted), meta


def _check_resumable(path: Path, content: bytes, meta: dict[str, Any],
                     trusted: dict[str, Any]) -> None:
    """A run's checkpoint (`content`, its bytes), if it was trained as `meta` says, or a
    one-line error."""
    found = read_meta(path, content)
    _check_meta(path, found, meta["material"], trusted)
    found.setdefault("test", "nominal")   # written before the test was recorded
    found.setdefault("material_weight", 1.0)   # written before the weight was a setting
    found.setdefault("tests_per_episode", 1)   # written before 2026-12-01's worst of K
    for key in ("target_g", "calibrated", "test", "material_weight", "tests_per_episode"):
        if found.get(key) != meta[key]:
            raise InputError(str(path), key, f"the run was trained with {key} "
                             f"{found.get(key)!r}, not {meta[key]!r}: resume it as it was started")


def _check_meta(path: Path, meta: dict[str, Any], material: str | None,
                trusted: dict[str, Any]) -> None:
    """A policy file trained for this bench (and `material`), pickling nothing but the
    `trusted` entries, or a one-line error."""
    if meta.get("observation") != list(OBS_NAMES) or meta.get("action") != list(NAMES):
        raise InputError(str(path), "observation", f"the policy was trained on "
                         f"{meta.get('env_id', 'another env')}, which observes or acts otherwise"
                         f" than {ENV_ID}: train a new one")
    if meta.get("env_id") != ENV_ID:  # the same names, other programs (e.g. v2's bottom wraps)
        raise InputError(str(path), "env_id", f"the policy was trained on {meta.get('env_id')},"
                         f" whose actions are other programs than {ENV_ID}'s: train a new one")
    if material is not None and meta.get("material") != material:
        raise InputError(str(path), "material", f"the policy was trained for "
                         f"{meta.get('material')!r}, not {material!r}")
    _check_card(path, meta)
    unknown = set(meta["_pickled"]) - set(trusted)
    if unknown:
        raise InputError(str(path), "policy", f"holds pickled entries {sorted(unknown)}, which "
                                              "are not loaded")


def _check_card(path: Path, meta: dict[str, Any]) -> None:
    """A policy observed its card's figures (`material_features`); one trained on figures the
    card no longer has would see an input it never saw. Policies written before the figures
    were recorded (2026-11-27) are taken as they are."""
    recorded, name = meta.get("material_features"), meta.get("material")
    if recorded is None or name not in MATERIALS:
        return
    now = material_features(MATERIALS[name])
    if not (isinstance(recorded, list) and len(recorded) == len(now)
            and all(is_finite_number(v) for v in recorded)
            and np.allclose(recorded, now, rtol=1e-9, atol=0.0)):
        raise InputError(str(path), "material_features", f"the policy was trained on the "
                         f"{name} card's figures of another version of wrapbench: train a new one")


def _load(path: Path, content: bytes, trusted: dict[str, Any], env: Any = None,
          **overrides: Any) -> PPO:
    """The policy file's weights (and optimizer state) from its checked bytes, nothing
    unpickled from them; `overrides`: attributes set anew (a resumed run's rollout shape)."""
    try:
        model = PPO.load(io.BytesIO(content), env=env, device="cpu", custom_objects=trusted,
                         **overrides)
    except (OSError, ValueError, KeyError, RuntimeError, TypeError, AttributeError) as exc:
        raise InputError(str(path), "policy", f"cannot be loaded ({exc})") from None
    if not all(bool(p.isfinite().all()) for p in model.policy.parameters()):
        raise InputError(str(path), "policy", "has weights that are not finite numbers")
    return model


def _policy(policy: PPO | Path | str, material: str) -> PPO:
    return policy if isinstance(policy, PPO) else load_policy(Path(policy), material)


def _env(load: LoadUnit, material: str, target_g: float,
         calibration: Calibration | None = None) -> WrapBenchEnv:
    """The one-unit env: it computes the observation and decodes actions exactly as training
    did (levels="target", as the policy was trained)."""
    return WrapBenchEnv(load=load, calibration=calibration, material=material,
                        target_g=target_g, levels="target")


def _action(model: PPO, obs: np.ndarray) -> np.ndarray:
    action, _ = model.predict(obs, deterministic=True)
    return np.asarray(action, np.float32).reshape(N_PARAMS)


def propose(policy_path: Path | PPO, load: LoadUnit, material: str, target_g: float,
            calibration: Calibration | None = None) -> WrapFormat:
    """Deterministic action of the trained policy for this unit's observation, decoded to a
    format (answers instantly; the caller verifies it in simulation). An already loaded `PPO`
    is accepted too, so evaluations over many units load the file once."""
    model = _policy(policy_path, material)
    env = _env(load, material, target_g, calibration)
    try:
        obs, _ = env.reset(seed=0)
        return env.decode(_action(model, obs))
    finally:
        env.close()


@dataclass(frozen=True)
class PolicyTrial:
    """One format tested on one unit at the target level."""

    load: str
    wrap: WrapFormat
    passed: bool
    valid: bool
    margin: float
    material_kg: float
    reward: float
    #: The action as chosen, in [-1, 1] per parameter (`wrapenv.design.NAMES`): a policy's
    #: action pinned at a bound on every unit has stopped learning that parameter.
    action: tuple[float, ...]


def evaluate(policy_or_none: PPO | Path | None, loads: list[LoadUnit], material: str,
             target_g: float, seed: int) -> list[PolicyTrial]:
    """Each unit tested (target level only) with the policy's proposal, or with a uniformly
    random action from np.random.default_rng(seed) when the policy is None (one draw per unit,
    in order): the per-unit detail behind `pass_rate`, for comparing material too."""
    model = None if policy_or_none is None else _policy(policy_or_none, material)
    rng = np.random.default_rng(seed)

    def choose(obs: np.ndarray) -> np.ndarray:
        if model is None:
            return rng.uniform(-1.0, 1.0, N_PARAMS).astype(np.float32)
        return _action(model, obs)

    return [run_trial(load, choose, material, target_g) for load in loads]


def run_trial(load: LoadUnit, choose: Callable[[np.ndarray], np.ndarray], material: str,
              target_g: float) -> PolicyTrial:
    """One unit tested (target level only, training's nominal test) with the action `choose`
    picks from the unit's observation."""
    env = _env(load, material, target_g)
    try:
        obs, _ = env.reset(seed=0)
        action = choose(obs)
        _, reward, _, _, info = env.step(action)
        return PolicyTrial(load.name, env.decode(action), bool(info["passed"]),
                           bool(info["valid"]), float(info["margin"]),
                           float(info["material_used"]["mass_kg"]), float(reward),
                           tuple(float(a) for a in np.clip(action, -1.0, 1.0)))
    finally:
        env.close()


def pass_rate(policy_or_none: PPO | Path | None, loads: list[LoadUnit], material: str,
              target_g: float, seed: int) -> float:
    """Fraction of `loads` on which the policy's proposal (or a uniformly random action from
    np.random.default_rng(seed) when policy is None) passes the target level (env
    levels="target"). An invalid (blown-up) simulation counts as a failure."""
    trials = evaluate(policy_or_none, loads, material, target_g, seed)
    return sum(t.passed for t in trials) / len(trials) if trials else math.nan


def held_out_loads(n: int, seed: int) -> list[LoadUnit]:
    """n units drawn like WrapBenchRandomEnv draws them, from a seed not used in training (the
    env's own sampler, so the distribution cannot drift from the training one; see
    `HELD_OUT_STREAM` for why the stream differs from every training env's)."""
    env = WrapBenchRandomEnv(levels="target")
    try:
        rng = np.random.default_rng([seed, HELD_OUT_STREAM])
        return [env.sample_unit(rng) for _ in range(n)]
    finally:
        env.close()


__all__ = ["TrainSettings", "PolicyTrial", "evaluate", "held_out_loads", "load_policy", "pass_rate",
           "propose", "run_trial", "train"]
