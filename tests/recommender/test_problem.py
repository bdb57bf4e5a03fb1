"""What a robust search searches (recommender/problem.py): the uncertain samples a candidate
is tried in, the objective it is ranked by, the search vector and the program it lays, and
what changes from one search round to the next. No simulation: tests/recommender/test_search.py
runs the search itself."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from recommender.problem import Problem, SearchSettings
from tests.recommender.conftest import FAST, TWO_LAYERS_OF_FOUR
from wrapenv.calibrated import Calibration
from wrapenv.config import InputError
from wrapenv.design import N_PARAMS
from wrapenv.load import LoadUnit
from wrapenv.uncertainty import MASS_SPREAD


def test_samples_stay_within_the_uncertainty_and_repeat_under_a_seed(two_layers_of_four):
    problem = Problem.build(two_layers_of_four, FAST)
    nominal = two_layers_of_four.friction
    samples = [problem.sample(seed).load(two_layers_of_four) for seed in range(50)]
    assert problem.sample(7).load(two_layers_of_four) == problem.sample(7).load(two_layers_of_four)
    for s in samples:
        for name in ("sled_pallet", "pallet_bundle", "bundle_bundle"):
            pair = s.friction.pair(name)
            assert pair.kinetic <= pair.static
            assert abs(pair.static - nominal.pair(name).static) < 5 * 0.03
        assert abs(s.bundle.mass_kg / two_layers_of_four.bundle.mass_kg - 1) <= MASS_SPREAD
    assert len({s.friction.pallet_bundle.static for s in samples}) == 50


def test_calibrated_std_widens_the_samples(two_layers_of_four):
    cal = Calibration.from_dict({"friction": {"pallet_bundle": {
        "static": 0.3, "kinetic": 0.25, "static_std": 0.1, "kinetic_std": 0.08}}})
    wide = Problem.build(two_layers_of_four, FAST, cal)
    narrow = Problem.build(two_layers_of_four, FAST)
    spread = [np.std([p.sample(s).load(two_layers_of_four).friction.pallet_bundle.static
                      for s in range(200)]) for p in (wide, narrow)]
    assert spread[0] > 2 * spread[1]


def test_any_failing_candidate_scores_worse_than_any_passing_one(two_layers_of_four):
    problem = Problem.build(two_layers_of_four, FAST)
    heaviest = problem.space.wrap(problem.space.high)
    lightest = problem.space.wrap(problem.space.low)
    layout = two_layers_of_four.layout()
    passing = problem.objective(heaviest, heaviest.material_used_on(layout).mass_kg, [0.3],
                                [True])
    failing = problem.objective(lightest, lightest.material_used_on(layout).mass_kg, [-0.01],
                                [False])
    assert failing > passing
    # a pass short of the margin goal scores worse than with it, better than any failure
    short = problem.objective(heaviest, heaviest.material_used_on(layout).mass_kg, [0.1],
                              [True])
    assert passing < short < failing


def test_every_program_of_the_space_lays_web_and_scores_a_finite_number():
    """On a unit lower than the web a spiral up has no height to climb, but the bottom and top
    wraps every program has still lay web: the objective stays a number CMA-ES can rank
    (a NaN from the mean tension of no passes once reached pycma on a 1-layer random unit)."""
    low = LoadUnit.from_dict({"name": "low", "pallet": {"preset": "EUR"},
                              "bundle": {"length_m": 0.28, "width_m": 0.19, "height_m": 0.2,
                                         "mass_kg": 6.0},
                              "stack": {"layers": 1, "pattern": "columnar"}})
    problem = Problem.build(low, FAST)
    least = problem.wrap(np.array([0.0, 0.0, 0.0, 0.85, 0.6, 0.5, 0.3, 0.6, 0.9]))
    assert low.load_height_m < least.web_width_m
    assert [p.zone for p in least.passes] == ["bottom", "top"]
    mass = least.material_used_on(problem.layout).mass_kg
    score = problem.objective(least, mass, [-1.0], [False])
    assert math.isfinite(score)
    assert score > problem.objective(least, mass, [0.3], [True])


def test_the_objective_is_the_web_relative_to_the_machine_s_default_program(two_layers_of_four):
    problem = Problem.build(two_layers_of_four, FAST)
    default = problem.space.laid(problem.space.machine_default())
    mass = default.material_used_on(two_layers_of_four.layout()).mass_kg
    assert mass == pytest.approx(problem.reference_mass_kg)
    # at half the yield force every tension is at the top of the searched range (5-50 %):
    # the tension price adds its whole 0.05
    assert problem.objective(default, mass, [0.5], [True]) == pytest.approx(1.0 + 0.05)


def test_the_objective_adds_the_margin_shortfall_and_the_price_of_each_second(two_layers_of_four):
    """A margin 0.1 short of the goal costs 10 x 0.1 = the web of one default program; a price
    on cycle time adds that price times the cycle's seconds; a failure in any sample adds the
    heaviest program's web."""
    timed = SearchSettings(**{**FAST.__dict__, "cycle_weight": 0.01})
    problem = Problem.build(two_layers_of_four, timed)
    default = problem.space.laid(problem.space.machine_default())
    mass = problem.reference_mass_kg
    short = problem.settings.margin_goal - 0.1
    base = 1.0 + 0.05 + 0.01 * default.cycle_time_s
    assert problem.objective(default, mass, [0.5, short], [True, True]) == pytest.approx(
        base + 10 * 0.1)
    assert problem.objective(default, mass, [0.5], [True]) == pytest.approx(base)
    assert problem.objective(default, mass, [0.5], [False]) == pytest.approx(
        base + problem.heaviest_ratio)


def test_a_program_over_the_cycle_limit_pays_in_proportion_to_its_excess(two_layers_of_four):
    """At the limit it is within it; at 1.5 x the limit it scores 1e6 x 1.5."""
    first = Problem.build(two_layers_of_four, FAST)
    default = first.space.laid(first.space.machine_default())

    def limited(limit: float) -> Problem:
        return Problem.build(two_layers_of_four, SearchSettings(**{**FAST.__dict__,
                                                           "max_cycle_s": limit}))

    assert limited(default.cycle_time_s).too_slow(default) is None
    assert limited(default.cycle_time_s / 1.5).too_slow(default) == pytest.approx(1.5e6)


def test_a_program_of_the_space_has_a_search_vector_that_lays_it_again(two_layers_of_four):
    """Where a search starts from a policy's proposal: the vector of any program of the space
    lays that program (wraps as they are, the rest as fractions of their range)."""
    problem = Problem.build(two_layers_of_four, FAST)
    rng = np.random.default_rng(3)
    for _ in range(20):
        x = rng.uniform(0.0, 1.0, 9)
        x[:3] = rng.integers([1, 1, 0], [7, 7, 5])
        wrap = problem.wrap(x)
        again = problem.vector(wrap)
        assert all(0.0 <= c <= 1.0 for c in again[3:]) and again[:3] == tuple(x[:3])
        assert problem.wrap(np.array(again)) == wrap
    with pytest.raises(ValueError, match="not from bands"):
        problem.vector(replace(wrap, program=None))


def test_a_coordinate_whose_range_is_one_value_is_0_in_the_search_vector(two_layers_of_four):
    """A unit of one layer (0.474 m) is lower than the 0.5 m web: the reinforcement's lower
    edge (coordinate 4) has a single place, 0.024 m, and its coordinate is 0, not 0 / 0."""
    one_layer = LoadUnit.from_dict({**TWO_LAYERS_OF_FOUR,
                                    "stack": {**TWO_LAYERS_OF_FOUR["stack"], "layers": 1}})
    problem = Problem.build(one_layer, FAST)
    assert problem.space.low[4] == problem.space.high[4]
    vector = problem.vector(problem.wrap(np.array([2, 2, 1] + [0.5] * 6)))
    assert vector[4] == 0.0 and all(map(math.isfinite, vector))


def test_a_slow_program_scores_below_any_simulated_failure(two_layers_of_four):
    """A unit that topples fails far beyond its limits (margins of -8 were seen): a program
    over the cycle-time limit must still score worse, whatever the price on cycle time."""
    slow = SearchSettings(**{**FAST.__dict__, "max_cycle_s": 25.0, "cycle_weight": 1.0})
    problem = Problem.build(two_layers_of_four, slow)
    wrap = problem.wrap(np.full(N_PARAMS, 0.5))
    mass = wrap.material_used_on(problem.layout).mass_kg
    toppled = problem.objective(wrap, mass, [-8.0], [False])
    assert wrap.cycle_time_s > 25.0 and problem.too_slow(wrap) > toppled


def test_target_above_the_bench_is_a_clear_error(two_layers_of_four):
    with pytest.raises(InputError, match="10 m/s"):
        Problem.build(two_layers_of_four, SearchSettings(targets=(("long", 1.2),)))


def test_a_later_round_tries_each_candidate_in_one_more_sample_with_twice_the_budget():
    assert FAST.in_round(1) == FAST
    second, third = FAST.in_round(2), FAST.in_round(3)
    assert (second.samples, second.max_candidates) == (FAST.samples + 1, 2 * FAST.max_candidates)
    assert (third.samples, third.max_candidates) == (FAST.samples + 2, 4 * FAST.max_candidates)
    assert not FAST.top_tension and second.top_tension and third.top_tension
    assert replace(second, samples=FAST.samples, max_candidates=FAST.max_candidates,
                   top_tension=False) == FAST
    with pytest.raises(ValueError):
        FAST.in_round(0)


def test_a_later_round_lays_every_zone_at_the_top_tension_and_changes_nothing_else(
        two_layers_of_four):
    """Tension costs no web: a later round searches wraps, overlap and the reinforcement's
    height, each zone at the top of the range, whatever the vector's tension coordinates."""
    first = Problem.build(two_layers_of_four, FAST)
    second = Problem.build(two_layers_of_four, FAST).in_round(2)
    x = np.array([3.0, 2.0, 1.0, 0.4, 0.5, 0.2, 0.0, 0.4, 0.6])   # the zones ordered
    low, top = first.space.tension_range_n
    gentle, tight = first.wrap(x).program, second.wrap(x).program
    assert [gentle.bottom_tension_n, gentle.middle_tension_n, gentle.top_tension_n] == [
        round(low + f * (top - low)) for f in (0.2, 0.0, 0.4)]
    assert {tight.bottom_tension_n, tight.middle_tension_n, tight.top_tension_n,
            tight.reinforcements[0].tension_n} == {top}
    assert replace(tight, bottom_tension_n=gentle.bottom_tension_n,
                   middle_tension_n=gentle.middle_tension_n, top_tension_n=gentle.top_tension_n,
                   reinforcements=gentle.reinforcements) == gentle
    assert "top_tension" in second.settings.identity()
    assert "top_tension" not in first.settings.identity()


def test_ordered_tensions_lay_the_bottom_and_top_at_least_as_tight_as_the_spiral(
        two_layers_of_four):
    """Ordered tensions (the default): a zone looser than the spiral is raised to it, a tighter
    one kept; the wraps, overlap, reinforcement and the vector's meaning are untouched against
    the free search (--no-ordered-tensions)."""
    ordered = Problem.build(two_layers_of_four, FAST)
    free = Problem.build(two_layers_of_four, replace(FAST, ordered_tensions=False))
    low, top = free.space.tension_range_n
    at = [round(low + f * (top - low)) for f in (0.0, 0.2, 0.4, 0.6)]
    loose = np.array([3.0, 2.0, 1.0, 0.4, 0.5, 0.0, 0.4, 0.2, 0.6])  # bottom, top under spiral
    p = ordered.wrap(loose).program
    assert [p.bottom_tension_n, p.middle_tension_n, p.top_tension_n] == [at[2]] * 3
    assert p.reinforcements[0].tension_n == at[3]                    # not a zone of the order
    f = free.wrap(loose).program
    assert replace(p, bottom_tension_n=f.bottom_tension_n, top_tension_n=f.top_tension_n) == f
    tight = np.array([3.0, 2.0, 1.0, 0.4, 0.5, 0.6, 0.2, 0.4, 0.0])  # both over the spiral
    assert ordered.wrap(tight).program == free.wrap(tight).program
    rng = np.random.default_rng(0)
    for _ in range(50):
        x = np.concatenate([[1, 1, 0], rng.uniform(0.0, 1.0, N_PARAMS - 3)])
        q = ordered.wrap(x).program
        assert q.bottom_tension_n >= q.middle_tension_n <= q.top_tension_n
        assert ordered.vector(ordered.wrap(x)) == ordered.vector(ordered.wrap(
            np.asarray(ordered.vector(ordered.wrap(x)))))          # a fixed point: resumable
    assert ordered.settings.identity() != free.settings.identity()
