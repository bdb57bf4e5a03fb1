"""The space of programs a search or a policy chooses from: what every program of it lays."""

from __future__ import annotations

import numpy as np
import pytest

from wrapenv.design import MAX_WRAPS, N_PARAMS, ProgramSpace
from wrapenv.load import LoadUnit
from wrapenv.material import MATERIALS, Material
from wrapenv.program import Machine
from wrapenv.wrap import Web


@pytest.fixture
def space() -> ProgramSpace:
    load = LoadUnit.from_toml("examples/pet_2layer_columnar.toml")
    return ProgramSpace.for_layout(load.layout(), "kraft")


def test_every_program_starts_with_a_parked_revolution_over_the_web_s_head(space):
    """The clamp lets the head go after the first revolution and paper does not cling: a
    program whose first revolution travels would leave the head free (0.7 of a spiral turn
    with nothing over its head once "held" the 2-layer example)."""
    lightest = space.program(np.zeros(N_PARAMS))
    assert (lightest.bottom_wraps, lightest.top_wraps) == (1, 1)
    assert space.decode(-np.ones(N_PARAMS)).passes[0].zone == "bottom"
    assert space.decode(-np.ones(N_PARAMS)).passes[0].turns == 1.0
    assert space.program(space.high).bottom_wraps == MAX_WRAPS


def test_wraps_range_as_the_space_documents_them(space):
    """Bottom and top wraps 1 to 6 revolutions, reinforcement 0 (none) to 4, the spiral's
    overlap up to 0.75 of the web (4 layers)."""
    assert space.low[:3].tolist() == [1, 1, 0]
    assert space.high[:4].tolist() == [6, 6, 4, 0.75]
    strongest = space.program(space.high)
    assert (strongest.top_wraps, strongest.reinforcements[0].wraps) == (6, 4)


@pytest.mark.parametrize("load_height_m", [0.3, 0.804, 1.6])
@pytest.mark.parametrize("web_width_m", [0.5, 0.75])
def test_the_web_of_every_program_closes_round_the_load_at_every_height(load_height_m,
                                                                        web_width_m):
    """A bottom and a top wrap cover a spiral's ends; where its helix is complete a spiral lays
    at least one layer: no height is held by part of a turn. Checked on random programs,
    reinforcements included, every 5 mm from the bottom wraps' edge to the load's top."""
    space = ProgramSpace(Web(MATERIALS["kraft"], "kraft", web_width_m), load_height_m, 0.1)
    rng = np.random.default_rng(0)
    for _ in range(200):
        wrap = space.wrap(space.low + rng.random(N_PARAMS) * (space.high - space.low))
        heights = np.arange(0.1, load_height_m, 0.005)
        assert min(wrap.layers_at(float(z)) for z in heights) >= 1 - 1e-9, wrap.program
        assert wrap.warnings() == ()


def test_the_bottom_wraps_lie_on_the_pallet_s_deck_clear_of_its_fork_entries(space):
    """A EUR pallet (144 mm) has its fork entries up to 100 mm, under 22 mm deck boards on 22 mm
    cross boards: every program's web reaches down over the deck and no lower, so forks lifting
    the unit onto the bench do not tear it, and a reinforcement is parked no lower either."""
    assert space.bottom_from_m == pytest.approx(0.144 - 0.044)
    rng = np.random.default_rng(1)
    for _ in range(50):
        wrap = space.wrap(space.low + rng.random(N_PARAMS) * (space.high - space.low))
        assert wrap.layers_at(0.099) == 0.0 and wrap.layers_at(0.101) >= 1.0, wrap.program
        assert min(p.start_m for p in wrap.passes) == pytest.approx(0.1)
    assert space.laid(space.machine_default()).passes[0].start_m == pytest.approx(0.1)


def test_the_web_starts_at_the_sled_under_a_pallet_no_taller_than_a_deck(load_file):
    """A 30 mm slip-sheet-like pallet has no fork entries to keep clear; a 1200 x 1000 pallet
    of 162 mm starts the web 44 mm below its top, like the EUR pallet."""
    thin = LoadUnit.from_toml(load_file({"pallet.height_m": 0.03}))
    assert ProgramSpace.for_layout(thin.layout(), "kraft").bottom_from_m == 0.0
    tall = LoadUnit.from_toml(load_file({"pallet.height_m": 0.162}))
    assert ProgramSpace.for_layout(tall.layout(), "kraft").bottom_from_m == pytest.approx(0.118)


def test_on_a_unit_lower_than_the_web_the_bottom_and_top_wraps_share_one_height(load_file):
    """One layer of 0.25 m bundles on a EUR pallet is 0.394 m high: the top wraps' web, 5 cm
    above it, starts at 0.394 + 0.05 - 0.5 < 0, i.e. at the sled, and so do the bottom wraps
    (the carriage would otherwise travel down to the top wraps). A 0.52 m unit's top wraps start
    at 0.07 m, below the deck's 0.100 m: its bottom wraps too."""
    low = LoadUnit.from_toml(load_file({"stack.layers": 1, "bundle.height_m": 0.25}))
    space = ProgramSpace.for_layout(low.layout(), "kraft")
    assert space.bottom_from_m == 0.0
    assert [p.zone for p in space.wrap(space.low).passes] == ["bottom", "top"]
    mid = LoadUnit.from_toml(load_file({"stack.layers": 2, "bundle.height_m": 0.188}))
    assert mid.layout().load_height_m == pytest.approx(0.52)
    assert ProgramSpace.for_layout(mid.layout(), "kraft").bottom_from_m == pytest.approx(0.07)


def test_tension_spans_5_to_50_percent_of_a_layer_s_yield_force(space):
    lo, hi = space.tension_range_n
    limit = space.material.yield_force_n_per_m * space.web_width_m
    assert (lo, hi) == pytest.approx((0.05 * limit, 0.5 * limit))
    assert space.program(space.high).middle_tension_n == pytest.approx(hi, abs=0.1)


def test_a_policy_s_action_spans_the_space_from_its_low_to_its_high_end(space):
    """-1 is each range's low end, +1 its high end, 0 its middle (environments `-v3`)."""
    ones = np.ones(N_PARAMS)
    assert space.decode(-ones) == space.wrap(space.low)
    assert space.decode(ones) == space.wrap(space.high)
    assert space.decode(0 * ones) == space.wrap((space.low + space.high) / 2)
    assert space.decode(3 * ones) == space.decode(ones)            # clipped


def test_a_reinforcement_may_be_parked_up_to_where_its_web_reaches_the_load_s_top(space):
    assert space.high[4] == pytest.approx(0.804 - 0.5)


def test_the_machine_s_default_program_lays_every_zone_at_half_the_yield_force(space):
    default = space.machine_default()
    half = space.material.yield_force_n_per_m * space.web_width_m / 2
    assert (default.bottom_wraps, default.up_overlap, default.top_wraps) == (3, 0.5, 3)
    assert (default.bottom_tension_n, default.middle_tension_n, default.top_tension_n) == (
        pytest.approx(half),) * 3


def test_a_vector_survives_program_and_back(space):
    x = np.array([3, 2, 1, 0.4, 0.2, 200.0, 300.0, 400.0, 500.0])
    assert np.allclose(space.values(space.program(x)), x)


def test_a_program_without_reinforcement_survives_vector_and_back(space):
    """The machine's default has none: its vector says 0 wraps, and the program comes back."""
    default = space.machine_default()
    x = space.values(default)
    assert x[2] == 0
    assert space.program(x) == default
    assert space.program(x).reinforcements == ()


def test_a_program_is_given_as_an_operator_types_it(space):
    """Whole newtons, whole percent of overlap, the reinforcement's height in millimetres: no
    panel takes 447.73 N or a 37.46 % overlap."""
    rng = np.random.default_rng(0)
    for action in rng.uniform(-1, 1, (50, N_PARAMS)):
        p = space.decode(action).program
        assert p is not None
        tensions = [p.bottom_tension_n, p.middle_tension_n, p.top_tension_n,
                    *(r.tension_n for r in p.reinforcements)]
        assert all(t == round(t) for t in tensions)
        assert p.up_overlap * 100 == pytest.approx(round(p.up_overlap * 100), abs=1e-9)
        assert all(r.from_m * 1000 == pytest.approx(round(r.from_m * 1000), abs=1e-9)
                   for r in p.reinforcements)


def test_a_machine_s_own_web_sets_the_tensions_the_width_laid_and_the_cycle():
    """A 0.75 m web of a stiffer paper on a machine at 10 rpm: tensions span 5-50 % of its
    yield force (4.5e5 N/m x 0.008 x 0.75 m = 2700 N: 135-1350 N), each revolution lays 0.75 m,
    and the cycle is timed at the machine's speed."""
    card = Material("our kraft", 0.1, 4.5e5, 0.008, 0.06, 0.1, 0.5, kind="paper")
    web = Web(card, "custom", 0.75, Machine(rpm=10.0))
    load = LoadUnit.from_toml("examples/pet_2layer_columnar.toml")
    space = ProgramSpace.for_layout(load.layout(), web)
    assert space.tension_range_n == pytest.approx((135.0, 1350.0))
    wrap = space.wrap(space.low)
    assert wrap.web_width_m == 0.75 and wrap.material == card and wrap.machine.rpm == 10.0
    assert wrap.passes[0].start_m == 0.1
    assert wrap.bands[0].to_m == pytest.approx(min(0.1 + 0.75, load.layout().load_height_m))


def test_no_program_asks_a_spiral_the_carriage_cannot_rise():
    """At 10 rpm the carriage (0.1 m/s) rises 0.6 m a revolution: a 0.75 m web's spiral
    overlaps at least 1 - 0.6 / 0.75 = 20 %, so the space starts there and every program it
    lays is laid as asked. At 12 rpm a 0.5 m web may touch (0 %)."""
    load = LoadUnit.from_toml("examples/pet_2layer_columnar.toml")
    wide = ProgramSpace.for_layout(load.layout(), Web(MATERIALS["kraft"], "kraft", 0.75,
                                                       Machine(rpm=10.0)))
    assert wide.min_overlap == pytest.approx(0.2)
    assert wide.program(wide.low).up_overlap == pytest.approx(0.2)
    assert not any("up_overlap" in w for w in wide.wrap(wide.low).warnings())
    assert ProgramSpace.for_layout(load.layout(), "kraft").min_overlap == 0.0
