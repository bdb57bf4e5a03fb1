"""What recordings tell about pairs that never slipped, and which further test would tell more."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from calibration.fit import static_std_above
from calibration.identify import (
    STUCK_MARGIN,
    Bound,
    advice_kinetic,
    advice_scale,
    advice_scale_at_fitted_friction,
    advice_slipped_throughout,
    advice_static,
    advice_unslipped,
    held_stuck,
    pair_bounds,
    pairs_present,
    slipped_throughout,
)
from wrapenv.load import Friction, FrictionPair


def _obs(level_g: float, slipped: set[str], stopper: bool = True, layers: int = 2,
         toppled: bool = False):
    """What identify reads of an observation: the pulse's peaks (braking at 0.25 x the level,
    as the bench's pulse), the pairs seen slipping, the load's stopper and layers, whether a
    column toppled."""
    load = SimpleNamespace(pallet_stopper=stopper, stack=SimpleNamespace(layers=layers))
    return SimpleNamespace(peak_accel_g=(level_g, 0.25 * level_g), slipped=frozenset(slipped),
                           load=load, toppled=toppled)


FRICTION = Friction(sled_pallet=FrictionPair(0.45, 0.40),
                    pallet_bundle=FrictionPair(0.50, 0.42),
                    bundle_bundle=FrictionPair(0.36, 0.30))


def test_a_stopped_pallet_is_loaded_by_the_braking_only():
    bounds = pair_bounds([_obs(0.35, {"bundle_bundle"}), _obs(0.45, {"bundle_bundle"})],
                         FRICTION, frozenset({"bundle_bundle"}))
    assert bounds["sled_pallet"] == Bound(pytest.approx(0.25 * 0.45), "braking")
    assert bounds["pallet_bundle"] == Bound(0.45, "level")


def test_a_pair_above_a_slipping_one_gets_only_its_kinetic_friction():
    """A free pallet sliding on the sled (kinetic 0.40) passes at most 0.40 g up to the
    bundles, however high the level."""
    obs = [_obs(0.6, {"sled_pallet"}, stopper=False)]
    bounds = pair_bounds(obs, FRICTION, frozenset({"sled_pallet"}))
    assert bounds["pallet_bundle"] == Bound(0.40, "sled_pallet")
    assert bounds["bundle_bundle"] == Bound(0.40, "sled_pallet")
    assert "a higher level does not load it more" in advice_unslipped(
        "pallet_bundle", bounds["pallet_bundle"])


def test_where_columns_toppled_a_higher_level_is_not_the_advice():
    """The 3-layer example's columns topple at 0.32 g before its bottom layer slides: a higher
    level would topple them sooner, so the advice is a unit without the toppling columns."""
    obs = [_obs(0.28, {"bundle_bundle"}), _obs(0.32, {"bundle_bundle"}, toppled=True)]
    bounds = pair_bounds(obs, FRICTION, frozenset({"bundle_bundle"}))
    assert bounds["pallet_bundle"] == Bound(0.32, "toppling")
    assert bounds["sled_pallet"].limited_by == "braking"
    text = advice_unslipped("pallet_bundle", bounds["pallet_bundle"])
    assert "columns toppled first" in text and "one-layer unit" in text and "0.40 g" in text


def test_the_one_layer_take_the_advice_names_bounds_the_pair_by_its_level():
    """Followed: the one-layer unit held at 0.40 g, where nothing can topple, so the bound is
    the level, and the advice turns to a higher level of the same unit."""
    obs = [_obs(0.28, {"bundle_bundle"}), _obs(0.32, {"bundle_bundle"}, toppled=True),
           _obs(0.40, set(), layers=1)]
    bounds = pair_bounds(obs, FRICTION, frozenset({"bundle_bundle"}))
    assert bounds["pallet_bundle"] == Bound(0.40, "level")
    assert advice_unslipped("pallet_bundle", bounds["pallet_bundle"]) == (
        "never slipped up to 0.40 g; test at 0.45 g or more")


def test_pairs_held_stuck_in_the_replay_sit_above_their_demand():
    bounds = {"sled_pallet": Bound(0.1, "braking"), "pallet_bundle": Bound(0.45, "level"),
              "bundle_bundle": Bound(0.45, "level")}
    held = held_stuck(FRICTION, bounds, frozenset({"bundle_bundle"}))
    assert held.sled_pallet == FRICTION.sled_pallet          # already above 0.1 + margin
    assert held.pallet_bundle.static == pytest.approx(0.45 + STUCK_MARGIN)
    assert held.pallet_bundle.kinetic / held.pallet_bundle.static == pytest.approx(0.42 / 0.50)
    assert held.bundle_bundle == FRICTION.bundle_bundle      # slipped: fitted, not held


def test_a_pair_above_one_that_slipped_in_another_take_carried_this_takes_level():
    """The bottom layer slid at 0.45 g, not at 0.35 g. The 0.45 g take passed up at most the
    bottom layer's kinetic friction; the 0.35 g take, where it held, passed up all 0.35 g."""
    obs = [_obs(0.35, set()), _obs(0.45, {"pallet_bundle"})]
    bounds = pair_bounds(obs, FRICTION, frozenset({"pallet_bundle"}))
    assert bounds["bundle_bundle"] == Bound(0.42, "pallet_bundle")
    low_kinetic = Friction(FRICTION.sled_pallet, FrictionPair(0.34, 0.33), FRICTION.bundle_bundle)
    bounds = pair_bounds(obs, low_kinetic, frozenset({"pallet_bundle"}))
    assert bounds["bundle_bundle"] == Bound(0.35, "level")   # not 0.33: it held at 0.35 g


@pytest.mark.parametrize("name, bound, needles", [
    ("pallet_bundle", Bound(0.1125, "braking"),
     ["without the pallet stopper", "0.20 g", "--mixed-loads"]),
    ("pallet_bundle", Bound(0.45, "level"), ["never slipped up to 0.45 g", "test at 0.50 g"]),
    ("pallet_bundle", Bound(0.30, "sled_pallet"),
     ["sled_pallet slipped first", "with the pallet stopper", "0.35 g", "--mixed-loads"]),
    ("bundle_bundle", Bound(0.30, "pallet_bundle"),
     ["pallet_bundle slipped first", "anti-slip sheet", "0.35 g", "--mixed-loads"]),
])
def test_advice_names_the_test_that_would_make_a_pair_slip(name, bound, needles):
    """A test on another set-up is another load file, which the fit takes only with
    --mixed-loads: the advice says so (it led a lab engineer into that refusal)."""
    text = advice_unslipped(name, bound)
    for needle in needles:
        assert needle in text, text
    assert ("--mixed-loads" in text) == (bound.limited_by != "level")


def test_advice_on_an_unresolved_static_coefficient_brackets_the_first_slip():
    obs = [_obs(0.30, set()), _obs(0.40, {"bundle_bundle"}), _obs(0.50, {"bundle_bundle"})]
    assert "between 0.30 and 0.40 g" in advice_static("bundle_bundle", obs, 0.08)
    assert "below 0.40 g" in advice_static("bundle_bundle", obs[1:], 0.08)


def test_the_bracket_s_lower_end_is_a_level_below_the_first_slip_that_held():
    """Takes that held at or above the level where the pair first slipped (repeat takes
    disagree near an onset) bracket nothing: the onset still lies between 0.30 and 0.40 g."""
    obs = [_obs(0.30, set()), _obs(0.40, {"bundle_bundle"}), _obs(0.40, set()),
           _obs(0.45, set()), _obs(0.50, {"bundle_bundle"})]
    assert "between 0.30 and 0.40 g" in advice_static("bundle_bundle", obs, 0.08)


def test_advice_on_an_unresolved_kinetic_coefficient_asks_for_a_longer_slide():
    """How far a slip runs pins the kinetic coefficient: a level above the highest the pair
    slipped at, not the highest tested (at 0.50 g the pair held); where a front row slides off
    its support there, the bundles behind it slide on and still pin it (the one-layer unit's
    0.55 g take: the fits it writes put pallet-bundle's kinetic coefficient within 0.021)."""
    obs = [_obs(0.30, {"pallet_bundle"}), _obs(0.45, {"pallet_bundle"}), _obs(0.50, set())]
    text = advice_kinetic("pallet_bundle", obs, 0.042)
    assert text.startswith("kinetic coefficient not resolved (± 0.042): how far a slip runs "
                           "pins it; ")
    assert "a level above 0.45 g" in text
    assert text.endswith("while some bundle that slips on it keeps its support there")


def test_a_pair_that_slipped_at_one_level_is_told_its_coefficients_trade():
    """Slipped at one level only (twice at 0.50 g), a later onset and a freer slide run as
    far: the one-layer unit's 0.50 g take is reproduced by the truth with pallet-bundle's
    static coefficient 0.03 higher and its kinetic one 0.04 lower (2.2 mm unexplained), so
    its fits' kinetic errors ran -0.089 to +0.021 with their static ones high."""
    obs = [_obs(0.40, set()), _obs(0.50, {"pallet_bundle"}), _obs(0.50, {"pallet_bundle"})]
    text = advice_kinetic("pallet_bundle", obs, 0.029)
    assert ("how far a slip runs pins it, but slipping at one level only, a later onset and a "
            "freer slide run as far (its static coefficient trades against it); a level above "
            "0.50 g") in text


def test_advice_on_a_bracketed_coefficient_names_the_shifts_the_recordings_allow():
    """Bracketed, yet the acceptance test did not refuse the value 0.075 lower (`fit._probe`):
    the advice says so, since the onset alone would suggest it is pinned."""
    obs = [_obs(0.30, set()), _obs(0.35, {"bundle_bundle"})]
    text = advice_static("bundle_bundle", obs, 0.0375, unrefused=[-0.075])
    assert "do not refuse it shifted -0.075" in text
    assert "between 0.30 and 0.35 g" in text


def test_advice_on_a_kinetic_coefficient_names_the_ridge_shifts_the_recordings_allow():
    """Slipped at one level only, and a probe 0.084 lower along the ridge was not refused
    (`fit._probe`): the advice gives the shift beside the trade that explains it."""
    obs = [_obs(0.35, set()), _obs(0.45, {"pallet_bundle"})]
    text = advice_kinetic("pallet_bundle", obs, 0.042, unrefused=[-0.084])
    assert text.startswith("kinetic coefficient not resolved (± 0.042; the recordings do not "
                           "refuse it shifted -0.084): how far a slip runs pins it, but ")


def test_a_single_layer_has_no_bundle_on_bundle_pair():
    assert pairs_present([_obs(0.4, set(), layers=1)]) == ("sled_pallet", "pallet_bundle")
    assert pairs_present([_obs(0.4, set())])[-1] == "bundle_bundle"


def test_a_pair_that_slipped_at_every_level_is_bounded_only_from_above():
    """Bundle on bundle slid at 0.35 and 0.45 g: the least it was asked to pass is the lower
    level, its static coefficient at most about 0.35, and a lower level would bracket it; a
    recording that held it (0.30 g) brackets its onset instead."""
    slid = [_obs(0.35, {"bundle_bundle"}), _obs(0.45, {"bundle_bundle", "pallet_bundle"})]
    bound = slipped_throughout("bundle_bundle", slid, FRICTION,
                               frozenset({"bundle_bundle", "pallet_bundle"}))
    assert bound == Bound(0.35, "level")
    advice = advice_slipped_throughout(bound, 0.424, 0.036)
    assert "only from above (about 0.35; more where the layers below rock" in advice
    assert "test at 0.30 g or lower" in advice
    assert slipped_throughout("bundle_bundle", [_obs(0.30, set()), *slid], FRICTION,
                              frozenset({"bundle_bundle"})) is None
    assert slipped_throughout("pallet_bundle", slid, FRICTION, frozenset()) is None


def test_the_static_coefficient_bounded_from_above_gets_an_honest_spread():
    """Uniform from the kinetic coefficient to the bound (or to the fitted value above it): by
    hand (0.424 - 0.300) / sqrt(12) = 0.0358, well above a surrogate's 0.012 and the 0.025 at
    which a static coefficient counts as resolved; bound above the fit: (0.40 - 0.30) / 3.464."""
    assert static_std_above(FrictionPair(0.424, 0.300), 0.35) == pytest.approx(0.0358, abs=1e-4)
    assert static_std_above(FrictionPair(0.36, 0.30), 0.40) == pytest.approx(0.0289, abs=1e-4)


def test_advice_on_an_unresolved_wrap_scale_gives_the_reason_of_its_web():
    """Paper is ~160 x stiffer than film: behind paper the load's give decides the motion, so
    the paper's stiffness hardly shows; a film's stiffness decides it, but an unresolved one is
    constrained only together with the laid tension and the give in series with it (fitted
    with the true friction: stiffness 3.9 x, tension 0.6 x, give 0.3 x for 1.3, 1, 1;
    docs/calibration.md), so the advice names what to measure and give as known."""
    paper = advice_scale("stiffness", 2.0, 1.0, paper=True)
    film = advice_scale("stiffness", 2.0, 1.0, paper=False)
    assert "hardly depends" in paper and "load-side compliance" in paper
    assert "hardly depends" not in film and "the film decides" in film
    assert "laid tension" in film and "give" in film and "--known" in film
    assert "film's stiffness" in advice_scale("tension", 2.0, 1.0, paper=False)
    film_give = advice_scale("give", 0.4, 0.1, paper=False)
    assert "in series" in film_give and "--known" in film_give
    assert "film" not in advice_scale("give", 0.4, 0.1, paper=True)


def test_a_wrap_scale_unresolved_on_takes_after_earlier_levels_asks_for_a_fresh_unit():
    """A lab's takes of one unit through the levels replay with several times a fresh unit's
    scatter, and LLDPE's stiffness was not pinned by them (docs/calibration.md, "A lab's
    takes"): the advice asks for the wrapped take on a freshly wrapped unit, only then."""
    carried = advice_scale("stiffness", 2.4, 1.9, paper=False, carried=True)
    assert carried.startswith(advice_scale("stiffness", 2.4, 1.9, paper=False))
    assert "film a freshly stacked and wrapped unit" in carried
    assert "freshly" not in advice_scale("stiffness", 2.4, 1.9, paper=False)


def test_a_scale_resolved_at_a_fitted_friction_says_what_its_standard_deviation_leaves_out():
    """The wrap stage holds the friction fitted in the same run, so a scale's ± says nothing of
    that friction's uncertainty (friction errors of 0.01 moved LLDPE's stiffness by a quarter):
    the advice says so and names the fits that do not depend on it."""
    text = advice_scale_at_fitted_friction("stiffness", 1.64, 0.23)
    assert text.startswith("stiffness scale 1.64 ± 0.23 holds only at the friction fitted")
    assert "--params wrap" in text and "--validate" in text
