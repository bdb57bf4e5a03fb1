"""The bench's command `train`: a PPO policy on random load units, in a folder it can resume.

It imports the policy's module, and torch with it: `wrapbench` imports this module only for a
training run, so that the other commands start without them.
"""

from __future__ import annotations

import argparse
import contextlib
from pathlib import Path

from recommender import policy
from recommender.commands import as_flag, check_target, named_web, read_calibration
from wrapenv.calibrated import Calibration
from wrapenv.config import InputError, check_output
from wrapenv.pool import most_workers


def _checked_settings(args: argparse.Namespace, calibration: Calibration | None
                      ) -> policy.TrainSettings:
    """The run's settings, checked where the library checks them (`TrainSettings.check`), each
    refusal naming its flag, before a folder is made; and what only the command bounds: the
    machine's cores, and a time limit that lets a run start."""
    most = most_workers()
    if args.envs > most:
        raise InputError("arguments", "--envs", f"must be <= {most} (got {args.envs}): each "
                                                "is a process simulating on a core")
    if args.minutes is not None and not args.minutes > 0:   # NaN too
        raise InputError("arguments", "--minutes", f"must be > 0 (got {args.minutes})")
    settings = policy.TrainSettings(
        timesteps=args.timesteps, workers=args.envs, material=args.material,
        target_g=args.target, seed=args.seed, max_minutes=args.minutes, calibration=calibration,
        test=args.test, material_weight=args.material_weight, log_std_init=args.log_std_init,
        tests_per_episode=args.tests_per_episode)
    try:
        settings.check()
    except InputError as exc:
        raise as_flag(exc) from None
    return settings


def _run_folder(out: Path, resume: bool, timesteps: int) -> bool:
    """The training run's folder, made if missing and checked (`timesteps`: the run's total);
    whether it was made (a refusal leaves no folder behind)."""
    if out.exists() and not out.is_dir():
        raise InputError(str(out), "--out", "exists and is not a folder")
    made = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(str(out), "--out", f"cannot be created ({exc.strerror})") from None
    try:
        check_output(out / policy.POLICY_FILE, "--out")
        _check_run_folder(out, resume, timesteps)
    except InputError:
        if made:
            out.rmdir()
        raise
    return made


def run_train(args: argparse.Namespace) -> int:
    named_web(args.material)
    check_target(args.target)
    calibration = (None if args.calibration is None
                   else read_calibration(args.calibration, "train"))
    settings = _checked_settings(args, calibration)
    made = _run_folder(args.out, args.resume, settings.rollout_timesteps)
    if settings.rollout_timesteps != settings.timesteps:
        print(f"training {settings.rollout_timesteps} timesteps: PPO collects whole rollouts of "
              f"{settings.n_steps * settings.n_envs} episodes")
    try:
        path = policy.train(settings, args.out, resume=args.resume)
    except KeyboardInterrupt as exc:
        kept = policy.last_checkpoint(args.out)
        if kept:
            exc.add_note(f"interrupted; no policy.zip written, the last checkpoint is {kept[0]} "
                         f"(--resume continues from it)")
        else:
            _forget_run(args.out, made)
            exc.add_note("interrupted before the first checkpoint: nothing written (the same "
                         "command starts the run again)")
        raise
    print(f"policy written to {path} (log: {args.out / policy.LOG_FILE})")
    return 0


def _forget_run(out: Path, made: bool) -> None:
    """What a run interrupted before its first checkpoint wrote: its log and its empty
    checkpoints/, and `out` itself if the run `made` it. Kept, the log made a folder that could
    be neither resumed (no checkpoint) nor trained into again (an earlier run's log)."""
    (out / policy.LOG_FILE).unlink(missing_ok=True)
    for folder in (out / policy.CHECKPOINT_DIR, out) if made else (out / policy.CHECKPOINT_DIR,):
        with contextlib.suppress(OSError):   # not empty: something else is there, kept
            folder.rmdir()


def _check_run_folder(out: Path, resume: bool, timesteps: int) -> None:
    """A new run needs a folder without one; a resumed run, an interrupted one (checkpoints,
    its log, no policy.zip), or a finished one to train on past its last checkpoint."""
    if resume:
        kept = policy.last_checkpoint(out)
        if kept is None or not (out / policy.LOG_FILE).is_file():
            raise InputError(str(out), "--resume", "holds no run to resume (checkpoints/ and "
                                                   "log.csv)")
        if (out / policy.POLICY_FILE).exists() and kept[1] >= timesteps:
            raise InputError(str(out), "--resume", f"the run finished, its last checkpoint at "
                             f"{kept[1]} timesteps: give --timesteps above {kept[1]} to train "
                             f"it on, or train a new one into another folder")
        return
    # a run that failed before its first checkpoint leaves an empty checkpoints/: no run
    earlier = [name for name in (policy.POLICY_FILE, policy.LOG_FILE) if (out / name).exists()]
    if any((out / policy.CHECKPOINT_DIR).glob("*")):
        earlier.append(policy.CHECKPOINT_DIR)
    if earlier:
        raise InputError(str(out), "--out", f"holds an earlier training run "
                                            f"({', '.join(earlier)}): give a new folder, or "
                                            f"--resume the run it holds")
