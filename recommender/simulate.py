"""`wrapbench simulate`: a load unit (wrapped or not) through test levels on the bench, with
the verdict, the program's text and the outputs a user asked for; every input and output
checked before any simulation."""

from __future__ import annotations

import argparse
import os
import sys
from concurrent.futures import as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tqdm import tqdm

from recommender.commands import (
    as_flag,
    check_hours,
    criteria_limits,
    read_calibration,
    say_written,
    warn,
    wrap_json,
)
from recommender.html_page import Robustness
from recommender.html_report import (
    check_report_folder,
    report_outputs,
    simulate_page,
    write_report,
)
from recommender.parallel import executor
from recommender.search import VERIFY_SEED, Trial
from recommender.text import (
    age_text,
    calibration_text,
    orientation_tested,
    program_text,
    rerun_note,
    sample_figures,
    verdict_table,
)
from wrapenv.bench import BenchRun, SimSettings, run_levels
from wrapenv.calibrated import Calibration
from wrapenv.config import InputError, check_distinct, check_output, result_json, write_together
from wrapenv.eumos import LevelVerdict, Limits
from wrapenv.load import Layout, LoadUnit, Orientation
from wrapenv.pool import most_workers
from wrapenv.profile import MeasuredProfile, Profile, PulseProfile, eumos_levels, target_warnings
from wrapenv.uncertainty import PassProbability, Uncertainty
from wrapenv.wrap import WrapFormat


def _levels(args: argparse.Namespace) -> list[Any]:
    """The profiles asked for: a measured one, the given levels, or the EUMOS sequence."""
    if args.profile and (args.level or args.eumos):
        raise InputError("arguments", "--profile", "cannot be combined with --level or --eumos")
    if args.level and args.eumos:
        raise InputError("arguments", "--level", "cannot be combined with --eumos")
    for flag, value in (("--target", args.target), ("--start", args.start)):
        if value is not None and (args.level or args.profile):
            # it used to be ignored: the run looked like the sequence the user asked for
            raise InputError("arguments", flag, "sets the EUMOS sequence; with --level or "
                                                "--profile the levels run are those given")
    if args.profile:
        return [MeasuredProfile.from_csv(args.profile)]
    try:
        if args.level:
            return [PulseProfile(g) for g in args.level]  # every level checked before running
        levels = (eumos_levels(start_g=args.start) if args.target is None
                  else eumos_levels(args.target, args.start))
        return [PulseProfile(g) for g in levels]
    except InputError as exc:
        raise as_flag(exc) from None


@dataclass(frozen=True)
class _Inputs:
    """What `simulate` runs: the load (calibrated when asked), its layout, the wrap as laid
    (for the program's text) and as simulated (calibrated and relaxed), the calibration."""

    load: LoadUnit
    layout: Layout
    laid: WrapFormat | None
    wrap: WrapFormat | None
    calibration: Calibration | None


def _inputs(args: argparse.Namespace, said: list[str]) -> _Inputs:
    load = LoadUnit.from_toml(args.load)
    layout = load.layout(args.orientation)
    laid = WrapFormat.from_toml(args.wrap, layout.load_height_m) if args.wrap else None
    wrap, calibration = laid, None
    if args.calibration:
        calibration = read_calibration(args.calibration, "simulate", said)
        load = calibration.apply(load)
        if wrap is not None:
            wrap = wrap.scaled(calibration.stiffness_scale, calibration.tension_scale)
    check_hours(args.hours_since_wrapping)
    if args.hours_since_wrapping and wrap is None:
        raise InputError("arguments", "--hours-since-wrapping", "needs --wrap (an unwrapped "
                         "unit has no wrap tension to relax)")
    if wrap is not None:
        wrap = wrap.relaxed(args.hours_since_wrapping)
    return _Inputs(load, layout, laid, wrap, calibration)


def _check_outputs(args: argparse.Namespace, wrapped: bool) -> None:
    """Every output writable, none onto an input or another output, before any simulation."""
    inputs = [p for p in (args.load, args.wrap, args.calibration, args.profile) if p]
    check_output(args.json, "--json", inputs=inputs)
    check_output(args.plot, "--plot", inputs=inputs)
    if args.report is not None:
        check_report_folder(args.report, inputs)
    check_output(args.tension_map, "--tension-map", inputs=inputs)
    check_distinct({**report_outputs(args.report), "--json": args.json, "--plot": args.plot,
                    "--tension-map": args.tension_map})
    if args.tension_map and not wrapped:
        raise InputError("arguments", "--tension-map", "needs --wrap (an unwrapped unit has "
                                                       "no envelope to map)")


def run_simulate(args: argparse.Namespace) -> int:
    said: list[str] = []
    given = _inputs(args, said)
    load, layout, laid, wrap = given.load, given.layout, given.laid, given.wrap
    _check_outputs(args, wrap is not None)
    _check_sampling(args)
    levels = _levels(args)
    warn("simulate", tuple(w for p in levels if isinstance(p, MeasuredProfile)
                           for w in p.warnings()), said)
    if args.target is not None:
        warn("simulate", target_warnings(args.target), said)
    if laid is not None:
        warn("simulate", laid.warnings(layout), said)
    limits = criteria_limits(args)
    stop = not args.level and not args.profile
    with tqdm(total=len(levels), desc="levels", unit="level", file=sys.stderr,
              disable=None) as bar:
        run = run_levels(load, levels, orientation=args.orientation, stop_at_failure=stop,
                         wrap=wrap, fresh=args.fresh, limits=limits,
                         on_level=lambda v: _level_done(bar, v),
                         on_rerun=lambda iterations: _rerun(bar, iterations))
    print(verdict_table(load, run, args.orientation))
    sampled = _sampled(args, given, levels, limits) if args.samples else None
    if sampled is not None:
        print(sampled.text())
    if given.calibration is not None:
        print(calibration_text(str(args.calibration), given.calibration, load, wrap is not None))
    if laid is not None:
        print(program_text(laid, layout))
        print(age_text(laid.material, args.hours_since_wrapping))
    page = None
    if args.report:   # first: the slowest to make, and nothing of it shows until it is whole
        named = {"load unit": args.load, "wrap": args.wrap, "calibration": args.calibration,
                 "sled profile": args.profile}
        robust = None if sampled is None else sampled.robustness()
        page = write_report(args.report, lambda stage: simulate_page(
            stage, load, run, laid, wrap, args.orientation, args.hours_since_wrapping, named,
            tuple(said), levels, robust))
    files = {}
    if args.json:
        files[Path(args.json)] = _json(args, given, run, sampled)
    if args.plot:
        from recommender.report import plot_displacements

        files[Path(args.plot)] = plot_displacements(run, title=load.name)
    if args.tension_map:
        from recommender.report import plot_tension_map

        files[Path(args.tension_map)] = plot_tension_map(run, layout, title=load.name)
    write_together(files)
    say_written(page, *files)
    return 0 if run.verdict.passed else 1


def _json(args: argparse.Namespace, given: _Inputs, run: BenchRun,
          sampled: Sampled | None) -> bytes:
    """`--json`'s document (CONTRACTS.md: simulate's keys; `samples` with --samples)."""
    out = run.verdict.to_json() | {"orientation": orientation_tested(given.load,
                                                                     args.orientation)}
    if sampled is not None:
        out["samples"] = sampled.to_json()
    if rerun_note(run):
        out["solver_iterations"] = run.solver_iterations
    if given.calibration is not None:
        out["calibration"] = str(args.calibration)
    if given.wrap is not None and given.laid is not None:
        out.update(wrap_json(given.wrap, given.laid, given.layout, args.hours_since_wrapping))
        out["hours_since_wrapping"] = args.hours_since_wrapping
    return result_json(out)


# -- samples of what the bench does not know (--samples) -------------------------------------


@dataclass(frozen=True)
class SampleRun:
    """One sample's run through the levels asked: the search's record of a program in a sample
    (its verdict, the last level it ran, the level it failed at if it failed, and what was
    drawn), and the highest level it passed."""

    trial: Trial
    highest_passed_g: float | None


@dataclass(frozen=True)
class Sampled:
    """The levels asked, run in `--samples` draws of what the bench does not know: how many
    passed, and the worst."""

    seed: int
    runs: tuple[SampleRun, ...]
    wrapped: bool

    @property
    def probability(self) -> PassProbability:
        return PassProbability(sum(r.trial.passed for r in self.runs), len(self.runs))

    @property
    def worst(self) -> SampleRun:
        return min(self.runs, key=lambda r: r.trial.margin)

    def text(self) -> str:
        p, worst = self.probability, self.worst
        w, low_high = worst.trial, p.interval
        reached = ("no level" if worst.highest_passed_g is None
                   else f"up to {worst.highest_passed_g:.2f} g")
        drawn = ("friction, bundle mass, web stiffness, laid tension, relaxation, the load's "
                 "give" if self.wrapped else "friction, bundle mass")
        return (f"samples: passes in {p.passed} of {p.samples} samples of what the bench does "
                f"not know ({drawn}; seed {self.seed}): pass probability {p.estimate:.0%}, 95 % "
                f"interval {low_high[0]:.0%}-{low_high[1]:.0%}\nworst sample: margin "
                f"{w.margin:.2f}, passed {reached}, at {w.level['level_g']:.2f} g "
                f"{sample_figures(w.level)}"
                + (f" (the level stopped once decided: {w.level['stopped_early']})"
                   if w.level.get("stopped_early") else ""))

    def robustness(self) -> Robustness:
        """The samples as the report's section tells them."""
        return Robustness(self.probability, self.worst.trial)

    def to_json(self) -> dict[str, Any]:
        worst = self.worst
        w = worst.trial
        return {"seed": self.seed, "pass_probability": self.probability.to_json(),
                "worst": {"margin": round(w.margin, 4),
                          "highest_passed_g": worst.highest_passed_g, "level": w.level,
                          "sample": w.sample}}


def _check_sampling(args: argparse.Namespace) -> None:
    if args.samples is None:
        for flag, value in (("--seed", args.seed), ("--workers", args.workers)):
            if value is not None:
                raise InputError("arguments", flag, "needs --samples (it sets how the samples "
                                                    "are drawn or run)")
        return
    if args.samples < 1:
        raise InputError("arguments", "--samples", f"must be >= 1 (got {args.samples})")
    most = most_workers()
    if args.workers is not None and not 1 <= args.workers <= most:
        raise InputError("arguments", "--workers", f"must be from 1 to {most} (got "
                                                   f"{args.workers}): a simulation keeps a core "
                                                   "busy")


def _sampled(args: argparse.Namespace, given: _Inputs, levels: list[Profile],
             limits: Limits) -> Sampled:
    """The levels asked, in `--samples` draws of the uncertain parameters (recommend's: a
    calibration's spreads where it gives them, the documented ones elsewhere; its seeds, so
    `--seed` as recommend's draws the samples its verification drew), each level stopped once
    decided: a pass probability needs only the verdicts."""
    seed = args.seed or 0
    uncertainty = Uncertainty.of(given.calibration, args.hours_since_wrapping)
    stop = not args.level and not args.profile
    workers = args.workers or os.cpu_count() or 1
    with executor("process", min(workers, args.samples)) as pool, \
            tqdm(total=args.samples, desc="samples", unit="sample", file=sys.stderr,
                 disable=None) as bar:
        futures = [pool.submit(_sample_run, given.load, levels, given.laid, uncertainty,
                               VERIFY_SEED + seed + k, args.orientation, stop, args.fresh,
                               limits) for k in range(args.samples)]
        for _ in as_completed(futures):
            bar.update(1)
        return Sampled(seed, tuple(f.result() for f in futures), given.laid is not None)


def _sample_run(load: LoadUnit, levels: list[Profile], laid: WrapFormat | None,
                uncertainty: Uncertainty, seed: int, orientation: Orientation | None,
                stop: bool, fresh: bool, limits: Limits) -> SampleRun:
    """One sample (in a worker): the load and the wrap as it draws them, through the levels;
    its trial names the side that faced the motion."""
    sample = uncertainty.draw(load, seed)
    wrap = sample.wrap(laid) if laid is not None else None
    verdict = run_levels(sample.load(load), levels, SimSettings(stop_when_decided=True),
                         orientation=orientation, stop_at_failure=stop, wrap=wrap, fresh=fresh,
                         limits=limits).verdict
    trial = Trial(verdict.passed, verdict.margin, orientation_tested(load, orientation),
                  verdict.levels[-1].to_json(), sample.to_json())
    return SampleRun(trial, verdict.highest_passed_g)


def _rerun(bar: Any, iterations: int) -> None:
    """Progress starts again: the squeezed stack was not solved, the levels run with more
    iterations."""
    bar.reset()
    bar.set_description(f"levels ({iterations} solver iterations)")


def _level_done(bar: Any, verdict: LevelVerdict) -> None:
    """Progress of `simulate`: one tick per level, with the last one's result."""
    bar.update(1)
    bar.set_postfix(level=f"{verdict.level_g:.2f} g", result="pass" if verdict.passed else "fail")
