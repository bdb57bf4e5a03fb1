"""The source paper's inverse problems: friction per contact pair, then the wrap's stiffness and
tension, fitted so that the bench replaying each recording reproduces its tracked paths.

Loss: the mean squared difference between simulated and tracked displacements (relative to the
sled, `calibration.replay`) over every object, frame and recording; its square root is the
residual RMS reported. Parameters live in a unit box: per slipping pair its static coefficient
and the ratio kinetic / static (so kinetic <= static by construction), per wrap the base-2
logarithms of the stiffness and tension scales. Two optimisers:
- CMA-ES (pycma, the default): robust to the loss's small jumps (a contact that sticks one
  step earlier), parallel over a generation;
- gradient descent with momentum as in the paper: forward finite-difference gradients,
  smoothed by an exponential moving average (the paper's EMA, since the loss is noisy),
  normalised steps of decaying length.
Uncertainty comes from the loss's curvature at the optimum (Gauss-Newton: s^2 (J^T J)^-1 from
central differences), widened by the residuals' autocorrelation (neighbouring frames are not
independent), and capped at a uniform spread over the parameter's range when the data say
nothing (e.g. a static coefficient the slip's start does not resolve). Pairs that never slipped
are held stuck and reported as not identified (`identified: false`) with the lower bound of
their static coefficient the recordings support.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor
from dataclasses import dataclass, field, replace

import cma
import numpy as np

from calibration.replay import Observation, replay, residuals
from wrapenv.bench import SimSettings
from wrapenv.calibrated import CalibratedPair, Calibration
from wrapenv.load import PAIRS, Friction, FrictionPair

METHODS = ("cmaes", "momentum")
PARAMS = ("friction", "wrap", "all")
STATIC_RANGE = (0.05, 1.2)
RATIO_RANGE = (0.5, 1.0)          # kinetic / static
LOG2_SCALE_RANGE = (-2.0, 2.0)    # wrap stiffness and tension: 1/4 to 4 times the card
#: A pair held stuck is set this far above the largest acceleration it had to transmit.
STUCK_MARGIN = 0.15
#: Loss given to a candidate whose simulation became unphysical (m^2: a 1 m residual).
INVALID_LOSS = 1.0
#: Finite-difference step in the unit box.
STEP = 0.02
#: Standard deviation of a value the data say nothing about: uniform over its whole range.
UNIFORM_STD = 1 / math.sqrt(12)
#: The momentum descent's uncertainty: the spread of its last iterates.
SPREAD_ITERATES = 8


@dataclass(frozen=True)
class FitSettings:
    method: str = "cmaes"
    params: str = "friction"
    budget: int = 240               # most simulations, gradient and uncertainty included
    workers: int = max(1, os.cpu_count() or 1)
    seed: int = 0
    #: The fit fails (no output) when the best residual RMS is above this.
    max_residual_m: float = 0.01
    sim: SimSettings = SimSettings()


@dataclass(frozen=True)
class Param:
    kind: str            # "static", "ratio", "stiffness", "tension"
    pair: str = ""
    low: float = 0.0
    high: float = 1.0

    def value(self, u: float) -> float:
        v = self.low + (self.high - self.low) * float(np.clip(u, 0.0, 1.0))
        return 2.0**v if self.kind in ("stiffness", "tension") else v

    def unit(self, value: float) -> float:
        v = math.log2(value) if self.kind in ("stiffness", "tension") else value
        return float(np.clip((v - self.low) / (self.high - self.low), 0.0, 1.0))


@dataclass(frozen=True)
class Model:
    """How a point of the unit box becomes the bench's friction and wrap scales."""

    params: tuple[Param, ...]
    base: Friction                  # values of the pairs not fitted
    scales: tuple[float, float] = (1.0, 1.0)

    def decode(self, u: np.ndarray) -> tuple[Friction, float, float]:
        values = {(p.kind, p.pair): p.value(x) for p, x in zip(self.params, u, strict=True)}
        pairs = {}
        for name in PAIRS:
            if ("static", name) in values:
                static = values["static", name]
                pairs[name] = FrictionPair(static, static * values["ratio", name])
        friction = replace(self.base, **pairs)
        stiffness = values.get(("stiffness", ""), self.scales[0])
        tension = values.get(("tension", ""), self.scales[1])
        return friction, stiffness, tension

    def encode(self, friction: Friction, scales: tuple[float, float]) -> np.ndarray:
        out = []
        for p in self.params:
            if p.kind == "static":
                out.append(p.unit(friction.pair(p.pair).static))
            elif p.kind == "ratio":
                pair = friction.pair(p.pair)
                out.append(p.unit(pair.kinetic / pair.static))
            else:
                out.append(p.unit(scales[0] if p.kind == "stiffness" else scales[1]))
        return np.array(out)


@dataclass
class Progress:
    """Loss history of a fit: (simulations so far, loss of the best point so far)."""

    simulations: int = 0
    curve: list[tuple[int, float]] = field(default_factory=list)
    #: told the simulations spent after every batch (a progress bar)
    listener: Callable[[int], None] | None = None
    best_u: np.ndarray | None = None
    best_loss: float = math.inf

    def record(self, us: Sequence[np.ndarray], losses: Sequence[float], sims: int) -> None:
        self.spend(sims)
        for u, loss in zip(us, losses, strict=True):
            if loss < self.best_loss:
                self.best_u, self.best_loss = np.array(u), loss
        self.curve.append((self.simulations, self.best_loss))

    def spend(self, sims: int) -> None:
        self.simulations += sims
        if self.listener is not None:
            self.listener(self.simulations)


def _replay_task(obs: Observation, friction: Friction, stiffness: float,
                 tension: float, sim: SimSettings) -> np.ndarray | None:
    simulated = replay(obs, friction, stiffness, tension, sim)
    return None if simulated is None else residuals(obs, simulated)


class Objective:
    """Residual vectors and losses of points of the unit box, simulated in parallel."""

    def __init__(self, observations: Sequence[Observation], model: Model, pool: Executor,
                 sim: SimSettings) -> None:
        self.observations, self.model, self.pool, self.sim = observations, model, pool, sim

    def residuals(self, us: Sequence[np.ndarray]) -> list[np.ndarray | None]:
        futures = [[self.pool.submit(_replay_task, obs, *self.model.decode(u), self.sim)
                    for obs in self.observations] for u in us]
        out: list[np.ndarray | None] = []
        for fs in futures:
            parts = [f.result() for f in fs]
            out.append(None if any(p is None for p in parts) else np.concatenate(parts))
        return out

    def losses(self, us: Sequence[np.ndarray]) -> list[float]:
        return [INVALID_LOSS if r is None else float(np.mean(r**2)) for r in self.residuals(us)]

    @property
    def sims_per_point(self) -> int:
        return len(self.observations)


def cmaes(objective: Objective, u0: np.ndarray, budget: int, seed: int,
          progress: Progress) -> np.ndarray:
    """pycma ask/tell until the budget (in simulations) or pycma's own stop; returns the final
    search distribution's standard deviations (what the search has not yet narrowed down)."""
    n = len(u0)
    popsize = 4 + int(3 * math.log(n))
    es = cma.CMAEvolutionStrategy(u0, 0.15, {"bounds": [0.0, 1.0], "popsize": popsize,
                                             "seed": seed + 1, "verbose": -9, "tolx": 2e-3})
    progress.record([u0], objective.losses([u0]), objective.sims_per_point)
    while not es.stop():
        if progress.simulations + popsize * objective.sims_per_point > budget:
            break
        us = es.ask()
        losses = objective.losses(us)
        es.tell(us, losses)
        progress.record(us, losses, len(us) * objective.sims_per_point)
    return np.asarray(es.result.stds, float)


def momentum(objective: Objective, u0: np.ndarray, budget: int, progress: Progress,
             beta: float = 0.5, step0: float = 0.05) -> np.ndarray:
    """The paper's gradient descent with momentum (EMA of forward-difference gradients);
    returns the spread (standard deviation) of the last `SPREAD_ITERATES` iterates per
    coordinate: where the descent still wanders, the loss does not tell the value apart.
    beta and step0 were chosen on the sliding-bundles recording of the tests: 0.8 / 0.08 took
    25 iterations to leave the start, 0.5 / 0.05 reached 0.4 mm residual in 48 simulations."""
    n = len(u0)
    u, velocity = np.array(u0, float), np.zeros(n)
    iterates = [u]
    k = 0
    while progress.simulations + (n + 1) * objective.sims_per_point <= budget:
        # step inwards at the upper bound so every probe stays in the box
        steps = np.where(u + STEP <= 1.0, STEP, -STEP)
        probes = [u] + [u + steps[i] * np.eye(n)[i] for i in range(n)]
        losses = objective.losses(probes)
        progress.record(probes, losses, len(probes) * objective.sims_per_point)
        grad = (np.array(losses[1:]) - losses[0]) / steps
        velocity = beta * velocity + (1 - beta) * grad
        norm = float(np.linalg.norm(velocity))
        if norm == 0.0:
            break
        u = np.clip(u - step0 / (1 + k / 8) * velocity / norm, 0.0, 1.0)
        iterates.append(u)
        k += 1
    return np.std(iterates[-SPREAD_ITERATES:], axis=0)


def _autocorrelation_time(r: np.ndarray) -> float:
    """Integrated autocorrelation time of a residual series (1 for white noise)."""
    r = r - r.mean()
    var = float(np.dot(r, r))
    if var == 0.0:
        return 1.0
    tau = 1.0
    for lag in range(1, len(r) // 4):
        rho = float(np.dot(r[:-lag], r[lag:])) / var
        if rho < 0.05:
            break
        tau += 2 * rho
    return tau


def _unit_std(objective: Objective, u: np.ndarray, r0: np.ndarray,
              progress: Progress) -> np.ndarray:
    """Standard deviations in the unit box from the Gauss-Newton curvature at u."""
    n = len(u)
    lo, hi = np.clip(u - STEP, 0, 1), np.clip(u + STEP, 0, 1)
    probes = [np.where(np.arange(n) == i, hi[i], u) for i in range(n)]
    probes += [np.where(np.arange(n) == i, lo[i], u) for i in range(n)]
    rs = objective.residuals(probes)
    progress.spend(len(probes) * objective.sims_per_point)
    if any(r is None for r in rs):
        return np.full(n, UNIFORM_STD)
    jac = np.stack([(rs[i] - rs[n + i]) / (hi[i] - lo[i]) for i in range(n)], axis=1)
    dof = max(1, len(r0) - n)
    s2 = float(np.dot(r0, r0)) / dof * _autocorrelation_time(r0)
    cov = s2 * np.linalg.pinv(jac.T @ jac)
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    flat = np.linalg.norm(jac, axis=0) < 1e-9
    return np.where(flat, UNIFORM_STD, np.minimum(std, UNIFORM_STD))


@dataclass(frozen=True)
class FitResult:
    calibration: Calibration
    residual_rms_m: float
    simulations: int
    method: str
    curve: list[tuple[int, float]]
    #: per observation: the simulated displacements of the fitted model (None: unphysical)
    fitted: list[dict[str, np.ndarray] | None]
    converged: bool


@dataclass(frozen=True)
class _Stage:
    """One inverse problem: some parameters, fitted on some of the recordings."""

    model: Model
    observations: tuple[Observation, ...]


def pairs_present(observations: Sequence[Observation]) -> tuple[str, ...]:
    """The contact pairs the recorded loads have (bundle on bundle needs two layers)."""
    layered = any(o.load.stack.layers > 1 for o in observations)
    return tuple(p for p in PAIRS if p != "bundle_bundle" or layered)


def fit(observations: Sequence[Observation], settings: FitSettings,
        listener: Callable[[int], None] | None = None) -> FitResult:
    """Fit the asked parameters to the observations (see the module docstring): friction on
    the unwrapped recordings (all of them when every one is wrapped), then the wrap's scales on
    the wrapped ones with that friction."""
    slipped = frozenset().union(*(o.slipped for o in observations))
    nominal = observations[0].load.friction
    base = _held_stuck(nominal, _pair_bounds(observations, nominal, frozenset()), slipped)
    wrapped = tuple(o for o in observations if o.wrap is not None)
    plain = tuple(o for o in observations if o.wrap is None) or tuple(observations)
    friction_params = tuple(q for name in PAIRS if name in slipped
                            for q in (Param("static", name, *STATIC_RANGE),
                                      Param("ratio", name, *RATIO_RANGE)))
    wrap_params = (Param("stiffness", "", *LOG2_SCALE_RANGE),
                   Param("tension", "", *LOG2_SCALE_RANGE))
    fit_friction = settings.params != "wrap" and bool(friction_params)
    fit_wrap = settings.params in ("wrap", "all") and bool(wrapped)
    progress = Progress(listener=listener)
    friction, scales = base, (1.0, 1.0)
    stds: dict[tuple[str, str], float] = {}
    stages = int(fit_friction) + int(fit_wrap)
    budget = settings.budget - len(observations)  # the fitted model's final replay
    with ProcessPoolExecutor(max_workers=settings.workers) as pool:
        if fit_friction:
            stage = _Stage(Model(friction_params, base), plain)
            u, std = _solve(stage, settings, budget // stages, pool, progress)
            friction, _, _ = stage.model.decode(u)
            stds |= _unit_stds(stage.model, std)
        if fit_wrap:
            stage = _Stage(Model(wrap_params, friction), wrapped)
            u, std = _solve(stage, settings, budget - progress.simulations, pool, progress)
            _, *scale_values = stage.model.decode(u)
            scales = (scale_values[0], scale_values[1])
            stds |= _unit_stds(stage.model, std)
        runs = [pool.submit(replay, o, friction, *scales, settings.sim) for o in observations]
        fitted = [f.result() for f in runs]
    progress.spend(len(observations))
    parts = [None if sim is None else residuals(o, sim)
             for o, sim in zip(observations, fitted, strict=True)]
    rms = (math.inf if any(r is None for r in parts)
           else float(np.sqrt(np.mean(np.concatenate(parts) ** 2))))
    # friction not asked for is not reported: the bench keeps the load file's values
    present = pairs_present(observations) if settings.params != "wrap" else ()
    bounds = _pair_bounds(observations, friction, slipped)
    calibration = _calibration(friction, scales, stds, slipped, bounds, present)
    return FitResult(calibration, rms, progress.simulations, settings.method, progress.curve,
                     fitted, rms <= settings.max_residual_m)


def _solve(stage: _Stage, settings: FitSettings, budget: int, pool: Executor,
           progress: Progress) -> tuple[np.ndarray, np.ndarray]:
    """The best point of one stage and its standard deviations (unit box)."""
    objective = Objective(stage.observations, stage.model, pool, settings.sim)
    n = len(stage.model.params)
    u0 = stage.model.encode(stage.model.base, stage.model.scales)
    # keep the best point's residuals and the curvature's probes within the budget
    search = budget - (2 * n + 1) * objective.sims_per_point
    stage_progress = Progress(progress.simulations, progress.curve, progress.listener)
    if settings.method == "cmaes":
        spread = cmaes(objective, u0, search, settings.seed, stage_progress)
    else:
        spread = momentum(objective, u0, search, stage_progress)
    progress.simulations = stage_progress.simulations
    u = stage_progress.best_u if stage_progress.best_u is not None else u0
    r = objective.residuals([u])[0]
    progress.spend(objective.sims_per_point)
    if r is None:
        return u, np.full(n, UNIFORM_STD)
    curvature = _unit_std(objective, u, r, progress)
    return u, np.minimum(np.hypot(curvature, spread), UNIFORM_STD)


def _unit_stds(model: Model, std: np.ndarray) -> dict[tuple[str, str], float]:
    """Standard deviations of the parameters' values (unit box std times the range; the
    scales' in their own units, from their base-2 logarithms)."""
    out = {}
    for p, s in zip(model.params, std, strict=True):
        width = p.high - p.low
        out[p.kind, p.pair] = float(s * width)
    return out


def _pair_bounds(observations: Sequence[Observation], fitted: Friction,
                 slipped: frozenset[str]) -> dict[str, float]:
    """Lower bound of the static coefficient of each pair that never slipped: the largest
    acceleration (in g) it had to transmit, backwards under the pulse and forwards when the
    sled brakes; a stopped pallet is held backwards by the stopper, and a pair above a slipping
    one was only asked as much as the slipping pair's kinetic friction passes up."""
    bounds = {}
    for k, name in enumerate(PAIRS):
        demand = 0.0
        for obs in observations:
            back, forward = obs.peak_accel_g
            if name == "sled_pallet" and obs.load.pallet_stopper:
                back = 0.0
            cap = min((fitted.pair(below).kinetic for below in PAIRS[:k] if below in slipped),
                      default=math.inf)
            demand = max(demand, min(max(back, forward), cap))
        bounds[name] = demand
    return bounds


def _held_stuck(nominal: Friction, bounds: dict[str, float], slipped: frozenset[str]) -> Friction:
    """Pairs that never slipped, set where they stick in the replay too."""
    pairs = {}
    for name in PAIRS:
        if name in slipped:
            continue
        pair = nominal.pair(name)
        static = max(pair.static, bounds[name] + STUCK_MARGIN)
        pairs[name] = FrictionPair(static, static * pair.kinetic / pair.static)
    return replace(nominal, **pairs)


def _calibration(friction: Friction, scales: tuple[float, float],
                 stds: dict[tuple[str, str], float], slipped: frozenset[str],
                 bounds: dict[str, float], present: tuple[str, ...]) -> Calibration:
    pairs = {}
    for name in present:
        pair = friction.pair(name)
        ratio = pair.kinetic / pair.static
        if name not in slipped:
            pairs[name] = CalibratedPair(bounds[name], bounds[name] * ratio, identified=False)
            continue
        static_std, ratio_std = stds["static", name], stds["ratio", name]
        # kinetic = ratio x static (delta method, the two taken as independent)
        kinetic_std = math.hypot(pair.static * ratio_std, ratio * static_std)
        pairs[name] = CalibratedPair(pair.static, pair.kinetic, static_std, kinetic_std)
    # a scale s = 2^v: std(s) = s ln 2 std(v)
    scale_std = tuple(s * math.log(2) * stds.get((kind, ""), 0.0)
                      for s, kind in zip(scales, ("stiffness", "tension"), strict=True))
    return Calibration(pairs, scales[0], scales[1], *scale_std)
