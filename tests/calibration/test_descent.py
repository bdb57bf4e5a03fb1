"""calibration.descent on residuals whose answer is known in closed form: the optimisers find the
least-squares point within their budgets, spent in whole steps to the last simulation; the
momentum descent's steps (length, direction, probes kept in the box); and the curvature's
standard deviation is the textbook one (the standard error of a mean, widened by the
residuals' correlation time)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import cast

import numpy as np
import pytest

from calibration.descent import UNIFORM_STD, curvature_std, descend, least_points, momentum
from calibration.objective import Objective, Progress


class LinearResiduals:
    """r(u) = A (u - u_star) + noise: an Objective without a bench (one simulation a point)."""

    sims_per_point = 1

    def __init__(self, a: np.ndarray, u_star: np.ndarray, noise: np.ndarray) -> None:
        self.a, self.u_star, self.noise = a, u_star, noise

    def residuals(self, us: Sequence[np.ndarray]) -> list[np.ndarray | None]:
        return [self.a @ (np.asarray(u) - self.u_star) + self.noise for u in us]

    def losses(self, us: Sequence[np.ndarray]) -> list[float]:
        return [float(np.mean(r**2)) for r in self.residuals(us) if r is not None]


def objective(a: np.ndarray, u_star: Sequence[float], noise: np.ndarray) -> Objective:
    return cast(Objective, LinearResiduals(a, np.asarray(u_star, float), noise))


def alternating(m: int, sigma: float, block: int = 1) -> np.ndarray:
    """+sigma and -sigma in blocks of `block` frames (mean 0 over whole periods)."""
    return sigma * np.where((np.arange(m) // block) % 2 == 0, 1.0, -1.0)


def test_the_curvature_std_of_one_value_seen_in_m_frames_is_the_standard_error_of_a_mean():
    """r_i = c (u - u*) + e_i, e_i = +-sigma alternating (no correlation between frames): the
    Gauss-Newton variance s^2 / (J^T J) with s^2 = sum e^2 / (m - 1) and J^T J = m c^2 is
    sigma^2 / ((m - 1) c^2)."""
    m, c, sigma = 801, 2.0, 0.01
    noise = alternating(m, sigma)
    obj = objective(np.full((m, 1), c), [0.5], noise)
    std = curvature_std(obj, np.array([0.5]), noise, Progress())
    assert std[0] == pytest.approx(sigma / (c * math.sqrt(m - 1)), rel=1e-6)


def test_two_values_seen_in_separate_frames_each_have_the_standard_error_of_their_own_mean():
    """The first half of m frames sees u0 with slope 2, the second half u1 with slope 4:
    J^T J = diag(m/2 x 4, m/2 x 16), s^2 = m sigma^2 / (m - 2)."""
    m, sigma = 800, 0.01
    a = np.zeros((m, 2))
    a[: m // 2, 0], a[m // 2:, 1] = 2.0, 4.0
    noise = alternating(m, sigma)
    std = curvature_std(objective(a, [0.5, 0.5], noise), np.array([0.5, 0.5]), noise,
                        Progress())
    s2 = m * sigma**2 / (m - 2)
    assert std == pytest.approx([math.sqrt(s2 / (m / 2 * 4.0)), math.sqrt(s2 / (m / 2 * 16.0))])


def test_correlated_residuals_widen_the_curvature_std_by_the_root_of_their_correlation_time():
    """The same residuals in blocks of 8 frames (a square wave): their autocorrelation at lags
    1, 2, 3 is 0.75, 0.5, 0.25 and 0 at 4, so the integrated correlation time is
    1 + 2 (0.75 + 0.5 + 0.25) = 4 frames, and the standard deviation doubles (to within the
    series' ends, a lag's products over m - lag frames)."""
    m, c, sigma = 800, 2.0, 0.01
    white, blocks = alternating(m, sigma), alternating(m, sigma, block=8)
    a = np.full((m, 1), c)
    std_white = curvature_std(objective(a, [0.5], white), np.array([0.5]), white, Progress())
    std_blocks = curvature_std(objective(a, [0.5], blocks), np.array([0.5]), blocks, Progress())
    assert std_blocks[0] / std_white[0] == pytest.approx(2.0, rel=0.01)


def test_a_value_the_residuals_do_not_depend_on_is_spread_uniformly_over_its_range():
    m = 100
    a = np.zeros((m, 2))
    a[:, 0] = 1.0                                       # the second value moves nothing
    noise = alternating(m, 0.01)
    progress = Progress()
    std = curvature_std(objective(a, [0.5, 0.5], noise), np.array([0.5, 0.5]), noise, progress)
    assert std[0] < 0.01 and std[1] == UNIFORM_STD == pytest.approx(0.2887, abs=1e-4)
    assert progress.simulations == 4                    # central differences: 2 per value


@pytest.mark.parametrize("method, tolerance", [("cmaes", 0.01), ("momentum", 0.05)])
def test_each_optimiser_finds_the_least_squares_point_within_its_budget(method, tolerance):
    """Two values, residuals that tell them apart (A of full rank), no noise: the best point
    lies at u* and the search, the best point's replay and the curvature's probes together
    spend no more than the budget."""
    rng = np.random.default_rng(0)
    a = rng.normal(size=(30, 2)) + np.array([2.0, 0.0])
    u_star = [0.62, 0.35]
    budget = 300
    progress = Progress()
    u, cov = descend(objective(a, u_star, np.zeros(30)), np.array([0.2, 0.8]), method,
                     budget, seed=0, progress=progress)
    assert np.abs(u - u_star).max() < tolerance
    assert progress.simulations <= budget
    assert np.all(np.diag(cov) <= UNIFORM_STD**2)


def test_the_least_points_a_descent_needs_are_its_search_then_the_replay_and_probes():
    """cmaes: its start and one generation of pycma's 4 + 3 ln n; momentum: one gradient of
    n + 1 points; both then the best point's replay and 2 n probes."""
    assert least_points("cmaes", 3) == (1 + 4 + int(3 * math.log(3))) + 7
    assert least_points("momentum", 3) == 4 + 7


@pytest.mark.parametrize("method, budget, spent", [
    # momentum, two values: 3 points a step; 5 after the search (the best point, 4 probes)
    ("momentum", 2 * (5 + 3 * 10), 70), ("momentum", 2 * (5 + 3 * 10) - 1, 64),
    # cmaes, two values: its start, then generations of 4 + int(3 ln 2) = 6
    ("cmaes", 2 * (5 + 1 + 6 * 3), 48), ("cmaes", 2 * (5 + 1 + 6 * 3) - 1, 36),
])
def test_a_descent_spends_its_budget_in_whole_steps_and_never_more(method, budget, spent):
    """Each point replays two recordings (two simulations). A budget that fits ten steps (three
    generations) is spent to the last simulation; one simulation less leaves the last step
    out, whose points would overrun it."""
    obj = LinearResiduals(np.eye(2).repeat(10, axis=0), np.array([0.9, 0.1]), np.zeros(20))
    obj.sims_per_point = 2
    progress = Progress()
    descend(cast(Objective, obj), np.array([0.5, 0.5]), method, budget, seed=0,
            progress=progress)
    assert progress.simulations == spent


class RecordedResiduals(LinearResiduals):
    """LinearResiduals that keep every batch of points asked for."""

    def __init__(self, *args: np.ndarray) -> None:
        super().__init__(*args)
        self.batches: list[list[np.ndarray]] = []

    def residuals(self, us: Sequence[np.ndarray]) -> list[np.ndarray | None]:
        self.batches.append([np.array(u) for u in us])
        return super().residuals(us)


def test_the_momentum_descent_steps_downhill_by_a_length_that_decays():
    """Each step is 0.05 long divided by 1 + k / 8 (k = 0, 1, 2 ...), along the smoothed
    gradient: on loss |u - u*|² / 2 from (0.5, 0.5), u* = (0.9, 0.1), the forward difference
    over 0.02 is u - u* + 0.01 = (-0.39, 0.41), and the first step runs against it."""
    obj = RecordedResiduals(np.eye(2), np.array([0.9, 0.1]), np.zeros(2))
    momentum(cast(Objective, obj), np.array([0.5, 0.5]), 3 * 3, Progress())
    iterates = [batch[0] for batch in obj.batches]          # each batch: u, then its probes
    steps = np.diff(iterates, axis=0)
    assert np.linalg.norm(steps, axis=1) == pytest.approx([0.05, 0.05 / 1.125])
    assert steps[0] / 0.05 == pytest.approx(np.array([0.39, -0.41]) / math.hypot(0.39, 0.41))


def test_an_offset_in_the_residuals_is_not_taken_for_correlation():
    """+-sigma alternating about 0.3 (a bias the model leaves): no correlation between frames,
    so s^2 = sum r^2 / (m - 1) = m (sigma^2 + 0.09) / (m - 1) and the variance s^2 / (m c^2)."""
    m, c, sigma = 801, 2.0, 0.01
    r0 = alternating(m, sigma) + 0.3
    obj = objective(np.full((m, 1), c), [0.5], r0)
    std = curvature_std(obj, np.array([0.5]), r0, Progress())
    s2 = float(np.dot(r0, r0)) / (m - 1)
    assert std[0] == pytest.approx(math.sqrt(s2 / (m * c**2)), rel=1e-6)


def test_at_the_box_s_upper_bound_the_gradient_is_probed_inwards():
    """From (1.0, 0.5) the first coordinate is probed at 0.98, not 1.02 (outside the box): the
    forward difference over -0.02 is u - u* - 0.01 = 0.09, and the step runs against it."""
    obj = RecordedResiduals(np.eye(2), np.array([0.9, 0.1]), np.zeros(2))
    momentum(cast(Objective, obj), np.array([1.0, 0.5]), 3 * 2, Progress())
    probes = obj.batches[0]
    assert np.array(probes[1:]) == pytest.approx(np.array([[0.98, 0.5], [1.0, 0.52]]))
    step = obj.batches[1][0] - probes[0]
    assert step / 0.05 == pytest.approx(-np.array([0.09, 0.41]) / math.hypot(0.09, 0.41))
