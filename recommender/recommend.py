"""The bench's command `recommend`: the least web that passes with a margin, found by a robust
search (or proposed by a trained policy), verified on fresh samples of what the bench does not
know, then printed and written as the user asked."""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from tqdm import tqdm

from recommender.checkpoint import FIRST_ROUND, Round, read_round
from recommender.checkpoint import FORMAT_FAMILY as SEARCH_CHECKPOINT
from recommender.commands import (
    check_hours,
    check_target,
    criteria_limits,
    named_web,
    read_calibration,
    say_written,
    warn,
    wrap_json,
)
from recommender.html_report import (
    check_report_folder,
    recommend_page,
    report_outputs,
    write_report,
)
from recommender.search import (
    STRONGEST_PROGRAM,
    TIGHT_PROGRAMS,
    Evaluation,
    Problem,
    RobustSearch,
    SearchSettings,
    SearchState,
    Verification,
    at_top_tension,
    next_start,
)
from recommender.text import calibration_text, program_text, sample_figures, verdict_table
from wrapenv.calibrated import Calibration
from wrapenv.config import (
    InputError,
    check_checkpoint,
    check_distinct,
    check_output,
    fraction_hint,
    printable,
    result_json,
    write_together,
)
from wrapenv.load import ORIENTATIONS, LoadUnit, Orientation
from wrapenv.pool import most_workers
from wrapenv.profile import target_warnings
from wrapenv.wrap import Web, WrapFormat

if TYPE_CHECKING:
    from stable_baselines3 import PPO

#: Robust passes tried, lightest first, until one passes the whole EUMOS sequence.
VERIFY_CANDIDATES = 3
#: The fewest fresh samples an answer's verification holds in (more with a larger --samples).
VERIFY_SAMPLES = 8


def _web(args: argparse.Namespace) -> Web:
    """The web a program is sought for: a named card on the default web, or a WRAP.toml's."""
    if args.web is None:
        return named_web(args.material or "kraft")
    if args.material is not None:
        raise InputError("arguments", "--material", "cannot be combined with --web (the web's "
                         "file names its material)")
    return Web.from_toml(args.web)


def _targets(args: argparse.Namespace) -> tuple[tuple[Orientation, float], ...]:
    """(orientation, target) pairs: --orientation both (default) searches both sides, each at
    --target unless --target-long / --target-short says otherwise."""
    sides = ORIENTATIONS if args.orientation == "both" else (args.orientation,)
    given = {"long": args.target_long, "short": args.target_short}
    for side, target in given.items():
        if target is not None:
            check_target(target, f"--target-{side}")
            if side not in sides:
                raise InputError("arguments", f"--target-{side}",
                                 f"needs --orientation {side} or both")
    check_target(args.target)
    return tuple((side, given[side] if given[side] is not None else args.target)
                 for side in sides)


#: The flags that only steer a search, and their arguments (None: not given, the search's
#: default).
SEARCH_FLAGS = {"--margin": "margin", "--budget": "budget", "--cycle-weight": "cycle_weight",
                "--rounds": "rounds"}
#: Search rounds at most (`SearchSettings.in_round`): a second round, with one more sample and
#: twice the budget, runs only when every pass of the first failed its verification. With
#: --method ppo round 1 is the policy's proposal, which searches nothing, so one more: a failing
#: proposal is followed by as many search rounds as a search has (held-out film unit 11: the
#: round from the proposal found no pass that held, where the search's round from the
#: strongest program answered; docs/recommend.md).
DEFAULT_ROUNDS = 2


def _settings(args: argparse.Namespace) -> SearchSettings:
    given = {name: getattr(args, name) for name in SEARCH_FLAGS.values()}
    margin = SearchSettings.margin_goal if given["margin"] is None else given["margin"]
    budget: int = SearchSettings.max_candidates if given["budget"] is None else given["budget"]
    cycle_weight = (SearchSettings.cycle_weight if given["cycle_weight"] is None
                    else given["cycle_weight"])
    for flag, value, low in (("--samples", args.samples, 1),
                             ("--budget", budget, len(TIGHT_PROGRAMS)),
                             ("--workers", args.workers, 1), ("--rounds", _rounds(args), 1)):
        if value < low:
            why = (": the first generation tries the lightest program at three tensions"
                   if flag == "--budget" else "")
            raise InputError("arguments", flag, f"must be >= {low} (got {value}){why}")
    most = most_workers() if args.backend == "process" else 4096
    if args.workers > most:
        raise InputError("arguments", "--workers", f"must be <= {most} on the {args.backend} "
                         f"backend (got {args.workers}): a simulation keeps a core busy")
    if not (0 <= margin < 1):
        raise InputError("arguments", "--margin",
                         f"must be in [0, 1) (got {margin}){fraction_hint(margin)}")
    if not args.max_cycle_s > 0:
        raise InputError("arguments", "--max-cycle-s", f"must be > 0 (got {args.max_cycle_s})")
    if not cycle_weight >= 0:
        raise InputError("arguments", "--cycle-weight", f"must be >= 0 (got {cycle_weight})")
    check_hours(args.hours_since_wrapping)
    return SearchSettings(targets=_targets(args), web=_web(args), samples=args.samples,
                          margin_goal=margin, max_candidates=budget, seed=args.seed,
                          workers=args.workers, popsize=min(SearchSettings.popsize, budget),
                          backend=args.backend, ray_address=args.ray_address,
                          max_cycle_s=args.max_cycle_s, cycle_weight=cycle_weight,
                          hours_since_wrapping=args.hours_since_wrapping,
                          limits=criteria_limits(args), fresh=args.fresh,
                          ordered_tensions=args.ordered_tensions)


def _rounds(args: argparse.Namespace) -> int:
    """Search rounds at most: --rounds, or `DEFAULT_ROUNDS` (one more with --method ppo, whose
    round 1 is its proposal)."""
    if args.rounds is not None:
        return int(args.rounds)
    return DEFAULT_ROUNDS + (args.method == "ppo")


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


def _check_flags(args: argparse.Namespace) -> None:
    """A flag that does nothing in the chosen mode is refused: the user meant something."""
    unused = [("--ray-address", args.ray_address is not None and args.backend != "ray",
               "needs --backend ray"),
              ("--policy", args.policy is not None and args.method != "ppo",
               "needs --method ppo (a search proposes its own program)"),
              ("--web", args.web is not None and args.method == "ppo",
               "a policy proposes for the card and the 0.5 m web it was trained on "
               "(--material); search for another web with --method cmaes")]
    unused += [(flag, wasted and args.method == "ppo" and _rounds(args) == 1,
                "steers a search; --method ppo with --rounds 1 does not search")
               for flag, wasted in (("--resume", args.resume),
                                    ("--checkpoint", args.checkpoint is not None),
                                    *((flag, getattr(args, name) is not None)
                                      for flag, name in SEARCH_FLAGS.items()
                                      if flag != "--rounds"))]
    for flag, wasted, why in unused:
        if wasted:
            raise InputError("arguments", flag, why)


def _check_outputs(args: argparse.Namespace) -> Path | None:
    inputs = [p for p in (args.load, args.calibration, args.policy, args.web) if p]
    check_output(args.json, "--json", inputs=inputs)
    check_output(args.wrap_out, "--wrap-out", inputs=inputs)
    checkpoint = _checkpoint(args)
    check_checkpoint(checkpoint, "--checkpoint", SEARCH_CHECKPOINT, inputs=inputs)
    check_distinct({**report_outputs(args.report), "--json": args.json,
                    "--wrap-out": args.wrap_out, "--checkpoint": checkpoint})
    if args.report is not None:
        check_report_folder(args.report, inputs)
    if args.resume and (checkpoint is None or not checkpoint.exists()):
        raise InputError(str(checkpoint), "--resume", "no checkpoint to resume from")
    return checkpoint


def run_recommend(args: argparse.Namespace) -> int:
    load = LoadUnit.from_toml(args.load)
    said: list[str] = []
    calibration = (read_calibration(args.calibration, "recommend", said) if args.calibration
                   else None)
    settings = _settings(args)
    _check_flags(args)
    checkpoint = _check_outputs(args)
    problem = Problem.build(load, settings, calibration)
    # resumed: its proposal was refused, and the search goes on
    proposer = (_Proposer.read(args.policy, load, calibration, settings.web.material_key)
                if args.method == "ppo" and not args.resume else None)
    # after every check: a refused command prints its one line alone
    warn("recommend", tuple(dict.fromkeys(w for _, g in settings.targets
                                          for w in target_warnings(g))), said)
    if calibration is not None:   # said first: every program below is judged with it
        print(calibration_text(str(args.calibration), calibration, problem.load, wrapped=True),
              flush=True)
    samples = max(VERIFY_SAMPLES, args.samples)
    if proposer is not None:
        return _recommend_by_policy(args, proposer, problem, checkpoint, samples, said)
    return _recommend_by_search(args, problem, checkpoint, samples, said)


@dataclass(frozen=True)
class _Proposer:
    """A trained policy and the unit it is to propose for, checked and loaded with the other
    inputs: a refused policy file prints its one line alone."""

    model: PPO
    meta: dict[str, Any]
    load: LoadUnit   # as the load file gives it: the policy applies the calibration itself
    calibration: Calibration | None

    @classmethod
    def read(cls, policy_path: Path | None, load: LoadUnit, calibration: Calibration | None,
             material: str) -> _Proposer:
        from recommender.policy import load_policy_and_meta

        needed = "a policy.zip from `wrapbench train` is needed with --method ppo"
        if policy_path is None:
            raise InputError("arguments", "--policy", needed)
        if policy_path.is_dir():
            raise InputError(str(policy_path), "--policy",
                             f"is a folder, not a policy.zip ({needed})")
        if not policy_path.is_file():
            raise InputError(str(policy_path), "--policy", f"no such file ({needed})")
        return cls(*load_policy_and_meta(policy_path, material), load, calibration)


def _recommend_by_policy(args: argparse.Namespace, proposer: _Proposer, problem: Problem,
                         checkpoint: Path | None, samples: int, said: list[str]) -> int:
    """The policy's proposal, verified as a search's answer is. It is round 1: if it does not
    hold, and --rounds allows, the next round searches from it (`_from_proposal`), once the
    strongest program of the space has held its verification (`_strongest_fails`: on three
    held-out film units where nothing holds, the round from the proposal took 75-563 s to find
    no pass, the check 37-78 s in all), and the round after that from the strongest program
    (`_search_rounds`); otherwise nothing is written (exit 1)."""
    t0 = time.perf_counter()
    best, check = _propose_with_policy(proposer, problem, samples, args.workers, said)
    refused = _refused_proposal(problem, best, check)
    _print_recommendation(problem, best, check, recommended=not refused,
                          margin_of="nominal")   # no search: the proposal's own runs
    print(f"policy proposal verified in {time.perf_counter() - t0:.0f} s")
    if not refused:
        _write_outputs(args, problem, best, check, 1, None, said)
        return 0
    if _rounds(args) == 1:   # as a search that finds no pass: nothing to enter, nothing written
        print(f"the policy's proposal {refused}: nothing written (--rounds 1); search from it "
              f"with more --rounds")
        return 1
    first = _from_proposal(problem, best.wrap)
    weak = _strongest_fails(problem.in_round(first.number), STRONGEST_PROGRAM, samples,
                            args.workers)
    if weak:
        print(f"round 1: the policy's proposal {refused}, and {weak}: no program is searched")
        return 1
    print(f"round 1: the policy's proposal {refused}; searching from it "
          f"{_next_round_text(problem, first.number, _rounds(args))}", flush=True)
    return _recommend_by_search(args, problem, checkpoint, samples, said, first)


def _from_proposal(problem: Problem, proposal: WrapFormat) -> Round:
    """The round after a policy's proposal that did not hold: a search from it, every tension
    at the top, as from a first round's pass that failed its verification (`next_start`). A
    film policy's proposals pass training's test on most units and fail the verification's
    samples on half (docs/recommend.md): near a pass, rather than at the light end where a
    first round starts. On the two held-out film units measured where the proposal failed and
    the search answered, the round from it answered with 9-10 % less web, a little sooner."""
    return FIRST_ROUND.next(0, 0, at_top_tension(problem.vector(proposal)))


def _recommend_by_search(args: argparse.Namespace, problem: Problem, checkpoint: Path | None,
                         samples: int, said: list[str], first: Round = FIRST_ROUND) -> int:
    """The robust search, its answer verified, in rounds while a round has no pass that holds
    its verification (`_search_rounds`, from `first`); an interrupt keeps the checkpoint and
    says so."""
    t0 = time.perf_counter()
    try:
        round_, current, state, chosen = _search_rounds(args, problem, checkpoint, samples,
                                                        first)
    except KeyboardInterrupt as exc:  # in a search or its answer's verification
        if checkpoint is not None and checkpoint.exists():
            exc.add_note(f"interrupted, nothing written; the search so far is kept in "
                         f"{checkpoint} (--resume continues it)")
        raise
    if chosen is None:
        print(_nothing_passed(state, current.settings, round_.number, samples,
                              round_.start))
        _forget(checkpoint)
        return 1
    best, check = chosen
    _print_recommendation(current, best, check)
    candidates = round_.earlier_candidates + len(state.history)
    simulations = round_.earlier_simulations + state.simulations
    print(f"searched {candidates} candidates ({simulations} simulations) in "
          f"{time.perf_counter() - t0:.0f} s ({args.workers} workers, {args.backend}"
          f"{_rounds_text(round_, current.settings, args.method)})")
    try:
        _write_outputs(args, current, best, check, simulations, state, said, round_)
    except KeyboardInterrupt as exc:
        if checkpoint is not None:
            exc.add_note(f"interrupted: --json and --wrap-out not written; the search is "
                         f"kept in {checkpoint} (--resume continues it)")
        raise
    _forget(checkpoint)
    return 0


def _search_rounds(args: argparse.Namespace, problem: Problem, checkpoint: Path | None,
                   samples: int, first: Round = FIRST_ROUND
                   ) -> tuple[Round, Problem, SearchState, tuple[Evaluation, Verification] | None]:
    """Search and verify; while every pass of a round failed its verification, or it found
    none, search again in the next round (`SearchSettings.in_round`), up to --rounds, from
    `next_start` (after no pass, the strongest program, and only if it holds its verification:
    `_strongest_fails`); after the round from a policy's proposal, from the strongest program
    (on held-out film unit 11 a third round from that round's passes found none that held,
    where the search answered from the strongest program; docs/recommend.md). A resumed
    search continues the round its checkpoint was written in.
    Returns the last round, its problem, its search and the verified answer (None: none)."""
    round_ = read_round(checkpoint) if args.resume else first
    resume = args.resume
    while True:
        current = problem.in_round(round_.number)
        search = RobustSearch(current, checkpoint, round_)
        state = search.resume() if resume else search.start()
        if round_.number > 1 and not resume:
            search.save()   # from now on an interrupt resumes this round, not the last
        state = _run_search(search, state, current.settings, round_.number)
        chosen = _verified(current, state, samples, args.workers)
        start = next_start(state, current.settings)
        if chosen is not None or round_.number >= _rounds(args) or start is None:
            return round_, current, state, chosen
        passes = bool(state.to_verify(current.settings.margin_goal))
        why = (_failed_verification(state, current.settings, samples) if passes else
               f"no program passed the search's {_samples_text(current.settings.samples)}")
        after_proposal = _from_proposal_round(args.method, round_.number)
        if after_proposal:   # the strongest program held its verification before round 2
            start = STRONGEST_PROGRAM
        strongest = start == STRONGEST_PROGRAM
        weak = ("" if passes or after_proposal else
                _strongest_fails(problem.in_round(round_.number + 1), start, samples,
                                 args.workers))
        if weak:
            print(f"round {round_.number}: {why}, and {weak}: no lighter program is searched",
                  flush=True)
            return round_, current, state, None
        round_, resume = round_.next(len(state.history), state.simulations, start), False
        print(f"round {round_.number - 1}: {why}; searching again "
              f"{_next_round_text(problem, round_.number, _rounds(args))}, from "
              f"{'the strongest program of the space' if strongest else 'the lightest of them'}",
              flush=True)


def _from_proposal_round(method: str, number: int) -> bool:
    """Whether search round `number` is the one from a policy's proposal (its round 1)."""
    return method == "ppo" and number == 2


def _next_round_text(problem: Problem, number: int, rounds: int) -> str:
    """How round `number` searches, as it starts (`SearchSettings.in_round`)."""
    following = problem.settings.in_round(number)
    return (f"with {following.samples} samples and a budget of {following.max_candidates} "
            f"candidates (round {number} of at most {rounds}), every tension at the top of its "
            f"range ({problem.space.tension_range_n[1]:.0f} N)")


def _strongest_fails(problem: Problem, start: tuple[float, ...], samples: int,
                     workers: int) -> str:
    """Why the strongest program of the space (`start`, in the round it would start) does not
    hold its verification ("": it holds, or it is over the cycle-time limit and a lighter one
    may not be). A round from it searches lighter, weaker programs: on the three of 12
    held-out film units where it did not hold, that round found nothing in 56-561 s
    (2026-11-28, docs/recommend.md)."""
    from recommender.search import verify

    wrap = problem.wrap(np.array(start))
    if problem.too_slow(wrap) is not None:
        return ""
    check = verify(problem, wrap, samples, workers=workers)
    if check.holds:
        return ""
    p = check.probability
    failed = [f"the {side} side ({_passed_to(run.verdict.highest_passed_g)})"
              for side, run in check.runs.items() if not run.verdict.passed]
    how = (f"fails the EUMOS sequence on {' and '.join(failed)}, and holds in {p.passed} of "
           f"{p.samples} samples" if failed else
           f"holds in only {p.passed} of {p.samples} samples")
    mass = wrap.material_used_on(problem.layout).mass_kg
    return (f"the strongest program of the space ({mass:.3f} kg, every tension at the top of "
            f"its range, {problem.space.tension_range_n[1]:.0f} N) {how}")


def _passed_to(level_g: float | None) -> str:
    """How far a failed sequence got: what tells an engineer how near the target a unit is."""
    return "no level passed" if level_g is None else f"passed to {level_g:.2f} g"


def _rounds_text(round_: Round, settings: SearchSettings, method: str) -> str:
    """'', or how many rounds the answer took and why (with --method ppo round 1 is the
    policy's proposal)."""
    if round_.number == 1:
        return ""
    before = ("the policy's proposal did not hold its verification"
              if _from_proposal_round(method, round_.number) else
              "the round before found no pass that held its verification")
    return (f"; round {round_.number}, {settings.samples} samples a candidate, every tension at "
            f"the top: {before}")


def _forget(checkpoint: Path | None) -> None:
    """A search that answered needs no checkpoint (removed once the answer is written)."""
    if checkpoint is not None:
        checkpoint.unlink(missing_ok=True)


def _failed_verification(state: SearchState, settings: SearchSettings,
                         verification_samples: int) -> str:
    """How a round's passes failed their verification."""
    passes = len(state.to_verify(settings.margin_goal))
    tried = min(passes, VERIFY_CANDIDATES)
    return (f"the {tried} lightest of the {passes} programs that passed the search's "
            f"{_samples_text(settings.samples)} failed their verification (the whole EUMOS "
            f"sequence, or one of {verification_samples} samples)")


def _samples_text(samples: int) -> str:
    return f"{samples} sample{'s' if samples != 1 else ''}"


def _nothing_passed(state: SearchState, settings: SearchSettings, round_number: int,
                    verification_samples: int, start: tuple[float, ...] | None = None) -> str:
    """Why no program is recommended (`settings`: those of the last round, `round_number`,
    `start`: where it started): the search's passes failed their verification, or every
    candidate failed (the strongest program of the space too, if the round started there), or
    was over the cycle-time limit and never simulated (nor were candidates heavier than a pass
    that later failed its verification: they are not slow)."""
    history = state.history
    last = f" in round {round_number}" if round_number > 1 else ""
    if state.to_verify(settings.margin_goal):
        return (f"no program recommended: "
                f"{_failed_verification(state, settings, verification_samples)}{last}; more "
                f"--samples, --budget or --rounds make the search's passes sturdier")
    slow = [e for e in history if e.cycle_s > settings.max_cycle_s]
    if history and len(slow) == len(history):
        return (f"no program within the cycle-time limit of {settings.max_cycle_s:g} s: all "
                f"{len(history)} candidates take longer (the fastest "
                f"{min(e.cycle_s for e in slow):.0f} s)")
    over = f", {len(slow)} of them over the cycle-time limit" if slow else ""
    strongest = (f", the strongest program of the space ({history[0].mass_kg:.3f} kg, every "
                 f"tension at the top) among them" if start == STRONGEST_PROGRAM and history
                 else "")
    return (f"no program passed the EUMOS sequence ({_targets_text(settings)}) after "
            f"{len(history)} candidates x {settings.samples} samples{over}{last}{strongest}")


def _targets_text(settings: SearchSettings) -> str:
    return ", ".join(f"{side} side {g:.2f} g" for side, g in settings.targets)


def _run_search(search: Any, state: SearchState, settings: SearchSettings,
                round_number: int) -> SearchState:
    desc = "candidates" if round_number == 1 else f"candidates (round {round_number})"
    with tqdm(total=settings.max_candidates, desc=desc, unit="program",
              file=sys.stderr, disable=None) as bar:
        bar.update(len(state.history))

        def progress(done: int, st: SearchState) -> None:
            bar.update(done - bar.n)
            best = st.best(settings.margin_goal)
            if best is not None:
                bar.set_postfix(best_kg=f"{best.mass_kg:.3f}", margin=f"{best.margin:.2f}")

        return search.run(state, progress)


def _verified(problem: Problem, state: SearchState, samples: int,
              workers: int) -> tuple[Evaluation, Verification] | None:
    """The first pass (`SearchState.to_verify`: confirmed ones, then screened ones) that also
    passes the whole EUMOS sequence in every orientation (the search tried the target levels
    only) and every sample of its verification, as a policy's proposal must: a pass of a few
    search samples may hold in them by chance (with --samples 2 a program passing 3 of 8
    verification samples was recommended, exit 0). A pass's verification ends at its first
    failure (`holding`)."""
    from recommender.search import holding

    for candidate in state.to_verify(problem.settings.margin_goal)[:VERIFY_CANDIDATES]:
        check = holding(problem, candidate.wrap, samples, workers=workers)
        if check is not None:
            return candidate, check
    return None


def _propose_with_policy(proposer: _Proposer, problem: Problem, samples: int, workers: int,
                         said: list[str]) -> tuple[Evaluation, Verification]:
    """A trained policy's program for this unit, answered at once, then verified."""
    from recommender.policy import propose
    from recommender.search import verify
    from wrapenv.envs.random_units import base_friction, outside

    meta, load, calibration = proposer.meta, proposer.load, proposer.calibration
    trained_g, target_g = meta.get("target_g"), problem.settings.target_g
    if isinstance(trained_g, int | float) and abs(trained_g - target_g) > 1e-9:
        warn("recommend", (f"the policy was trained for {trained_g:g} g and is asked for "
                           f"{target_g:g} g (the target is one of its observations): its "
                           "proposal is an extrapolation, verified as given",), said)
    if meta.get("calibrated", False) != (calibration is not None):
        warn("recommend", ("the policy was trained " + ("without a calibration, and --calibration "
                           "is given" if calibration else "with a calibration, and none is given")
                           + ": it observes this unit's uncertainty unlike in training; its "
                           "proposal is verified as given",), said)
    # the unit as the policy observes it (calibration applied), against the units it was
    # trained on: about the calibration's friction only if it was trained with one
    observed = calibration.apply(load) if calibration is not None else load
    trained_on = base_friction(calibration if meta.get("calibrated", False) else None)
    unseen = outside(observed, trained_on)
    if unseen:
        warn("recommend", ("this unit lies outside the random units the policy was trained on ("
                           + "; ".join(unseen) + "): its proposal is an extrapolation, verified "
                           "as given",), said)
    wrap = propose(proposer.model, load, problem.settings.web.material_key,
                   problem.settings.target_g, calibration)
    if problem.settings.ordered_tensions:   # the proposal as the search would lay its vector
        wrap = problem.wrap(np.asarray(problem.vector(wrap)))
    check = verify(problem, wrap, samples, workers=workers)
    mass = wrap.material_used_on(problem.layout).mass_kg
    margin = min(run.verdict.margin for run in check.runs.values())
    best = Evaluation((), wrap, mass, wrap.cycle_time_s, (margin,), (check.passed,), 0.0)
    return best, check


def _refused_proposal(problem: Problem, best: Evaluation, check: Verification) -> str:
    """Why a policy's proposal is not recommended ("": it is). As a search's answer, it must
    pass the nominal sequence and every sample of its verification, within the cycle-time
    limit (a search keeps that by never simulating a slower candidate)."""
    limit = problem.settings.max_cycle_s
    if best.cycle_s > limit:
        return f"takes {best.cycle_s:.0f} s, over the cycle-time limit of {limit:g} s"
    if not check.passed:
        return "fails"
    if check.probability.passed < check.probability.samples:
        return (f"passes only {check.probability.passed} of {check.probability.samples} "
                f"samples")
    return ""


def _margins_text(goal: float, best: Evaluation, check: Verification, margin_of: str) -> str:
    """The margins behind an answer, told apart: the worst of these samples' (which only had
    to pass), the one it was chosen by (`margin_of`: the search's own samples', or a
    proposal's nominal run) and the one asked."""
    worst = "" if check.worst is None else f"margin {check.worst.margin:.2f} in the worst sample, "
    return f"{worst}{best.margin:.2f} {margin_of}; {goal:.2f} asked"


def _print_recommendation(problem: Problem, best: Evaluation, check: Verification,
                          recommended: bool = True, margin_of: str = "in the search's"
                          ) -> None:
    s, p = problem.settings, check.probability
    low, high = p.interval
    head = "recommended wrapping program" if recommended else "the policy's proposal"
    print(f"{head} for {printable(problem.load.name)}: "
          f"{'passes' if check.passed else 'fails'} {_targets_text(s)}, "
          f"{s.hours_since_wrapping:g} h after wrapping, in {p.passed} of {p.samples} samples "
          f"of what the bench does not know (pass probability {p.estimate:.0%}, 95 % interval "
          f"{low:.0%}-{high:.0%}; {_margins_text(s.margin_goal, best, check, margin_of)})")
    print(program_text(best.wrap, problem.layout))
    for orientation, run in check.runs.items():
        print(f"-- {orientation} side along the motion --")
        print(verdict_table(problem.load, run, orientation))
    if check.worst is not None:
        w = check.worst
        print(f"worst sample: {w.orientation} side, margin {w.margin:.2f}, "
              f"{sample_figures(w.level)}")


def _write_outputs(args: argparse.Namespace, problem: Problem, best: Evaluation,
                   check: Verification, evaluations: int, state: SearchState | None,
                   said: list[str], round_: Round = FIRST_ROUND) -> None:
    """The report first (the slowest to make; nothing of it shows until it is whole), then
    --json and --wrap-out together: an interrupt leaves the report at most. `round_`: the
    search round that answered (`evaluations` counts every round's simulations)."""
    candidates = None if state is None else round_.earlier_candidates + len(state.history)
    page = (_write_report(args, problem, check, best, state, candidates, said) if args.report
            else None)
    files = {}
    if args.json:
        weakest = check.runs[check.weakest]
        out = {**wrap_json(problem.simulated(best.wrap), best.wrap, problem.layout,
                           problem.settings.hours_since_wrapping),
               "program": best.wrap.to_json().get("program"),
               "verdict": {**weakest.verdict.to_json(), "orientation": check.weakest},
               "orientations": {o: run.verdict.to_json() for o, run in check.runs.items()},
               "targets": {o: g for o, g in problem.settings.targets},
               "hours_since_wrapping": problem.settings.hours_since_wrapping,
               "robust_pass_rate": check.probability.estimate,
               "pass_probability": check.probability.to_json(),
               "worst_sample": asdict(check.worst) if check.worst is not None else None,
               "robust_samples": check.probability.samples, "search_margin": best.margin,
               "evaluations": evaluations, "candidates": candidates,
               **({} if state is None else {"rounds": round_.number,
                                            "search_samples": problem.settings.samples}),
               "method": args.method, "target_g": problem.settings.target_g,
               **({} if args.calibration is None else {"calibration": str(args.calibration)})}
        files[Path(args.json)] = result_json(out)
    if args.wrap_out:
        files[Path(args.wrap_out)] = best.wrap.to_toml().encode()
    write_together(files)
    say_written(page, *files)


def _write_report(args: argparse.Namespace, problem: Problem, check: Verification,
                  best: Evaluation, state: SearchState | None, candidates: int | None,
                  said: list[str]) -> Path:
    """report.html and its files (state None: a policy's proposal, no search; `candidates`:
    tried in every round); returns the page."""
    given = {"load unit": args.load, "calibration": args.calibration, "policy": args.policy}
    return write_report(args.report, lambda stage: recommend_page(
        stage, problem, check, best, state, given, tuple(said), candidates))
