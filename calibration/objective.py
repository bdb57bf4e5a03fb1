"""The fit's parameter space and its objective: points of a unit box become friction pairs and
wrap scales, and replays of every recording (in parallel) become residual vectors.

Per slipping pair the box holds its static or its kinetic coefficient, and the ratio kinetic /
static (so kinetic <= static by construction); per wrap scale (`calibration.replay.WRAP_SCALES`)
the base-2 logarithm of the scale.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Executor, Future
from dataclasses import dataclass, field, replace

import numpy as np

from calibration import features
from calibration.checkpoint import ReplayLog
from calibration.replay import Observation, replay, residuals
from wrapenv.bench import SimSettings
from wrapenv.load import PAIRS, Friction, FrictionPair

#: Loss given to a candidate whose simulation became unphysical (m^2: a 1 m residual).
INVALID_LOSS = 1.0


def offsets(observations: Sequence[Observation]) -> list[int]:
    """Where each recording's features start in `Objective.residuals`' vectors (per body its
    slip's and turn's frames, `features.spans`), and, last, where the vectors end."""
    return [0, *itertools.accumulate(2 * sum(o.frames.values()) for o in observations)]


def loss(r: np.ndarray | None) -> float:
    """A candidate's loss from its residual vector `r`: the mean square, `INVALID_LOSS` if
    its simulation became unphysical (None)."""
    return INVALID_LOSS if r is None else float(np.mean(r**2))


@dataclass(frozen=True)
class Param:
    """One coordinate of the fit's unit box: a pair's static or kinetic coefficient or their
    ratio, linear from `low` to `high`; or a wrap scale, 2 to the power `low` to `high`, so a
    halving and a doubling lie equally far from 1."""

    kind: str            # "static", "kinetic", "ratio", or a wrap scale ("stiffness", ...)
    pair: str = ""
    low: float = 0.0
    high: float = 1.0

    @property
    def is_scale(self) -> bool:
        return self.kind not in ("static", "kinetic", "ratio")

    def value(self, u: float) -> float:
        v = self.low + (self.high - self.low) * float(np.clip(u, 0.0, 1.0))
        return 2.0**v if self.is_scale else v

    def unit(self, value: float) -> float:
        v = math.log2(value) if self.is_scale else value
        return float(np.clip((v - self.low) / (self.high - self.low), 0.0, 1.0))


@dataclass(frozen=True)
class Model:
    """How a point of the unit box becomes the bench's friction and wrap scales."""

    params: tuple[Param, ...]
    base: Friction                  # values of the pairs not fitted
    scales: Mapping[str, float] = field(default_factory=dict)   # scales not fitted

    def index(self) -> dict[tuple[str, str], int]:
        """Each parameter's coordinate in the box, by (kind, pair)."""
        return {(p.kind, p.pair): i for i, p in enumerate(self.params)}

    def decode(self, u: np.ndarray) -> tuple[Friction, dict[str, float]]:
        values = {(p.kind, p.pair): p.value(x) for p, x in zip(self.params, u, strict=True)}
        pairs = {}
        for name in PAIRS:
            if ("static", name) in values:
                static = values["static", name]
                pairs[name] = FrictionPair(static, static * values["ratio", name])
            elif ("kinetic", name) in values:
                kinetic = values["kinetic", name]
                pairs[name] = FrictionPair(kinetic / values["ratio", name], kinetic)
        scales = dict(self.scales) | {p.kind: values[p.kind, ""] for p in self.params
                                      if p.is_scale}
        return replace(self.base, **pairs), scales

    def encode(self, friction: Friction, scales: Mapping[str, float]) -> np.ndarray:
        out = []
        for p in self.params:
            pair = friction.pair(p.pair) if p.pair else None
            if p.kind == "static" and pair is not None:
                out.append(p.unit(pair.static))
            elif p.kind == "kinetic" and pair is not None:
                out.append(p.unit(pair.kinetic))
            elif p.kind == "ratio" and pair is not None:
                out.append(p.unit(pair.kinetic / pair.static))
            else:
                out.append(p.unit(scales.get(p.kind, 1.0)))
        return np.array(out)


@dataclass
class Progress:
    """Loss history of a fit: (simulations so far, loss of the best point so far)."""

    simulations: int = 0
    #: the simulations by what they were for ("search", the default, and the parts `fit`
    #: names), which the budget bounds only in part (`FitSettings.budget`)
    parts: dict[str, int] = field(default_factory=dict)
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

    def new_stage(self) -> None:
        """A stage fits other parameters (and recordings): its losses are not compared with
        the last stage's best."""
        self.best_u, self.best_loss = None, math.inf

    def spend(self, sims: int, part: str = "search") -> None:
        self.simulations += sims
        if sims:
            self.parts[part] = self.parts.get(part, 0) + sims
        if self.listener is not None:
            self.listener(self.simulations)


def _replay_task(obs: Observation, friction: Friction, scales: dict[str, float],
                 sim: SimSettings) -> np.ndarray | None:
    simulated = replay(obs, friction, scales, sim)
    return None if simulated is None else residuals(obs, simulated)


class Objective:
    """Residual vectors and losses of points of the unit box, simulated in parallel; with a
    `log`, each replay is taken from it when it holds it and added to it when simulated (a
    resumed fit, `calibration.checkpoint`)."""

    def __init__(self, observations: Sequence[Observation], model: Model, pool: Executor,
                 sim: SimSettings, log: ReplayLog | None = None) -> None:
        self.observations, self.model, self.pool, self.sim = observations, model, pool, sim
        self.log = log
        #: replays made (simulated, or taken from the log), and those that became unphysical
        self.replays = self.unphysical = 0

    def residuals(self, us: Sequence[np.ndarray]) -> list[np.ndarray | None]:
        """Per point its residuals over every recording (None: a replay became unphysical)."""
        futures = [[self._replay(obs, u) for obs in self.observations] for u in us]
        out: list[np.ndarray | None] = []
        for fs in futures:
            results = [self._logged(key, f) for key, f in fs]
            parts = [r for r in results if r is not None]
            self.replays += len(fs)
            self.unphysical += len(fs) - len(parts)
            out.append(np.concatenate(parts) if len(parts) == len(fs) else None)
        return out

    def _replay(self, obs: Observation, u: np.ndarray
                ) -> tuple[str | None, Future[np.ndarray | None]]:
        """The replay of `obs` at `u` under way, and its key in the log (None: taken from the
        log, or no log)."""
        friction, scales = self.model.decode(u)
        if self.log is None:
            return None, self.pool.submit(_replay_task, obs, friction, scales, self.sim)
        key = self.log.key(obs, friction, scales, self.sim)
        held, residual = self.log.get(key)
        if not held:
            return key, self.pool.submit(_replay_task, obs, friction, scales, self.sim)
        done: Future[np.ndarray | None] = Future()
        done.set_result(residual)
        return None, done

    def _logged(self, key: str | None, future: Future[np.ndarray | None]) -> np.ndarray | None:
        result = future.result()
        if key is not None and self.log is not None:
            self.log.add(key, result)
        return result

    def losses(self, us: Sequence[np.ndarray]) -> list[float]:
        return [loss(r) for r in self.residuals(us)]

    @property
    def sims_per_point(self) -> int:
        return len(self.observations)

    def pair_features(self) -> dict[str, np.ndarray]:
        """Indices into `residuals`' vectors of the features of each contact pair: the slips
        and turns of the bodies resting on it (a slip isolates its pair)."""
        out: dict[str, list[np.ndarray]] = {}
        for obs, start in zip(self.observations, offsets(self.observations)[:-1], strict=True):
            for name, idx in features.spans(obs.frames).items():
                out.setdefault(obs.bodies[name].pair, []).append(start + idx)
        return {pair: np.concatenate(idx) for pair, idx in out.items()}

    @property
    def shared_noise(self) -> list[np.ndarray]:
        """Indices into `residuals`' vectors of each body's slip and of its turn: each counted
        from the body's first tracked frame, so that frame's tracker error is shared by all."""
        out = []
        for obs, start in zip(self.observations, offsets(self.observations)[:-1], strict=True):
            for idx in features.spans(obs.frames).values():
                half = len(idx) // 2
                out += [start + idx[:half], start + idx[half:]]
        return out
