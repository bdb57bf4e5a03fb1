"""Optimisers that minimise the loss of single replays: CMA-ES and the source paper's gradient
descent with momentum, and the Gauss-Newton uncertainty at their optimum.

They suit recordings in which the bench repeats itself (bodies that slide on their own: a replay
with the true values reproduces the recording to a tenth of a millimetre); on a whole unit near
its slip threshold, whose replays scatter by tens of millimetres, `calibration.surrogate` fits
the mean response instead.
- CMA-ES (pycma): robust to the loss's small jumps (a contact that sticks one step earlier),
  parallel over a generation;
- gradient descent with momentum as in the paper: forward finite-difference gradients,
  smoothed by an exponential moving average (the paper's EMA, since the loss is noisy),
  normalised steps of decaying length.
Uncertainty comes from the loss's curvature at the optimum (Gauss-Newton: s^2 (J^T J)^-1 from
central differences), widened by the residuals' autocorrelation (neighbouring frames are not
independent), and capped at a uniform spread over the parameter's range when the data say
nothing.
"""

from __future__ import annotations

import math

import cma
import numpy as np

from calibration.objective import Objective, Progress

#: Finite-difference step in the unit box.
STEP = 0.02
#: Standard deviation of a value the data say nothing about: uniform over its whole range.
UNIFORM_STD = 1 / math.sqrt(12)
#: The momentum descent's uncertainty: the spread of its last iterates.
SPREAD_ITERATES = 8


def population(n: int) -> int:
    """pycma's default population size for n parameters."""
    return 4 + int(3 * math.log(n))


def least_points(method: str, n: int) -> int:
    """The fewest points with which `descend` searches at all: cmaes its start and one
    generation, momentum one gradient step; then the best point's replay and the curvature's
    2n probes."""
    search = 1 + population(n) if method == "cmaes" else n + 1
    return search + 2 * n + 1


def cmaes(objective: Objective, u0: np.ndarray, budget: int, seed: int,
          progress: Progress) -> np.ndarray:
    """pycma ask/tell until the budget (in simulations) or pycma's own stop; returns the final
    search distribution's standard deviations (what the search has not yet narrowed down)."""
    n = len(u0)
    popsize = population(n)
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


def curvature_std(objective: Objective, u: np.ndarray, r0: np.ndarray,
              progress: Progress) -> np.ndarray:
    """Standard deviations in the unit box from the Gauss-Newton curvature at u."""
    n = len(u)
    lo, hi = np.clip(u - STEP, 0, 1), np.clip(u + STEP, 0, 1)
    probes = [np.where(np.arange(n) == i, hi[i], u) for i in range(n)]
    probes += [np.where(np.arange(n) == i, lo[i], u) for i in range(n)]
    rs = [r for r in objective.residuals(probes) if r is not None]
    progress.spend(len(probes) * objective.sims_per_point)
    if len(rs) < len(probes):
        return np.full(n, UNIFORM_STD)
    jac = np.stack([(rs[i] - rs[n + i]) / (hi[i] - lo[i]) for i in range(n)], axis=1)
    dof = max(1, len(r0) - n)
    s2 = float(np.dot(r0, r0)) / dof * _autocorrelation_time(r0)
    cov = s2 * np.linalg.pinv(jac.T @ jac)
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    flat = np.linalg.norm(jac, axis=0) < 1e-9
    return np.where(flat, UNIFORM_STD, np.minimum(std, UNIFORM_STD))


def descend(objective: Objective, u0: np.ndarray, method: str, budget: int, seed: int,
            progress: Progress) -> tuple[np.ndarray, np.ndarray]:
    """The best point `method` ("cmaes" or "momentum") finds within `budget` simulations, and
    its covariance (diagonal: the curvature's standard deviations combined with the optimiser's
    remaining spread)."""
    n = len(u0)
    # keep the best point's residuals and the curvature's probes within the budget
    search = budget - (2 * n + 1) * objective.sims_per_point
    if method == "cmaes":
        spread = cmaes(objective, u0, search, seed, progress)
    else:
        spread = momentum(objective, u0, search, progress)
    u = progress.best_u if progress.best_u is not None else u0
    r = objective.residuals([u])[0]
    progress.spend(objective.sims_per_point)
    if r is None:
        return u, np.diag(np.full(n, UNIFORM_STD**2))
    std = np.minimum(np.hypot(curvature_std(objective, u, r, progress), spread), UNIFORM_STD)
    return u, np.diag(std**2)
