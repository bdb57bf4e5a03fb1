"""Robust CMA-ES search for the wrap format with the least material that passes EUMOS 40509.

A candidate is a vector of `wrapenv.design.FormatSpace` (layers, band heights and tensions of a
three-zone format). It counts as passing only if it passes the target level in each of K samples
of the uncertain parameters: friction of every pair drawn around its (calibrated) value with its
standard deviation, bundle masses within ±5 %. The objective (minimised) is the material mass
relative to a 3-layer full-height wrap, plus a penalty that grows with the shortfall of the worst
sample's margin below the wanted safety margin. A blown-up simulation counts as a failure.

The loop is pycma's ask/tell, one generation at a time; samples of a generation run in parallel
(worker processes, or Ray tasks on a cluster: `recommender.parallel`); after every generation
the state is checkpointed (atomically) so an interrupted search resumes where it stopped.
"""

from __future__ import annotations

import math
import os
import pickle
from collections.abc import Callable
from concurrent.futures import Executor
from dataclasses import dataclass, field, replace
from pathlib import Path

import cma
import numpy as np

from recommender.parallel import executor
from wrapenv.bench import BenchRun, SimSettings, run_levels
from wrapenv.calibrated import Calibration
from wrapenv.config import InputError, write_atomic
from wrapenv.design import FormatSpace
from wrapenv.load import PAIRS, FrictionPair, Layout, LoadUnit
from wrapenv.profile import PulseProfile, eumos_levels
from wrapenv.wrap import WrapFormat

#: Friction standard deviation assumed for a pair without calibration (CTU Code figures are
#: quoted to about ±0.03).
DEFAULT_FRICTION_STD = 0.03
MASS_SPREAD = 0.05
#: Objective penalty per unit of margin shortfall: one unit of margin outweighs the material of
#: ten full 3-layer wraps, so no failing candidate ever beats a passing one.
PENALTY_PER_MARGIN = 10.0
#: Default starting point of the search: about one layer in each band (see `start`).
LIGHT_START = np.array([-0.6, -0.6, -0.6, 0.0, 0.0, 0.0, 0.0, 0.0])
#: Objective per unit of mean tension (as a fraction of the searched range).
TENSION_PRICE = 0.05


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
    sigma0: float = 0.4
    seed: int = 0
    workers: int = max(1, os.cpu_count() or 1)
    backend: str = "process"       # "process" (this machine) or "ray"
    ray_address: str | None = None  # None: a local Ray instance; "auto" or "ray://...": a cluster
    sim: SimSettings = SimSettings()


@dataclass(frozen=True)
class Evaluation:
    """One candidate tried in K samples."""

    vector: tuple[float, ...]
    wrap: WrapFormat
    mass_kg: float
    margins: tuple[float, ...]
    passed: tuple[bool, ...]
    objective: float

    @property
    def robust_pass(self) -> bool:
        return all(self.passed)

    @property
    def margin(self) -> float:
        return min(self.margins)


@dataclass
class SearchState:
    """Everything a resumed search needs; pickled after every generation."""

    es: cma.CMAEvolutionStrategy
    history: list[Evaluation] = field(default_factory=list)
    generation: int = 0
    stale_generations: int = 0

    def finished(self, settings: SearchSettings) -> bool:
        return (self.es.stop() or len(self.history) >= settings.max_candidates
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
    space: FormatSpace
    settings: SearchSettings
    reference_mass_kg: float
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
        space = FormatSpace.for_layout(layout, settings.material)
        return cls(load, layout, std, space, settings, space.reference_mass_kg(layout), *scales)

    def wrap(self, vector: np.ndarray) -> WrapFormat:
        """The format to program into the machine (what `--wrap-out` writes)."""
        return self.space.decode(vector)

    def simulated(self, wrap: WrapFormat) -> WrapFormat:
        """The format as the calibrated bench sees it (stiffness and tension scaled)."""
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


def _trial(problem: Problem, wrap: WrapFormat, seed: int) -> tuple[bool, float]:
    """Pass and margin of a format on one sampled load at the target level (in a worker)."""
    load = problem.sample_load(seed)
    v = run_levels(load, [problem.settings.target_g], problem.settings.sim,
                   wrap=problem.simulated(wrap)).verdict
    return v.passed, v.margin


def _objective(problem: Problem, wrap: WrapFormat, mass_kg: float, margins: list[float]) -> float:
    """Material relative to a full 3-layer wrap, a penalty for the margin shortfall, and a
    small price on tension (a tie-breaker: among formats of equal material, the gentler one
    is kinder to the web at the load's corners)."""
    shortfall = max(0.0, problem.settings.margin_goal - min(margins))
    t0, t1 = problem.space.tension_range_n
    tension = np.mean([(b.tension_n - t0) / (t1 - t0) for b in wrap.bands])
    return (mass_kg / problem.reference_mass_kg + PENALTY_PER_MARGIN * shortfall
            + TENSION_PRICE * float(tension))


Progress = Callable[[int, int, SearchState], None]


class RobustSearch:
    """CMA-ES over wrap formats; `run()` returns the final state (see `SearchState.best`)."""

    def __init__(self, problem: Problem, checkpoint: Path | None = None) -> None:
        self.problem, self.checkpoint = problem, checkpoint

    def start(self, x0: np.ndarray | None = None) -> SearchState:
        """A new search from `x0` (default: one layer per band, band heights and tensions in the
        middle of their ranges: the light side, where the cheapest safe format usually is)."""
        s = self.problem.settings
        x0 = LIGHT_START if x0 is None else np.asarray(x0, float)
        es = cma.CMAEvolutionStrategy(x0, s.sigma0, {
            "bounds": [-1.0, 1.0], "popsize": s.popsize, "seed": s.seed + 1,
            "verbose": -9, "maxfevals": s.max_candidates,
        })
        return SearchState(es)

    def resume(self) -> SearchState:
        if self.checkpoint is None or not self.checkpoint.exists():
            raise InputError(str(self.checkpoint), "--resume", "no checkpoint to resume from")
        try:
            state = pickle.loads(self.checkpoint.read_bytes())
        except Exception as exc:  # a truncated or foreign file
            raise InputError(str(self.checkpoint), "", f"not a search checkpoint ({exc})") from None
        if not isinstance(state, SearchState):
            raise InputError(str(self.checkpoint), "", "not a search checkpoint")
        return state

    def run(self, state: SearchState, progress: Progress | None = None) -> SearchState:
        s = self.problem.settings
        with executor(s.backend, s.workers, s.ray_address) as pool:
            while not state.finished(s):
                self._generation(state, pool)
                if self.checkpoint is not None:
                    write_atomic(self.checkpoint, pickle.dumps(state))
                if progress is not None:
                    progress(len(state.history), s.max_candidates, state)
        return state

    def _generation(self, state: SearchState, pool: Executor) -> None:
        s, problem = self.problem.settings, self.problem
        before = state.best(s.margin_goal)
        xs = state.es.ask()
        seeds = [s.seed * 1_000_003 + state.generation * 1009 + k for k in range(s.samples)]
        wraps = [problem.wrap(x) for x in xs]
        futures = [[pool.submit(_trial, problem, w, seed) for seed in seeds] for w in wraps]
        values = []
        for x, wrap, fs in zip(xs, wraps, futures, strict=True):
            results = [f.result() for f in fs]
            passed = tuple(p for p, _ in results)
            margins = tuple(m for _, m in results)
            mass = wrap.material_used_on(problem.layout).mass_kg
            value = _objective(problem, wrap, mass, list(margins))
            state.history.append(Evaluation(tuple(float(v) for v in x), wrap, mass, margins,
                                            passed, value))
            values.append(value)
        state.es.tell(xs, values)
        state.generation += 1
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
