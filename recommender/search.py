"""Robust CMA-ES search for the wrapping program with the least web that passes EUMOS 40509.

A candidate is a program of `wrapenv.design.ProgramSpace`: whole numbers of bottom, top and
reinforcement wraps (integer variables: pycma rounds them in `ask` and keeps their spread from
collapsing below one wrap, its integer handling), a spiral overlap, a reinforcement height and
four tensions. It counts as passing only if it passes the target level of every orientation
searched (long and short side along the motion, each with its target) in each of K samples of
the uncertain parameters (`wrapenv.uncertainty`: friction, masses, the web's stiffness and
tension, its relaxation since wrapping). The settings, the problem and its objective (web laid,
margin shortfall, cycle time) are in `recommender.problem`. A blown-up simulation is a failure.

A candidate heavier than a confirmed pass that meets the margin goal cannot become the answer,
whatever it would score: it is not simulated, and CMA-ES is told the objective it would have if
it passed with the margin goal (its web, a lower bound of its objective). After the first
generations most candidates are heavier than the incumbent; this keeps the simulations for the
candidates that could still win (benchmarks/bench_recommend.py).

Multi-fidelity: candidates are screened with `SimSettings.screening()` (a level ends at its
first rest in the deceleration or once it has failed), which agrees with the default settings on
every verdict and within 0.002 of margin in benchmarks/bench_screening.py, in the first
`screen_samples` of the K samples. A screened pass can only become the answer once confirmed
with the default settings in all K samples: the lightest screened passes that would replace the
incumbent are confirmed in rank order until one holds; one that fails its confirmation is
recorded as failed. Only confirmed passes rank (`SearchState.ranked`). A sample's orientations
run as tasks of their own, side by side.

The loop is pycma's ask/tell, one generation at a time; samples run in parallel (worker
processes, or Ray tasks: `recommender.parallel`). After every generation the search is
checkpointed as data (`recommender.checkpoint`): what was asked, what it scored and with which
fidelity. A resumed search replays those generations into a new CMA-ES with the same seed (no
simulation), which reproduces its state exactly, and refuses a checkpoint of another problem.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from concurrent.futures import Executor, Future, as_completed
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import cma
import numpy as np

from recommender import checkpoint
from recommender.checkpoint import FIRST_ROUND, Round
from recommender.parallel import executor, stop
from recommender.problem import Problem, SearchSettings
from wrapenv.bench import BenchRun, SimSettings, run_levels
from wrapenv.config import InputError
from wrapenv.design import (
    INTEGER_INDICES,
    MAX_REINFORCEMENT_WRAPS,
    MAX_WRAPS,
    MIN_BOTTOM_WRAPS,
    MIN_TOP_WRAPS,
    N_PARAMS,
    TENSION_INDICES,
)
from wrapenv.load import Orientation
from wrapenv.profile import eumos_levels
from wrapenv.uncertainty import PassProbability
from wrapenv.wrap import WrapFormat

#: Where the search starts (ProgramSpace values, continuous ones as fractions of their range):
#: 2 bottom wraps, 1 top wrap, no reinforcement, a spiral at 25 % overlap, tensions mid-range.
LIGHT_START = (2.0, 1.0, 0.0, 1 / 3, 0.5, 0.5, 0.5, 0.5, 0.5)
#: Also tried in the first generation (injected into CMA-ES): the least web of the space, one
#: bottom wrap, a spiral with no overlap and one top wrap, at the top, middle and bottom of the
#: tension range. Once one passes with the margin goal every heavier candidate is dominated, and
#: among them the rank's tension price picks the gentlest that does (CMA-ES's own samples hardly
#: ever land on an overlap of exactly 0, so they would not offer it; benchmarks/tension_cap.py
#: found the margin flat in tension on the examples).
TIGHT_PROGRAMS = tuple((float(MIN_BOTTOM_WRAPS), float(MIN_TOP_WRAPS), 0.0, 0.0, 0.0) + (t,) * 4
                       for t in (1.0, 0.5, 0.0))
#: Where a round starts that follows one with no pass at all: the most web the space lays (every
#: wrap, the spiral at its largest overlap, the reinforcement halfway up its range), every
#: tension at the top. A round's screened failures all score about the same (a level stops
#: once it has failed, at a margin of about -1), so among them CMA-ES only sees that the lighter
#: costs less, and a search with no pass drifts light, away from where the passes are: on the 6
#: of 12 held-out film units whose first round found none, the strongest program held 8 of 8
#: verification samples on 3 (a round from it answers all 3), 7 of 8 on 2 and 3 of 8 on one
#: (2026-11-28, docs/recommend.md). A round from it searches lighter, weaker programs, so it
#: starts only once this program has held its verification (`recommender.recommend`).
STRONGEST_PROGRAM = (float(MAX_WRAPS), float(MAX_WRAPS), float(MAX_REINFORCEMENT_WRAPS), 1.0,
                     0.5, 1.0, 1.0, 1.0, 1.0)
#: Initial spread per coordinate, times `sigma0`: wraps by whole revolutions, the rest by a
#: share of its range.
COORDINATE_STDS = (5.0, 5.0, 3.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0)
#: How an evaluation was judged: screened (cheap), the default settings, or not simulated
#: because a confirmed pass that meets the margin goal is lighter (it cannot be the answer).
SCREENING, DEFAULT, DOMINATED = "screening", "default", "dominated"
FIDELITIES = (SCREENING, DEFAULT, DOMINATED)


@dataclass(frozen=True)
class Evaluation:
    """One candidate tried in K samples (none when it broke the cycle-time limit)."""

    vector: tuple[float, ...]
    wrap: WrapFormat
    mass_kg: float
    cycle_s: float
    margins: tuple[float, ...]
    passed: tuple[bool, ...]
    objective: float
    fidelity: str = DEFAULT  # one of FIDELITIES

    @property
    def robust_pass(self) -> bool:
        return bool(self.passed) and all(self.passed)

    @property
    def margin(self) -> float:
        return min(self.margins, default=-1.0)

    def rank(self, margin_goal: float) -> tuple[bool, float, float, float]:
        """Sort key among passes: meeting the margin goal first, then by material, then by
        objective (among programs laying the same web, e.g. one spiral at several tensions, the
        lower tension and shorter cycle its price asks for; short of the goal, the larger
        margin), then by largest margin."""
        return (self.margin < margin_goal, self.mass_kg, self.objective, -self.margin)


@dataclass
class SearchState:
    """Everything a resumed search needs: the optimiser and every generation's scores."""

    es: cma.CMAEvolutionStrategy
    history: list[Evaluation] = field(default_factory=list)
    generation: int = 0
    stale_generations: int = 0
    #: Levels simulated so far (screening, confirmations).
    simulations: int = 0

    def finished(self, settings: SearchSettings) -> bool:
        """Done when CMA-ES stops, when another generation would try more candidates than
        the budget, or after `patience` generations without a lighter robust pass (counted
        once there is one)."""
        return bool(self.es.stop()
                    or len(self.history) + self.es.popsize > settings.max_candidates
                    or self.stale_generations >= settings.patience)

    def ranked(self, margin_goal: float) -> list[Evaluation]:
        """Robust passes confirmed at the default fidelity, by `Evaluation.rank`."""
        passing = [e for e in self.history if e.robust_pass and e.fidelity == DEFAULT]
        return sorted(passing, key=lambda e: e.rank(margin_goal))

    def best(self, margin_goal: float) -> Evaluation | None:
        ranked = self.ranked(margin_goal)
        return ranked[0] if ranked else None

    def to_verify(self, margin_goal: float) -> list[Evaluation]:
        """Passes an answer is verified from, best first: the confirmed ones, then the screened
        passes never confirmed (they ranked after a confirmed pass; a verification runs the
        default fidelity on more samples than a confirmation does). On the bundled example
        the confirmed 80 N program held in the search's 3 samples and 5 of its 8; the 440 N
        program, screened at a margin of 0.84, was the answer left unverified."""
        screened = [e for e in self.history if e.robust_pass and e.fidelity == SCREENING]
        return self.ranked(margin_goal) + sorted(screened, key=lambda e: e.rank(margin_goal))


@dataclass(frozen=True)
class Trial:
    """A program in one sample, every orientation at its target: the weakest one's figures."""

    passed: bool
    margin: float
    orientation: Orientation
    level: dict[str, Any]  # the weakest orientation's level verdict (simulate's JSON)
    sample: dict[str, Any]
    simulations: int = 1  # levels run: one per orientation


def _trial(problem: Problem, wrap: WrapFormat, seed: int, sim: SimSettings,
           orientation: Orientation, target_g: float) -> Trial:
    """A program in one sample of the uncertain parameters, one orientation at its target (in a
    worker: a sample's orientations run side by side)."""
    sample = problem.sample(seed)
    verdict = run_levels(sample.load(problem.load), [target_g], sim, orientation=orientation,
                         wrap=sample.wrap(wrap), limits=problem.settings.limits).verdict
    return Trial(verdict.passed, verdict.margin, orientation, verdict.levels[-1].to_json(),
                 sample.to_json())


def _submit_sample(pool: Executor, problem: Problem, wrap: WrapFormat, seed: int,
                   sim: SimSettings) -> list[Future[Trial]]:
    """Every orientation of one sample, as tasks of the pool."""
    return [pool.submit(_trial, problem, wrap, seed, sim, orientation, target)
            for orientation, target in problem.settings.targets]


def weakest(trials: list[Trial], stop_when_decided: bool = False) -> Trial:
    """A sample's orientations (in the order of the targets) as one trial: passed if every one
    passed, with the figures of the one with the smallest margin. With `stop_when_decided` the
    sample is judged as if it had ended at its first failing orientation (the margin of a level
    stopped once decided is a bound; the later orientations' bounds are not told), as when the
    orientations ran one after the other."""
    failed = next((i for i, t in enumerate(trials) if not t.passed), len(trials))
    told = trials[:failed + 1] if stop_when_decided else trials
    worst = min(told, key=lambda t: t.margin)
    return replace(worst, passed=all(t.passed for t in trials), simulations=len(trials))


#: Called after each generation with the candidates tried so far and the state.
Progress = Callable[[int, SearchState], None]


class RobustSearch:
    """CMA-ES over programs; `run()` returns the final state (see `SearchState.best`)."""

    def __init__(self, problem: Problem, checkpoint: Path | None = None,
                 round_: Round = FIRST_ROUND) -> None:
        """`round_`: the search round this is (its problem is `Problem.in_round`'s), written
        into the checkpoint with what the rounds before it spent."""
        self.problem, self.checkpoint, self.round = problem, checkpoint, round_
        #: Every generation as data: what was asked ("x") and how each candidate scored.
        self._generations: list[dict[str, Any]] = []
        self._simulations = 0  # levels simulated in the generation under way

    def _strategy(self, x0: np.ndarray) -> cma.CMAEvolutionStrategy:
        s = self.problem.settings
        lo, hi = self.problem.space.low, self.problem.space.high
        lower = [float(lo[i]) if i in INTEGER_INDICES else 0.0 for i in range(N_PARAMS)]
        upper = [float(hi[i]) if i in INTEGER_INDICES else 1.0 for i in range(N_PARAMS)]
        return cma.CMAEvolutionStrategy(x0, s.sigma0, {
            "bounds": [lower, upper], "popsize": s.popsize, "seed": s.seed + 1,
            "verbose": -9, "maxfevals": s.max_candidates, "CMA_stds": list(COORDINATE_STDS),
            "integer_variables": list(INTEGER_INDICES),
        })

    def start(self) -> SearchState:
        """A new search. The first round starts from `LIGHT_START` (the light side, where the
        cheapest safe program usually is) and its first generation also tries `TIGHT_PROGRAMS`;
        a later round starts from the program its round was given (`next_start`), which its
        first generation tries, with the lightest program (its tensions are all at the top:
        `SearchSettings.in_round`)."""
        self._generations, self._simulations = [], 0
        x0 = self.round.start
        tried = TIGHT_PROGRAMS if x0 is None else (x0, TIGHT_PROGRAMS[0])
        es = self._strategy(np.array(LIGHT_START if x0 is None else x0, float))
        es.inject([es.gp.geno(np.array(x, float), from_bounds=es.boundary_handler.inverse)
                   for x in tried], force=True)
        return SearchState(es)

    def resume(self) -> SearchState:
        """The search of the checkpoint, replayed; refused if it is another problem's."""
        generations = checkpoint.load(self.checkpoint, self._identity())
        state = self.start()
        try:
            for generation in generations:
                self._replay(state, generation)
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(str(self.checkpoint), "generations",
                             f"cannot be replayed ({exc})") from None
        return state

    def _identity(self) -> dict[str, Any]:
        p = self.problem
        u = p.uncertainty
        return {"load": json.loads(json.dumps(p.load.to_dict())), **p.settings.identity(),
                "stiffness_scale": [u.stiffness_scale, u.stiffness_scale_std],
                "tension_scale": [u.tension_scale, u.tension_scale_std],
                "friction_std": {k: list(v) for k, v in u.friction_std.items()},
                "give_std": u.give_std}

    def _replay(self, state: SearchState, generation: dict[str, Any]) -> None:
        """A checkpointed generation told again: its programs rebuilt, nothing simulated."""
        asked = np.array(state.es.ask(), float)
        xs = np.array(generation["x"], float)
        if asked.shape != xs.shape or not np.allclose(asked, xs, rtol=0, atol=1e-9):
            raise ValueError("its candidates are not what this version of the search asks")
        if not set(generation["fidelity"]) <= set(FIDELITIES):
            raise ValueError(f"a fidelity is none of {', '.join(FIDELITIES)}")
        evaluations = [
            self._evaluation(x, [float(m) for m in margins], [bool(p) for p in passed],
                             str(fidelity), float(objective))
            for x, margins, passed, objective, fidelity in zip(
                asked, generation["margins"], generation["passed"], generation["objective"],
                generation["fidelity"], strict=True)]
        self._simulations = int(generation["simulations"])
        self._record(state, asked, evaluations)

    def _evaluation(self, x: np.ndarray, margins: list[float], passed: list[bool],
                    fidelity: str, objective: float | None = None) -> Evaluation:
        problem = self.problem
        wrap = problem.wrap(x)
        mass = wrap.material_used_on(problem.layout).mass_kg
        if objective is None:
            slow = problem.too_slow(wrap)
            objective = (slow if slow is not None
                         else problem.objective(wrap, mass, margins, passed))
        return Evaluation(tuple(float(v) for v in x), wrap, mass, wrap.cycle_time_s,
                          tuple(margins), tuple(passed), objective, fidelity)

    def run(self, state: SearchState, progress: Progress | None = None) -> SearchState:
        s = self.problem.settings
        with executor(s.backend, s.workers, s.ray_address) as pool:
            while not state.finished(s):
                self._generation(state, pool)
                self.save()
                if progress is not None:
                    progress(len(state.history), state)
        return state

    def save(self) -> None:
        """Checkpoint the generations told so far (a round's first save holds none: resumed,
        the round starts again rather than the one before it)."""
        checkpoint.save(self.checkpoint, self._identity(), self._generations, self.round)

    def _generation(self, state: SearchState, pool: Executor) -> None:
        """Ask; screen (or simulate at the default fidelity without screening) and confirm
        the candidates that could still win; tell."""
        s = self.problem.settings
        xs = np.array(state.es.ask(), float)
        seeds = [s.seed * 1_000_003 + state.generation * 1009 + k for k in range(s.samples)]
        incumbent = state.best(s.margin_goal)
        evaluations = [self._dominated(x, incumbent) for x in xs]
        open_ = [i for i, e in enumerate(evaluations) if e is None]
        if s.screen is None:
            judged = self._simulate(pool, xs[open_], seeds, s.sim, DEFAULT)
        else:
            screened = self._simulate(pool, xs[open_], seeds[:s.screen_samples], s.screen,
                                      SCREENING)
            judged = self._confirm(state, pool, xs[open_], seeds, screened)
        for i, evaluation in zip(open_, judged, strict=True):
            evaluations[i] = evaluation
        self._record(state, xs, [e for e in evaluations if e is not None])

    def _dominated(self, x: np.ndarray, incumbent: Evaluation | None) -> Evaluation | None:
        """A candidate heavier than an incumbent that meets the margin goal, scored without a
        simulation as if it passed with the margin goal; None if it could still win."""
        goal = self.problem.settings.margin_goal
        if incumbent is None or incumbent.margin < goal:
            return None
        bound = self._evaluation(x, [goal], [True], DOMINATED)
        if bound.mass_kg <= incumbent.mass_kg + 1e-9:
            return None
        return replace(bound, margins=(), passed=())

    def _simulate(self, pool: Executor, xs: np.ndarray, seeds: list[int],
                  sim: SimSettings, fidelity: str) -> list[Evaluation]:
        """Candidates in every sample at one fidelity; over the cycle limit: not simulated.
        With `sim.stop_when_decided`, in two rounds: the first sample, then the others only
        for the candidates that passed it (a failed sample has decided the candidate)."""
        problem = self.problem
        wraps = [problem.wrap(x) for x in xs]
        rounds = [seeds[:1], seeds[1:]] if sim.stop_when_decided else [seeds]
        trials: list[list[Trial]] = [[] for _ in xs]
        for round_seeds in rounds:
            futures = [[] if problem.too_slow(w) is not None or not all(t.passed for t in done)
                       else [_submit_sample(pool, problem, w, seed, sim) for seed in round_seeds]
                       for w, done in zip(wraps, trials, strict=True)]
            for done, samples in zip(trials, futures, strict=True):
                done.extend(weakest([f.result() for f in sample], sim.stop_when_decided)
                            for sample in samples)
        self._simulations += sum(t.simulations for done in trials for t in done)
        return [self._evaluation(x, [t.margin for t in done], [t.passed for t in done],
                                 fidelity) for x, done in zip(xs, trials, strict=True)]

    def _confirm(self, state: SearchState, pool: Executor, xs: np.ndarray, seeds: list[int],
                 screened: list[Evaluation]) -> list[Evaluation]:
        """The generation's screened passes that would replace the incumbent, confirmed at
        the default fidelity in the same samples, best first, until one holds that ranks before
        every screened pass left (a confirmed pass short of the margin goal ranks after a
        screened one that meets it: that one is confirmed too). A confirmation replaces the
        screened evaluation, pass or fail. Its
        failing levels run to their end: a level stopped once decided scores about -1 (the
        displacement at the stop counts as permanent), and CMA-ES learns from the graded
        margin of a full run (2-layer LLDPE: without it the search found no pass)."""
        s = self.problem.settings
        out = list(screened)
        incumbent = state.best(s.margin_goal)
        for i in sorted((i for i, e in enumerate(out) if e.robust_pass),
                        key=lambda i: out[i].rank(s.margin_goal)):
            if incumbent is not None and incumbent.rank(s.margin_goal) <= out[i].rank(
                    s.margin_goal):
                break
            out[i] = self._simulate(pool, xs[i:i + 1], seeds, s.sim, DEFAULT)[0]
            if out[i].robust_pass and (incumbent is None or out[i].rank(s.margin_goal)
                                       < incumbent.rank(s.margin_goal)):
                incumbent = out[i]
        return out

    def _record(self, state: SearchState, xs: np.ndarray, evaluations: list[Evaluation]) -> None:
        s = self.problem.settings
        before = state.best(s.margin_goal)
        values = [e.objective for e in evaluations]
        state.es.tell(list(xs), values)
        state.history.extend(evaluations)
        state.generation += 1
        state.simulations += self._simulations
        self._generations.append({"simulations": self._simulations, "x": xs.tolist(),
                                  "objective": values,
                                  "margins": [list(e.margins) for e in evaluations],
                                  "passed": [list(e.passed) for e in evaluations],
                                  "fidelity": [e.fidelity for e in evaluations]})
        self._simulations = 0
        after = state.best(s.margin_goal)
        state.stale_generations = stale_generations(before, after, state.stale_generations,
                                                    s.margin_goal)


def at_top_tension(vector: tuple[float, ...]) -> tuple[float, ...]:
    """A search vector with every tension at the top of its range: where a later round starts
    from a program (its settings lay every tension there, `SearchSettings.in_round`)."""
    x = list(vector)
    for i in TENSION_INDICES:
        x[i] = 1.0
    return tuple(x)


def next_start(state: SearchState, settings: SearchSettings) -> tuple[float, ...] | None:
    """Where the round after this search's starts (tensions at the top): from its best pass
    if it had one (its passes all failed their verification), else from `STRONGEST_PROGRAM`;
    None when no round can do better (every candidate was over the cycle-time limit)."""
    passes = state.to_verify(settings.margin_goal)
    if passes:
        return at_top_tension(passes[0].vector)
    if state.history and all(e.cycle_s > settings.max_cycle_s for e in state.history):
        return None
    return STRONGEST_PROGRAM


def stale_generations(before: Evaluation | None, after: Evaluation | None, stale: int,
                      margin_goal: float) -> int:
    """Generations in a row without a better robust pass, counted from the first pass: a
    search with none yet goes on to its budget (3-layer LLDPE searches stopped after
    `patience` generations with nothing passing). Better is lighter, or the first to meet the
    margin goal (which ranks first however heavy: counted stale, a search could end on it
    before looking for a lighter one that meets the goal too)."""
    if after is None:
        return 0
    if before is None or (after.margin < margin_goal) != (before.margin < margin_goal):
        return 0
    return 0 if after.mass_kg < before.mass_kg - 1e-9 else stale + 1


@dataclass(frozen=True)
class Verification:
    """A program run the way a lab would see it: the EUMOS sequence of every orientation on the
    nominal load, and its pass probability over fresh samples of what is not known."""

    runs: dict[Orientation, BenchRun]  # orientation -> the nominal EUMOS sequence up to its target
    probability: PassProbability
    worst: Trial | None  # the sample with the smallest margin

    @property
    def passed(self) -> bool:
        return all(run.verdict.passed for run in self.runs.values())

    @property
    def holds(self) -> bool:
        """What an answer must do: pass every nominal sequence and every sample."""
        return self.passed and self.probability.passed == self.probability.samples

    @property
    def weakest(self) -> Orientation:
        """The orientation with the smallest nominal margin."""
        return min(self.runs, key=lambda o: self.runs[o].verdict.margin)


#: The verification's samples are drawn from this seed plus the search's (`--seed`): the
#: default search keeps the samples it always had, another seed draws others.
VERIFY_SEED = 12345


def verify(problem: Problem, wrap: WrapFormat, samples: int, workers: int = 1) -> Verification:
    """The EUMOS sequence in every orientation on the nominal load (one unit through the levels,
    as a lab runs it, unless `fresh` is set), and the pass rate at the targets over `samples`
    fresh samples of the uncertain parameters. The samples stop a level
    once it has failed: a pass probability needs only the verdicts (the worst sample's figures
    are then those at its stop). The nominal sequences run in the pool
    too, after the samples."""
    s = problem.settings
    with executor(s.backend, workers, s.ray_address) as pool:
        return _verification(*_submit_verification(pool, problem, wrap, samples))


def holding(problem: Problem, wrap: WrapFormat, samples: int,
            workers: int = 1) -> Verification | None:
    """`verify` of a program that holds (every sample and nominal sequence passes); None as
    soon as one fails, its other simulations stopped (`recommender.parallel.stop`). An answer
    is the first of a search's passes that holds, and the others' figures are never shown: on
    the bundled example the first pass verified fails its third sample of 8, and ending its
    verification there takes `recommend` from 129 to 101 CPU s (benchmarks/bench_recommend.py,
    docs/speed.md)."""
    s = problem.settings
    with executor(s.backend, workers, s.ray_address) as pool:
        samples_, nominal = _submit_verification(pool, problem, wrap, samples)
        futures: list[Future[Any]] = [*(f for sample in samples_ for f in sample),
                                      *nominal.values()]
        for done in as_completed(futures):
            result = done.result()
            if not (result.passed if isinstance(result, Trial) else result.verdict.passed):
                stop(pool)
                return None
        return _verification(samples_, nominal)


def _submit_verification(pool: Executor, problem: Problem, wrap: WrapFormat, samples: int
                         ) -> tuple[list[list[Future[Trial]]], dict[Orientation, Future[BenchRun]]]:
    """A verification's simulations, as tasks of the pool: the samples (their levels stopped
    once decided), then the nominal sequences (the longest tasks, last: a sample that fails
    first saves them in `holding`)."""
    s = problem.settings
    decided = replace(s.sim, stop_when_decided=True)
    trials = [_submit_sample(pool, problem, wrap, VERIFY_SEED + s.seed + k, decided)
              for k in range(samples)]
    nominal = {orientation: pool.submit(run_levels, problem.load, eumos_levels(target), s.sim,
                                        orientation=orientation, stop_at_failure=True,
                                        wrap=problem.simulated(wrap), fresh=s.fresh,
                                        limits=s.limits)
               for orientation, target in s.targets}
    return trials, nominal


def _verification(samples: list[list[Future[Trial]]],
                  nominal: dict[Orientation, Future[BenchRun]]) -> Verification:
    trials = [weakest([f.result() for f in sample], True) for sample in samples]
    runs = {orientation: future.result() for orientation, future in nominal.items()}
    worst = min(trials, key=lambda t: t.margin, default=None)
    return Verification(runs, PassProbability(sum(t.passed for t in trials), len(trials)), worst)


__all__ = ["DEFAULT", "DOMINATED", "FIDELITIES", "SCREENING", "STRONGEST_PROGRAM",
           "Evaluation", "Problem", "RobustSearch", "SearchSettings", "SearchState", "Trial",
           "Verification", "at_top_tension", "holding", "next_start", "verify"]
