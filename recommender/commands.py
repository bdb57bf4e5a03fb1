"""The bench's own commands: `simulate`, `recommend` and `train`.

Each takes the parsed arguments, checks every input and output before any simulation, and maps
the domain's errors (which name domain fields) onto the flags a user typed.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import asdict
from pathlib import Path
from typing import Any

from tqdm import tqdm

from recommender.search import Evaluation, Problem, SearchSettings, SearchState
from recommender.text import program_text, verdict_table
from wrapenv.bench import BenchRun, run_levels
from wrapenv.calibrated import Calibration
from wrapenv.config import InputError, check_output, write_atomic
from wrapenv.load import Layout, LoadUnit
from wrapenv.material import MATERIALS
from wrapenv.profile import MeasuredProfile, PulseProfile, eumos_levels
from wrapenv.wrap import WrapFormat

#: Robust passes tried, lightest first, until one passes the whole EUMOS sequence.
VERIFY_CANDIDATES = 3
#: Flags of the domain's fields, for messages that name what the user typed.
FLAGS = {"target_g": "--target", "start_g": "--start", "level_g": "--level",
         "material": "--material"}


def as_flag(exc: InputError) -> InputError:
    """A domain error about an argument, naming the flag instead of the field."""
    return InputError("arguments", FLAGS.get(exc.field, exc.field), exc.message)


def _target(target_g: float) -> None:
    """A target level the bench can produce, or a usage error naming --target."""
    try:
        PulseProfile(target_g)
    except InputError as exc:
        raise InputError("arguments", "--target", exc.message) from None


def _material(key: str) -> None:
    if key not in MATERIALS:
        raise InputError("arguments", "--material",
                         f"must be one of {', '.join(map(repr, MATERIALS))} (got {key!r})")


def _warn(command: str, messages: tuple[str, ...]) -> None:
    for message in messages:
        sys.stderr.write(f"wrapbench {command}: warning: {message}\n")


# --- simulate ----------------------------------------------------------------------------------


def _levels(args: argparse.Namespace) -> list[Any]:
    """The profiles asked for: a measured one, the given levels, or the EUMOS sequence."""
    if args.profile and (args.level or args.eumos):
        raise InputError("arguments", "--profile", "cannot be combined with --level or --eumos")
    if args.level and args.eumos:
        raise InputError("arguments", "--level", "cannot be combined with --eumos")
    if args.profile:
        return [MeasuredProfile.from_csv(args.profile)]
    try:
        if args.level:
            return [PulseProfile(g) for g in args.level]  # every level checked before running
        return [PulseProfile(g) for g in eumos_levels(args.target, args.start)]
    except InputError as exc:
        raise as_flag(exc) from None


def run_simulate(args: argparse.Namespace) -> int:
    load = LoadUnit.from_toml(args.load)
    layout = load.layout(args.orientation)
    wrap = WrapFormat.from_toml(args.wrap, layout.load_height_m) if args.wrap else None
    laid = wrap
    if args.calibration:
        calibration = Calibration.from_json(args.calibration)
        load = calibration.apply(load)
        if wrap is not None:
            wrap = wrap.scaled(calibration.stiffness_scale, calibration.tension_scale)
    check_output(args.json, "--json")
    check_output(args.plot, "--plot")
    check_output(args.tension_map, "--tension-map")
    if args.tension_map and wrap is None:
        raise InputError("arguments", "--tension-map", "needs --wrap (an unwrapped unit has "
                                                       "no envelope to map)")
    levels = _levels(args)
    if laid is not None:
        _warn("simulate", laid.warnings())
    stop = not args.level and not args.profile
    run = run_levels(load, levels, orientation=args.orientation, stop_at_failure=stop, wrap=wrap)
    print(verdict_table(load, run, args.orientation))
    if laid is not None:
        print(program_text(laid, layout))
    if args.json:
        out = run.verdict.to_json()
        if wrap is not None and laid is not None:
            out.update(wrap_json(wrap, laid, layout))
        write_atomic(args.json, (json.dumps(out, indent=2) + "\n").encode())
    if args.plot:
        from recommender.report import plot_displacements

        plot_displacements(run, args.plot, title=load.name)
    if args.tension_map:
        from recommender.report import plot_tension_map

        plot_tension_map(run, layout, args.tension_map, title=load.name)
    return 0 if run.verdict.passed else 1


def wrap_json(simulated: WrapFormat, laid: WrapFormat, layout: Layout) -> dict[str, Any]:
    """The JSON keys of a wrap: what was simulated (`format`: bands as simulated, the program
    as entered), the web laid and the cycle time."""
    cycle = laid.cycle_time_s
    return {"format": {**simulated.to_json(), **({"program": laid.to_json()["program"]}
                                                 if laid.program is not None else {})},
            "material_used": asdict(laid.material_used_on(layout)),
            "cycle_time_s": round(cycle, 3), "pallets_per_hour": round(3600 / cycle, 2)}


# --- recommend ---------------------------------------------------------------------------------


def _settings(args: argparse.Namespace) -> SearchSettings:
    for flag, value, low in (("--samples", args.samples, 1), ("--budget", args.budget, 2),
                             ("--workers", args.workers, 1)):
        if value < low:
            raise InputError("arguments", flag, f"must be >= {low} (got {value})")
    if not (0 <= args.margin < 1):
        raise InputError("arguments", "--margin", f"must be in [0, 1) (got {args.margin})")
    if not args.max_cycle_s > 0:
        raise InputError("arguments", "--max-cycle-s", f"must be > 0 (got {args.max_cycle_s})")
    if not args.cycle_weight >= 0:
        raise InputError("arguments", "--cycle-weight",
                         f"must be >= 0 (got {args.cycle_weight})")
    _material(args.material)
    _target(args.target)
    return SearchSettings(target_g=args.target, material=args.material, samples=args.samples,
                          margin_goal=args.margin, max_candidates=args.budget, seed=args.seed,
                          workers=args.workers, popsize=min(8, args.budget),
                          backend=args.backend, ray_address=args.ray_address,
                          max_cycle_s=args.max_cycle_s, cycle_weight=args.cycle_weight)


def _checkpoint(args: argparse.Namespace) -> Path | None:
    """Where the search keeps its state: --checkpoint, else beside the --json output, else
    nowhere (an unasked file in the working folder is litter)."""
    if args.checkpoint is not None:
        return Path(args.checkpoint)
    if args.json is not None:
        return args.json.with_name(args.json.stem + ".checkpoint.json")
    if args.resume:
        raise InputError("arguments", "--resume", "needs --checkpoint (or --json, beside which "
                                                  "the checkpoint is kept)")
    return None


def _check_outputs(args: argparse.Namespace) -> Path | None:
    check_output(args.json, "--json")
    check_output(args.wrap_out, "--wrap-out")
    checkpoint = _checkpoint(args)
    check_output(checkpoint, "--checkpoint")
    if args.report is not None and args.report.exists() and not args.report.is_dir():
        raise InputError(str(args.report), "--report", "exists and is not a folder")
    return checkpoint


def run_recommend(args: argparse.Namespace) -> int:
    from recommender.search import RobustSearch

    load = LoadUnit.from_toml(args.load)
    calibration = Calibration.from_json(args.calibration) if args.calibration else None
    settings = _settings(args)
    checkpoint = _check_outputs(args)
    problem = Problem.build(load, settings, calibration)
    samples = max(8, args.samples)
    if args.method == "ppo":
        t0 = time.perf_counter()
        run, rate, best = _propose_with_policy(args, problem, samples)
        _print_recommendation(problem, best, run, rate, samples)
        print(f"policy proposal verified in {time.perf_counter() - t0:.0f} s")
        _write_outputs(args, problem, best, run, rate, samples, 1)
        return 0 if run.verdict.passed else 1
    search = RobustSearch(problem, checkpoint)
    if args.resume and (checkpoint is None or not checkpoint.exists()):
        raise InputError(str(checkpoint), "--resume", "no checkpoint to resume from")
    state = search.resume() if args.resume else search.start()
    t0 = time.perf_counter()
    state = _run_search(search, state, settings)
    chosen = _verified(problem, state, samples, args.workers)
    if checkpoint is not None:
        checkpoint.unlink(missing_ok=True)
    if chosen is None:
        print(f"no program passed the EUMOS sequence up to {args.target:.2f} g after "
              f"{len(state.history)} candidates x {args.samples} samples")
        return 1
    best, run, rate = chosen
    _print_recommendation(problem, best, run, rate, samples)
    simulations = sum(len(e.passed) for e in state.history)
    print(f"searched {len(state.history)} candidates ({simulations} simulations) in "
          f"{time.perf_counter() - t0:.0f} s ({args.workers} workers, {args.backend})")
    _write_outputs(args, problem, best, run, rate, samples, simulations,
                   candidates=len(state.history))
    if args.report:
        _write_report(args.report, problem, run, best, state, settings.margin_goal)
    return 0


def _run_search(search: Any, state: SearchState, settings: SearchSettings) -> SearchState:
    with tqdm(total=settings.max_candidates, desc="candidates", unit="program",
              file=sys.stderr, disable=None) as bar:
        bar.update(len(state.history))

        def progress(done: int, total: int, st: SearchState) -> None:
            bar.update(done - bar.n)
            best = st.best(settings.margin_goal)
            if best is not None:
                bar.set_postfix(best_kg=f"{best.mass_kg:.3f}", margin=f"{best.margin:.2f}")

        return search.run(state, progress)


def _verified(problem: Problem, state: SearchState, samples: int,
              workers: int) -> tuple[Evaluation, BenchRun, float] | None:
    """The lightest robust pass that also passes the whole EUMOS sequence (the search tried
    the target level only)."""
    from recommender.search import verify

    for candidate in state.ranked(problem.settings.margin_goal)[:VERIFY_CANDIDATES]:
        run, rate = verify(problem, candidate.wrap, samples, workers=workers)
        if run.verdict.passed:
            return candidate, run, rate
    return None


def _propose_with_policy(args: argparse.Namespace, problem: Problem,
                         samples: int) -> tuple[BenchRun, float, Evaluation]:
    """A trained policy's program for this unit, answered at once, then verified."""
    from recommender.policy import propose
    from recommender.search import verify

    if args.policy is None or not args.policy.is_file():
        where = "arguments" if args.policy is None else str(args.policy)
        raise InputError(where, "--policy", "a policy.zip from `wrapbench train` is needed "
                                            "with --method ppo")
    calibration = Calibration.from_json(args.calibration) if args.calibration else None
    wrap = propose(args.policy, LoadUnit.from_toml(args.load), args.material, args.target,
                   calibration)
    run, rate = verify(problem, wrap, samples, workers=args.workers)
    mass = wrap.material_used_on(problem.layout).mass_kg
    best = Evaluation((), wrap, mass, wrap.cycle_time_s, (run.verdict.margin,),
                      (run.verdict.passed,), 0.0)
    return run, rate, best


def _print_recommendation(problem: Problem, best: Evaluation, run: BenchRun, rate: float,
                          samples: int) -> None:
    s = problem.settings
    print(f"recommended wrapping program for {problem.load.name}: passes {s.target_g:.2f} g in "
          f"{rate:.0%} of {samples} samples of friction and mass (search margin "
          f"{best.margin:.2f})")
    print(program_text(best.wrap, problem.layout))
    print(verdict_table(problem.load, run, None))


def _write_outputs(args: argparse.Namespace, problem: Problem, best: Evaluation, run: BenchRun,
                   rate: float, samples: int, evaluations: int,
                   candidates: int | None = None) -> None:
    if args.json:
        out = {**wrap_json(problem.simulated(best.wrap), best.wrap, problem.layout),
               "program": best.wrap.to_json().get("program"),
               "verdict": run.verdict.to_json(), "robust_pass_rate": rate,
               "robust_samples": samples, "search_margin": best.margin,
               "evaluations": evaluations, "candidates": candidates,
               "method": args.method, "target_g": args.target}
        write_atomic(args.json, (json.dumps(out, indent=2) + "\n").encode())
    if args.wrap_out:
        write_atomic(args.wrap_out, best.wrap.to_toml().encode())


def _write_report(folder: Path, problem: Problem, run: BenchRun, best: Evaluation,
                  state: SearchState, margin_goal: float) -> None:
    from recommender.report import plot_displacements, plot_search, plot_tension_map, write_video

    folder.mkdir(parents=True, exist_ok=True)
    plot_displacements(run, folder / "displacement.png", title=problem.load.name)
    plot_tension_map(run, problem.layout, folder / "tension_map.png", title=problem.load.name)
    plot_search(state.history, best, folder / "search.png", margin_goal)
    write_video(run.traces[-1], problem.layout, problem.simulated(best.wrap),
                folder / "test.mp4")


# --- train -------------------------------------------------------------------------------------


def run_train(args: argparse.Namespace) -> int:
    from recommender.policy import TrainSettings, train

    for flag, value in (("--timesteps", args.timesteps), ("--envs", args.envs)):
        if value < 1:
            raise InputError("arguments", flag, f"must be >= 1 (got {value})")
    _material(args.material)
    _target(args.target)
    if args.out.exists() and not args.out.is_dir():
        raise InputError(str(args.out), "--out", "exists and is not a folder")
    args.out.mkdir(parents=True, exist_ok=True)
    settings = TrainSettings(timesteps=args.timesteps, n_envs=args.envs, material=args.material,
                             target_g=args.target, seed=args.seed)
    path = train(settings, args.out)
    print(f"policy written to {path} (log: {args.out / 'log.csv'})")
    return 0
