"""Robust CMA-ES search for the wrapping program with the least web that passes EUMOS 40509.

A candidate is a program of `wrapenv.design.ProgramSpace`: whole numbers of bottom, top and
reinforcement wraps (integer variables: pycma rounds them in `ask` and keeps their spread from
collapsing below one wrap, its integer handling), a spiral overlap, a reinforcement height and
four tensions. It counts as passing only if it passes the target level in each of K samples of
the uncertain parameters: friction of every pair drawn around its (calibrated) value with its
standard deviation, bundle masses within ±5 %. The objective (minimised) is the kg of web laid
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
from wrapenv.bench import BenchRun, SimSettings, run_levels
from wrapenv.calibrated import Calibration
from wrapenv.config import InputError, read_json, write_atomic
from wrapenv.design import INTEGER_INDICES, N_PARAMS, ProgramSpace
from wrapenv.load import PAIRS, FrictionPair, Layout, LoadUnit
from wrapenv.profile import PulseProfile, eumos_levels
from wrapenv.wrap import WrapFormat

#: Friction standard deviation assumed for a pair without calibration (CTU Code figures are
#: quoted to about ±0.03).
DEFAULT_FRICTION_STD = 0.03
MASS_SPREAD = 0.05
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


@dataclass(frozen=True)
class SearchSettings:
    target_g: float = 0.5
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
    sim: SimSettings = SimSettings()

    def identity(self) -> dict[str, Any]:
        """What makes two searches the same search (a checkpoint must match it)."""
        return {"target_g": self.target_g, "material": self.material, "samples": self.samples,
                "margin_goal": self.margin_goal, "popsize": self.popsize,
                "sigma0": self.sigma0, "seed": self.seed, "max_cycle_s": _json_float(
                    self.max_cycle_s), "cycle_weight": self.cycle_weight}


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
        return bool(self.es.stop() or len(self.history) >= settings.max_candidates
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
    friction_std: dict[str, tuple[float, float]]  # pair -> (static std, kinetic std)
    space: ProgramSpace
    settings: SearchSettings
    reference_mass_kg: float
    #: Web of the heaviest program of the space, in reference masses.
    heaviest_ratio: float
    stiffness_scale: float = 1.0
    tension_scale: float = 1.0

    @classmethod
    def build(cls, load: LoadUnit, settings: SearchSettings,
              calibration: Calibration | None = None) -> Problem:
        std = {p: (DEFAULT_FRICTION_STD, DEFAULT_FRICTION_STD) for p in PAIRS}
        scales = (1.0, 1.0)
        if calibration is not None:
            load = calibration.apply(load)
            for name, pair in calibration.friction.items():
                std[name] = (pair.static_std or DEFAULT_FRICTION_STD,
                             pair.kinetic_std or DEFAULT_FRICTION_STD)
            scales = (calibration.stiffness_scale, calibration.tension_scale)
        PulseProfile(settings.target_g)  # validates the target against the bench
        layout = load.layout()
        space = ProgramSpace.for_layout(layout, settings.material)
        reference = space.reference_mass_kg(layout)
        heaviest = space.wrap(space.high).material_used_on(layout).mass_kg / reference
        return cls(load, layout, std, space, settings, reference, heaviest, *scales)

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
        """The wrap as the calibrated bench sees it (stiffness and tension scaled)."""
        return wrap.scaled(self.stiffness_scale, self.tension_scale)

    def sample_load(self, seed: int) -> LoadUnit:
        """The load with friction and masses drawn within their uncertainty."""
        rng = np.random.default_rng(seed)
        pairs = {}
        for name in PAIRS:
            nominal = self.load.friction.pair(name)
            s_std, k_std = self.friction_std[name]
            static = max(0.05, nominal.static + rng.normal(0, s_std))
            kinetic = min(static, max(0.04, nominal.kinetic + rng.normal(0, k_std)))
            pairs[name] = FrictionPair(static, kinetic)
        bundle = self.load.bundle
        bundle = replace(bundle, mass_kg=bundle.mass_kg * rng.uniform(1 - MASS_SPREAD,
                                                                      1 + MASS_SPREAD))
        return replace(self.load, bundle=bundle, friction=replace(self.load.friction, **pairs))

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


def _trial(problem: Problem, wrap: WrapFormat, seed: int) -> tuple[bool, float]:
    """Pass and margin of a program on one sampled load at the target level (in a worker)."""
    load = problem.sample_load(seed)
    v = run_levels(load, [problem.settings.target_g], problem.settings.sim,
                   wrap=problem.simulated(wrap)).verdict
    return v.passed, v.margin


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
        return {"load": json.loads(json.dumps(p.load.to_dict())), **p.settings.identity(),
                "stiffness_scale": p.stiffness_scale, "tension_scale": p.tension_scale,
                "friction_std": {k: list(v) for k, v in p.friction_std.items()}}

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
            results = [f.result() for f in fs]
            evaluations.append(self._evaluation(x, [m for _, m in results],
                                                [p for p, _ in results]))
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


def verify(problem: Problem, wrap: WrapFormat, samples: int, seed: int = 12345,
           workers: int = 1) -> tuple[BenchRun, float]:
    """The EUMOS sequence on the nominal load, and the pass rate at the target over `samples`
    fresh samples of the uncertain parameters."""
    run = run_levels(problem.load, eumos_levels(problem.settings.target_g), problem.settings.sim,
                     stop_at_failure=True, wrap=problem.simulated(wrap))
    s = problem.settings
    with executor(s.backend, workers, s.ray_address) as pool:
        results = list(pool.map(_trial, [problem] * samples, [wrap] * samples,
                                [seed + k for k in range(samples)]))
    rate = sum(1 for passed, _ in results if passed) / samples if samples else math.nan
    return run, rate


def _json_float(x: float) -> float | str:
    return x if math.isfinite(x) else "inf"


__all__ = ["Evaluation", "Problem", "RobustSearch", "SearchSettings", "SearchState", "verify"]
