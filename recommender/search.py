"""Robust CMA-ES search for the wrapping program with the least web that passes EUMOS 40509.

A candidate is a program of `wrapenv.design.ProgramSpace`: whole numbers of bottom, top and
reinforcement wraps (integer variables: pycma rounds them in `ask` and keeps their spread from
collapsing below one wrap, its integer handling), a spiral overlap, a reinforcement height and
four tensions. It counts as passing only if it passes the target level of every orientation
searched (long and short side along the motion, each with its target) in each of K samples of
the uncertain parameters (`recommender.uncertainty`: friction, masses, the web's stiffness and
tension, its relaxation since wrapping). The objective (minimised) is the kg of web laid
relative to the machine's default program, plus a penalty that grows with the shortfall of the
worst sample's margin below the wanted margin, plus an optional price on cycle time; a program
slower than the cycle-time limit is rejected without a simulation. A blown-up simulation is a
failure.

The loop is pycma's ask/tell, one generation at a time; samples run in parallel (worker
processes, or Ray tasks: `recommender.parallel`). After every generation the search is
checkpointed as data (JSON): what was asked and what it scored. A resumed search replays those
generations into a new CMA-ES with the same seed (no simulation), which reproduces its state
exactly, and refuses a checkpoint of another problem.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable
from concurrent.futures import Executor
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import cma
import numpy as np

from recommender.parallel import executor
from recommender.uncertainty import TRANSPORT_HOURS, PassProbability, Sample, Uncertainty
from wrapenv.bench import BenchRun, SimSettings, run_levels
from wrapenv.calibrated import Calibration
from wrapenv.config import InputError, read_json, write_atomic
from wrapenv.design import INTEGER_INDICES, N_PARAMS, ProgramSpace
from wrapenv.eumos import EUMOS_LIMITS, Limits
from wrapenv.load import Layout, LoadUnit
from wrapenv.profile import PulseProfile, eumos_levels
from wrapenv.wrap import WrapFormat

#: Objective penalty per unit of margin shortfall (below the margin goal): a tenth of margin is
#: worth the web of one machine-default program.
PENALTY_PER_MARGIN = 10.0
#: Objective of a program slower than the cycle-time limit (plus its relative excess): worse
#: than any simulated candidate (whose margin is at worst -1 of every level), so the search
#: moves back under the limit.
SLOW_PENALTY = 2 * PENALTY_PER_MARGIN + 10.0
#: Objective per unit of mean tension (as a fraction of the searched range): a tie-breaker,
#: among programs of equal web the gentler one is kinder to the web at the load's corners.
TENSION_PRICE = 0.05
#: Where the search starts (ProgramSpace values, continuous ones as fractions of their range):
#: 2 bottom wraps, 1 top wrap, no reinforcement, a spiral at 25 % overlap, tensions mid-range.
LIGHT_START = (2.0, 1.0, 0.0, 1 / 3, 0.5, 0.5, 0.5, 0.5, 0.5)
#: Initial spread per coordinate, times `sigma0`: wraps by whole revolutions, the rest by a
#: share of its range.
COORDINATE_STDS = (5.0, 5.0, 3.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0)
CHECKPOINT_FORMAT = "wrapbench-search/1"


#: A load is only as safe as its weaker orientation: road rules ask 0.8 g forward and 0.5 g
#: sideways and rearward (EN 12195-1); the default searches both sides at 0.5 g.
BOTH_SIDES = (("long", 0.5), ("short", 0.5))


@dataclass(frozen=True)
class SearchSettings:
    #: (orientation, target level in g) pairs every candidate must pass.
    targets: tuple[tuple[str, float], ...] = BOTH_SIDES
    material: str = "kraft"
    samples: int = 3               # K robust samples per candidate
    margin_goal: float = 0.2       # wanted margin of the worst sample (0.2: 80 % of each limit)
    popsize: int = 8
    max_candidates: int = 48
    #: Stop after this many generations without a lighter robust pass.
    patience: int = 3
    sigma0: float = 0.3
    seed: int = 0
    workers: int = max(1, os.cpu_count() or 1)
    backend: str = "process"       # "process" (this machine) or "ray"
    ray_address: str | None = None  # None: a local Ray instance; "auto" or "ray://...": a cluster
    max_cycle_s: float = math.inf  # programs slower than this are rejected
    cycle_weight: float = 0.0      # objective per second of cycle, in reference masses
    hours_since_wrapping: float = TRANSPORT_HOURS
    sim: SimSettings = SimSettings()
    #: The criteria a level is judged by (EUMOS 40509's, optionally a layer-shift limit).
    limits: Limits = EUMOS_LIMITS
    #: Verify on a fresh unit per level instead of one unit through the sequence, as a lab.
    fresh: bool = False

    @property
    def target_g(self) -> float:
        """The highest target of any orientation."""
        return max(g for _, g in self.targets)

    def identity(self) -> dict[str, Any]:
        """What makes two searches the same search (a checkpoint must match it)."""
        return {"targets": [list(t) for t in self.targets], "material": self.material,
                "hours_since_wrapping": self.hours_since_wrapping, "samples": self.samples,
                "margin_goal": self.margin_goal, "popsize": self.popsize,
                "sigma0": self.sigma0, "seed": self.seed, "max_cycle_s": _json_float(
                    self.max_cycle_s), "cycle_weight": self.cycle_weight,
                **({} if self.limits.layer_shift_fraction is None else
                   {"layer_shift_limit": self.limits.layer_shift_fraction})}


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

    @property
    def robust_pass(self) -> bool:
        return bool(self.passed) and all(self.passed)

    @property
    def margin(self) -> float:
        return min(self.margins, default=-1.0)


@dataclass
class SearchState:
    """Everything a resumed search needs: the optimiser and every generation's scores."""

    es: cma.CMAEvolutionStrategy
    history: list[Evaluation] = field(default_factory=list)
    generation: int = 0
    stale_generations: int = 0

    def finished(self, settings: SearchSettings) -> bool:
        """Done when CMA-ES stops, when another generation would try more candidates than
        the budget, or after `patience` generations without a lighter robust pass."""
        return bool(self.es.stop()
                    or len(self.history) + self.es.popsize > settings.max_candidates
                    or self.stale_generations >= settings.patience)

    def ranked(self, margin_goal: float) -> list[Evaluation]:
        """Robust passes, those meeting the margin goal first, each group by material (then
        largest margin)."""
        passing = [e for e in self.history if e.robust_pass]
        return sorted(passing, key=lambda e: (e.margin < margin_goal, e.mass_kg, -e.margin))

    def best(self, margin_goal: float) -> Evaluation | None:
        ranked = self.ranked(margin_goal)
        return ranked[0] if ranked else None


@dataclass(frozen=True)
class Problem:
    """What the workers need: picklable, no Bullet state."""

    load: LoadUnit
    layout: Layout
    uncertainty: Uncertainty
    space: ProgramSpace
    settings: SearchSettings
    reference_mass_kg: float
    #: Web of the heaviest program of the space, in reference masses.
    heaviest_ratio: float

    @classmethod
    def build(cls, load: LoadUnit, settings: SearchSettings,
              calibration: Calibration | None = None) -> Problem:
        if calibration is not None:
            load = calibration.apply(load)
        for _, target in settings.targets:
            PulseProfile(target)  # validates every target against the bench
        layout = load.layout()
        space = ProgramSpace.for_layout(layout, settings.material)
        reference = space.reference_mass_kg(layout)
        heaviest = space.wrap(space.high).material_used_on(layout).mass_kg / reference
        uncertainty = Uncertainty.of(calibration, settings.hours_since_wrapping)
        return cls(load, layout, uncertainty, space, settings, reference, heaviest)

    def values(self, x: np.ndarray) -> np.ndarray:
        """ProgramSpace values of a search vector: wraps as they are, the continuous
        coordinates from fractions of their range."""
        lo, hi = self.space.low, self.space.high
        v = lo + np.asarray(x, float) * (hi - lo)
        v[list(INTEGER_INDICES)] = np.asarray(x, float)[list(INTEGER_INDICES)]
        return v

    def wrap(self, x: np.ndarray) -> WrapFormat:
        """The program to enter into the machine (what `--wrap-out` writes)."""
        return self.space.wrap(self.values(x))

    def simulated(self, wrap: WrapFormat) -> WrapFormat:
        """The wrap as the (calibrated) bench sees it at the nominal values: stiffness and
        tension scaled, tension relaxed for the hours since wrapping."""
        return self.uncertainty.nominal(wrap)

    def sample(self, seed: int) -> Sample:
        """The uncertain parameters drawn for one seed."""
        return self.uncertainty.draw(self.load, seed)

    def sample_load(self, seed: int) -> LoadUnit:
        """The load with friction and masses drawn within their uncertainty."""
        return self.sample(seed).load(self.load)

    def objective(self, wrap: WrapFormat, mass_kg: float, margins: list[float],
                  passed: list[bool]) -> float:
        """Web relative to the machine's default program, a penalty for the margin shortfall,
        a price on cycle time (if asked) and on tension (a tie-breaker). A failure in any
        sample also pays the web of the heaviest program of the space, so it never scores
        better than a pass."""
        s = self.settings
        shortfall = max(0.0, s.margin_goal - min(margins))
        t0, t1 = self.space.tension_range_n
        tension = np.mean([(p.tension_n - t0) / (t1 - t0) for p in wrap.passes])
        failed = 0.0 if all(passed) else self.heaviest_ratio
        return (mass_kg / self.reference_mass_kg + PENALTY_PER_MARGIN * shortfall + failed
                + s.cycle_weight * wrap.cycle_time_s + TENSION_PRICE * float(tension))

    def too_slow(self, wrap: WrapFormat) -> float | None:
        """The objective of a program over the cycle-time limit, None if within it."""
        limit = self.settings.max_cycle_s
        cycle = wrap.cycle_time_s
        return None if cycle <= limit else SLOW_PENALTY * (1 + (cycle - limit) / limit)


@dataclass(frozen=True)
class Trial:
    """A program in one sample, every orientation at its target: the weakest one's figures."""

    passed: bool
    margin: float
    orientation: str
    level: dict[str, Any]  # the weakest orientation's level verdict (simulate's JSON)
    sample: dict[str, Any]


def _trial(problem: Problem, wrap: WrapFormat, seed: int) -> Trial:
    """A program in one sample of the uncertain parameters (in a worker)."""
    sample = problem.sample(seed)
    load, laid = sample.load(problem.load), sample.wrap(wrap)
    weakest: Trial | None = None
    passed = True
    for orientation, target in problem.settings.targets:
        verdict = run_levels(load, [target], problem.settings.sim, orientation=orientation,
                             wrap=laid, limits=problem.settings.limits).verdict
        passed &= verdict.passed
        if weakest is None or verdict.margin < weakest.margin:
            weakest = Trial(verdict.passed, verdict.margin, orientation,
                            verdict.levels[-1].to_json(), sample.to_json())
    assert weakest is not None
    return replace(weakest, passed=passed)


Progress = Callable[[int, int, SearchState], None]


class RobustSearch:
    """CMA-ES over programs; `run()` returns the final state (see `SearchState.best`)."""

    def __init__(self, problem: Problem, checkpoint: Path | None = None) -> None:
        self.problem, self.checkpoint = problem, checkpoint
        #: Every generation as data: what was asked ("x") and how each candidate scored.
        self._generations: list[dict[str, list[Any]]] = []

    def _strategy(self, x0: np.ndarray) -> cma.CMAEvolutionStrategy:
        s = self.problem.settings
        hi = self.problem.space.high
        upper = [float(hi[i]) if i in INTEGER_INDICES else 1.0 for i in range(N_PARAMS)]
        return cma.CMAEvolutionStrategy(x0, s.sigma0, {
            "bounds": [[0.0] * N_PARAMS, upper], "popsize": s.popsize, "seed": s.seed + 1,
            "verbose": -9, "maxfevals": s.max_candidates, "CMA_stds": list(COORDINATE_STDS),
            "integer_variables": list(INTEGER_INDICES),
        })

    def start(self, x0: np.ndarray | None = None) -> SearchState:
        """A new search from `x0` (default `LIGHT_START`: the light side, where the cheapest
        safe program usually is)."""
        self._generations = []
        return SearchState(self._strategy(np.array(LIGHT_START if x0 is None else x0, float)))

    def resume(self) -> SearchState:
        """The search of the checkpoint, replayed; refused if it is another problem's."""
        path = self.checkpoint
        if path is None or not path.exists():
            raise InputError(str(path), "resume", "no checkpoint to resume from")
        data = read_json(path)
        if data.get("format") != CHECKPOINT_FORMAT:
            raise InputError(str(path), "format", "not a wrapbench search checkpoint")
        mine = self._identity()
        for key, value in mine.items():
            if data.get("problem", {}).get(key) != value:
                raise InputError(str(path), f"problem.{key}", "the checkpoint is of another "
                                 "search (load, material, target or seed differ)")
        state = self.start()
        try:
            for generation in data["generations"]:
                self._replay(state, generation)
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(str(path), "generations", f"cannot be replayed ({exc})") from None
        return state

    def _identity(self) -> dict[str, Any]:
        p = self.problem
        u = p.uncertainty
        return {"load": json.loads(json.dumps(p.load.to_dict())), **p.settings.identity(),
                "stiffness_scale": [u.stiffness_scale, u.stiffness_scale_std],
                "tension_scale": [u.tension_scale, u.tension_scale_std],
                "friction_std": {k: list(v) for k, v in u.friction_std.items()}}

    def _replay(self, state: SearchState, generation: dict[str, list[Any]]) -> None:
        """A checkpointed generation told again: its programs rebuilt, nothing simulated."""
        asked = np.array(state.es.ask(), float)
        xs = np.array(generation["x"], float)
        if asked.shape != xs.shape or not np.allclose(asked, xs, rtol=0, atol=1e-9):
            raise ValueError("its candidates are not what this version of the search asks")
        evaluations = [
            self._evaluation(x, [float(m) for m in margins], [bool(p) for p in passed],
                             float(objective))
            for x, margins, passed, objective in zip(
                asked, generation["margins"], generation["passed"], generation["objective"],
                strict=True)]
        self._record(state, asked, evaluations)

    def _evaluation(self, x: np.ndarray, margins: list[float], passed: list[bool],
                    objective: float | None = None) -> Evaluation:
        problem = self.problem
        wrap = problem.wrap(x)
        mass = wrap.material_used_on(problem.layout).mass_kg
        if objective is None:
            slow = problem.too_slow(wrap)
            objective = (slow if slow is not None
                         else problem.objective(wrap, mass, margins, passed))
        return Evaluation(tuple(float(v) for v in x), wrap, mass, wrap.cycle_time_s,
                          tuple(margins), tuple(passed), objective)

    def run(self, state: SearchState, progress: Progress | None = None) -> SearchState:
        s = self.problem.settings
        with executor(s.backend, s.workers, s.ray_address) as pool:
            while not state.finished(s):
                self._generation(state, pool)
                self._save()
                if progress is not None:
                    progress(len(state.history), s.max_candidates, state)
        return state

    def _save(self) -> None:
        if self.checkpoint is None:
            return
        data = {"format": CHECKPOINT_FORMAT, "problem": self._identity(),
                "generations": self._generations}
        write_atomic(self.checkpoint, (json.dumps(data) + "\n").encode())

    def _generation(self, state: SearchState, pool: Executor) -> None:
        s, problem = self.problem.settings, self.problem
        xs = np.array(state.es.ask(), float)
        seeds = [s.seed * 1_000_003 + state.generation * 1009 + k for k in range(s.samples)]
        wraps = [problem.wrap(x) for x in xs]
        futures = [[] if problem.too_slow(w) is not None else
                   [pool.submit(_trial, problem, w, seed) for seed in seeds] for w in wraps]
        evaluations = []
        for x, fs in zip(xs, futures, strict=True):
            trials = [f.result() for f in fs]
            evaluations.append(self._evaluation(x, [t.margin for t in trials],
                                                [t.passed for t in trials]))
        self._record(state, xs, evaluations)

    def _record(self, state: SearchState, xs: np.ndarray, evaluations: list[Evaluation]) -> None:
        s = self.problem.settings
        before = state.best(s.margin_goal)
        values = [e.objective for e in evaluations]
        state.es.tell(list(xs), values)
        state.history.extend(evaluations)
        state.generation += 1
        self._generations.append({"x": xs.tolist(), "objective": values,
                                  "margins": [list(e.margins) for e in evaluations],
                                  "passed": [list(e.passed) for e in evaluations]})
        after = state.best(s.margin_goal)
        improved = after is not None and (before is None or after.mass_kg < before.mass_kg - 1e-9)
        state.stale_generations = 0 if improved else state.stale_generations + 1


@dataclass(frozen=True)
class Verification:
    """A program run the way a lab would see it: the EUMOS sequence of every orientation on the
    nominal load, and its pass probability over fresh samples of what is not known."""

    runs: dict[str, BenchRun]  # orientation -> the nominal EUMOS sequence up to its target
    probability: PassProbability
    worst: Trial | None  # the sample with the smallest margin

    @property
    def passed(self) -> bool:
        return all(run.verdict.passed for run in self.runs.values())

    @property
    def weakest(self) -> str:
        """The orientation with the smallest nominal margin."""
        return min(self.runs, key=lambda o: self.runs[o].verdict.margin)


def verify(problem: Problem, wrap: WrapFormat, samples: int, seed: int = 12345,
           workers: int = 1) -> Verification:
    """The EUMOS sequence in every orientation on the nominal load (one unit through the levels,
    as a lab runs it, unless `fresh` is set), and the pass rate at the targets over `samples`
    fresh samples of the uncertain parameters."""
    s = problem.settings
    runs = {orientation: run_levels(problem.load, eumos_levels(target), s.sim,
                                    orientation=orientation, stop_at_failure=True,
                                    wrap=problem.simulated(wrap), fresh=s.fresh,
                                    limits=s.limits)
            for orientation, target in s.targets}
    with executor(s.backend, workers, s.ray_address) as pool:
        trials = list(pool.map(_trial, [problem] * samples, [wrap] * samples,
                               [seed + k for k in range(samples)]))
    worst = min(trials, key=lambda t: t.margin, default=None)
    return Verification(runs, PassProbability(sum(t.passed for t in trials), samples), worst)


def _json_float(x: float) -> float | str:
    return x if math.isfinite(x) else "inf"


__all__ = ["Evaluation", "Problem", "RobustSearch", "SearchSettings", "SearchState", "Trial",
           "Verification", "verify"]
