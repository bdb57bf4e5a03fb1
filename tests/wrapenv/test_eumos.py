"""EUMOS 40509's criteria as one table, judged on hand-made traces: each limit's boundary (≤ for
the 5 % and 10 % limits, < for the 4 cm of the lowest 20 cm), damage, an invalid run, the
permanent displacement since the unit was put on the sled, and the shift between layers with
its optional criterion."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from wrapenv.config import InputError
from wrapenv.eumos import (
    ELASTIC,
    EUMOS_CRITERIA,
    FALL_DROP_M,
    LAYER_SHIFT,
    LOW_ZONE,
    PERMANENT,
    Limits,
    Verdict,
    evaluate,
    level_margin,
)
from wrapenv.trace import Trace

HEIGHT_M = 1.0   # load height: a fraction of it is the same number of metres
HALF_M = 0.1     # half a bundle's height


def _rot_y(angle_rad: float) -> np.ndarray:
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def trace(path_x_m: list[list[float]], bottom_z_m: list[float], layers: list[int] | None = None,
          pallet_x_m: list[float] | None = None, final_tilt_rad: float = 0.0,
          valid: bool = True, origin_m: np.ndarray | None = None) -> Trace:
    """Bundles at x = 0.3 k (bundle k) moved along x by `path_x_m[t][k]` at sample t, standing
    on `bottom_z_m`; the pallet moved by `pallet_x_m[t]` (bundles move with it on top)."""
    path = np.array(path_x_m, float)
    steps, n = path.shape
    pallet_x = np.zeros(steps) if pallet_x_m is None else np.array(pallet_x_m, float)
    bottom = np.array(bottom_z_m, float)
    bundle_pos_m = np.zeros((steps, n, 3))
    bundle_pos_m[..., 0] = 0.3 * np.arange(n) + path + pallet_x[:, None]
    bundle_pos_m[..., 2] = bottom + HALF_M
    bundle_rot = np.broadcast_to(np.eye(3), (steps, n, 3, 3)).copy()
    bundle_rot[-1, :] = _rot_y(final_tilt_rad)
    pallet_pos_m = np.zeros((steps, 3))
    pallet_pos_m[:, 0] = pallet_x
    return Trace(
        level_g=0.5, load_height_m=HEIGHT_M, names=tuple(f"L1C{k + 1}R1" for k in range(n)),
        bottom_z_m=bottom, t_s=np.arange(steps) * 0.1, sled_accel_mps2=np.zeros(steps),
        pallet_pos_m=pallet_pos_m, pallet_rot=np.broadcast_to(np.eye(3), (steps, 3, 3)).copy(),
        bundle_pos_m=bundle_pos_m, bundle_rot=bundle_rot, valid=valid,
        invalid_reason="" if valid else "non-finite state",
        layers=None if layers is None else np.array(layers), origin_m=origin_m)


def moved_to(final_x_m: float, bottom_z_m: float = 0.5) -> Trace:
    """One bundle that ends `final_x_m` from where it started (above the lowest 20 cm)."""
    return trace([[0.0], [final_x_m]], [bottom_z_m])


def test_the_table_holds_eumos_limits_with_their_comparisons():
    assert [c.key for c in EUMOS_CRITERIA] == ["elastic_10pct", "permanent_5pct", "low20_4cm"]
    assert (ELASTIC.limit_m(0.8), ELASTIC.strict) == (pytest.approx(0.08), False)
    assert (PERMANENT.limit_m(0.8), PERMANENT.strict) == (pytest.approx(0.04), False)
    assert (LOW_ZONE.limit_m(0.8), LOW_ZONE.strict) == (0.04, True)  # metres, whatever the height
    assert PERMANENT.describe(0.804, "≤") == "≤ 40.2 mm (5 % of height)"
    assert LOW_ZONE.describe(0.804) == "< 40 mm (bundles below 20 cm)"
    assert [c.label for c in EUMOS_CRITERIA] == [
        "Elastic max", "Permanent max", "Lowest 20 cm, permanent"]


def test_permanent_exactly_on_five_percent_passes_and_just_over_fails():
    on, over = evaluate(moved_to(0.05)), evaluate(moved_to(0.0501))
    assert on.permanent_total_max_m == 0.05
    assert on.criteria["permanent_5pct"] and on.passed
    assert not over.criteria["permanent_5pct"] and not over.passed
    assert level_margin(on, HEIGHT_M) == pytest.approx(0.0)


def test_exactly_four_cm_in_the_lowest_20_cm_fails():
    on, under = evaluate(moved_to(0.04, bottom_z_m=0.0)), evaluate(moved_to(0.0399, 0.0))
    assert on.permanent_low20_m == 0.04
    assert not on.criteria["low20_4cm"] and on.criteria["permanent_5pct"] and not on.passed
    assert under.criteria["low20_4cm"] and under.passed
    # the same 4 cm above the lowest 20 cm is only 4 % of the height: it passes
    assert evaluate(moved_to(0.04, bottom_z_m=0.2)).passed


def test_figures_are_judged_as_reported_to_the_micrometre():
    """The JSON gives metres to six decimals, and the criteria read the same figures: a level
    is never reported on its limit and judged over it."""
    on, over = evaluate(moved_to(0.0500004)), evaluate(moved_to(0.0500006))
    assert (on.permanent_total_max_m, on.passed) == (0.05, True)
    assert (over.permanent_total_max_m, over.passed) == (0.050001, False)


def test_elastic_exactly_on_ten_percent_passes():
    on = evaluate(trace([[0.0], [0.10], [0.0]], [0.5]))
    over = evaluate(trace([[0.0], [0.1001], [0.0]], [0.5]))
    assert on.elastic_max_m == 0.1 and on.permanent_max_m == 0.0
    assert on.criteria["elastic_10pct"] and on.passed
    assert not over.criteria["elastic_10pct"] and not over.passed
    assert level_margin(over, HEIGHT_M) == pytest.approx(-0.001)


def test_a_toppled_bundle_is_damage_and_fails_however_little_it_moved():
    leaning = evaluate(trace([[0.0], [0.0]], [0.5], final_tilt_rad=math.radians(11)))
    upright_enough = evaluate(trace([[0.0], [0.0]], [0.5], final_tilt_rad=math.radians(9)))
    assert leaning.damage == ("L1C1R1 toppled",)
    assert not leaning.criteria["no_damage"] and not leaning.passed
    assert level_margin(leaning, HEIGHT_M) == -1.0  # its figures are all 0: -1 at best
    assert upright_enough.passed


def lowered(by_m: float, tilt_rad: float = 0.0) -> Trace:
    """One bundle standing on 0.5 m that ends `by_m` lower (still above that height for any
    `by_m` < `HALF_M`), tilted by `tilt_rad`."""
    t = trace([[0.0], [0.0]], [0.5], final_tilt_rad=tilt_rad)
    pos = t.bundle_pos_m.copy()
    pos[-1, 0, 2] -= by_m
    return replace(t, bundle_pos_m=pos)


def test_an_upright_bundle_lower_than_it_was_stacked_has_fallen_off_its_support():
    """A bottom bundle taller than the pallet slides off it onto the sled's deck upright: its
    centre stays above the pallet's top, yet it left its support."""
    assert evaluate(lowered(0.05)).damage == ("L1C1R1 fallen",)
    assert evaluate(lowered(FALL_DROP_M + 0.001)).damage == ("L1C1R1 fallen",)
    assert evaluate(lowered(0.005)).passed               # the solver's overlap: on its support
    assert evaluate(lowered(0.05, math.radians(30))).damage == ("L1C1R1 toppled",)
    # tilted, but its centre ended below where its underside stood: it fell off
    assert evaluate(lowered(0.2, math.radians(30))).damage == ("L1C1R1 fallen",)


def test_an_invalid_run_never_passes_even_without_displacement():
    level = evaluate(trace([[0.0], [0.0]], [0.5], valid=False))
    assert all(level.criteria.values())          # every figure is inside its limit ...
    assert not level.passed and not level.valid  # ... and still no pass
    assert level_margin(level, HEIGHT_M) == -1.0
    assert not Verdict(HEIGHT_M, (level,)).passed


def test_a_unit_still_moving_at_the_end_is_judged_where_it_stands_and_says_so():
    """A squeezed stack's numerical creep never ends; its figures are those at the end."""
    moving = evaluate(replace(moved_to(0.001), not_at_rest="still moving 3 s after the sled "
                                                          "stopped"))
    assert moving.passed and level_margin(moving, HEIGHT_M) == pytest.approx(0.98)
    assert moving.to_json()["not_at_rest"] == "still moving 3 s after the sled stopped"
    assert "not_at_rest" not in evaluate(moved_to(0.001)).to_json()


def test_a_level_stopped_early_says_why_and_only_then():
    stopped = evaluate(replace(moved_to(0.2), stopped_early="L1C1R1 past 5 % of the height"))
    assert stopped.to_json()["stopped_early"] == "L1C1R1 past 5 % of the height"
    assert "stopped_early" not in evaluate(moved_to(0.2)).to_json()


def test_no_level_of_a_run_that_blew_up_is_reported_as_passed():
    """CONTRACTS.md: `valid` false, then no level may be reported as passed, not even one
    that met its criteria before the blow-up."""
    before = evaluate(moved_to(0.001))
    blown = evaluate(trace([[0.0], [0.0]], [0.5], valid=False))
    assert before.passed
    verdict = Verdict(HEIGHT_M, (before, blown))
    data = verdict.to_json()
    assert data["valid"] is False and data["highest_passed_g"] is None
    assert [level["passed"] for level in data["levels"]] == [False, False]
    assert Verdict(HEIGHT_M, (before,)).to_json()["levels"][0]["passed"] is True


def test_each_figure_is_also_given_in_percent_of_the_load_height():
    """simulate's JSON (`*_pct`) and the report's table: 20 mm out and 10 mm left on a 0.8 m
    load are 2.5 % and 1.25 % of its height; the lowest 20 cm's limit is in metres alone."""
    level = evaluate(replace(trace([[0.0], [0.02], [0.01]], [0.5]), load_height_m=0.8))
    assert level.elastic_max_pct == pytest.approx(2.5)
    assert level.permanent_max_pct == level.permanent_total_max_pct == pytest.approx(1.25)
    assert level.layer_shift_max_pct == pytest.approx(1.25)     # one layer: on the pallet
    assert ELASTIC.figure_text(level, 0.8) == "20.0 mm (2.5 %)"
    assert PERMANENT.figure_text(level, 0.8) == "10.0 mm (1.2 %)"
    low = evaluate(replace(trace([[0.0], [0.01]], [0.0]), load_height_m=0.8))
    assert LOW_ZONE.figure_text(low, 0.8) == "10.0 mm"


def test_permanent_since_the_unit_was_put_on_is_what_the_criterion_judges():
    # the unit stood 3 cm further back when it was first put on the sled: this level moved the
    # bundle 3 cm (passes alone), 6 cm since it was put on (over 5 %)
    level = evaluate(trace([[0.0], [0.03]], [0.5], origin_m=np.array([[-0.03, 0.0, 0.6]])))
    assert level.permanent_max_m == pytest.approx(0.03)
    assert level.permanent_total_max_m == pytest.approx(0.06)
    assert level.permanent_total_max_pct == pytest.approx(6.0)
    assert not level.criteria["permanent_5pct"]
    # a fresh unit's total is its level's own
    fresh = evaluate(moved_to(0.03))
    assert fresh.permanent_total_max_m == fresh.permanent_max_m == pytest.approx(0.03)


def two_layers(pallet_slides: bool = False) -> Trace:
    """Layer 1: bundles 0 and 1 moved 5 mm; layer 2: bundles 2 and 3 moved 30 and 10 mm
    (their mean 20 mm), all relative to the pallet, which may slide 50 mm on the sled."""
    moves = [0.005, 0.005, 0.030, 0.010]
    pallet = [0.0, 0.05] if pallet_slides else None
    return trace([[0.0] * 4, moves], [0.0, 0.0, 0.2, 0.2], layers=[1, 1, 2, 2],
                 pallet_x_m=pallet)


def test_layer_shift_is_the_largest_shift_of_a_layers_mean_on_the_layer_below():
    # layer 1 on the pallet: 5 mm; layer 2 on layer 1: 20 - 5 = 15 mm; the largest is 15 mm
    for pallet_slides in (False, True):  # measured in the pallet's frame
        level = evaluate(two_layers(pallet_slides))
        assert level.layer_shift_max_m == pytest.approx(0.015)
        assert level.layer_shift_max_pct == pytest.approx(1.5)
    assert two_layers().layer_shift_m() == pytest.approx(0.015)


def test_the_layer_shift_criterion_is_judged_only_when_asked():
    plain = evaluate(two_layers())
    assert LAYER_SHIFT not in plain.criteria and plain.passed
    strict = evaluate(two_layers(), limits=Limits(layer_shift_fraction=0.01))
    loose = evaluate(two_layers(), limits=Limits(layer_shift_fraction=0.02))
    assert strict.criteria[LAYER_SHIFT] is False and not strict.passed
    assert loose.criteria[LAYER_SHIFT] is True and loose.passed
    # the margin reads the same table: 15 mm of a 20 mm limit leaves 0.25 (the 30 mm of the
    # highest bundle is 0.6 of the 5 % limit, 0.4 left)
    assert level_margin(loose, HEIGHT_M) == pytest.approx(0.25)
    assert level_margin(plain, HEIGHT_M) == pytest.approx(0.4)
    assert "layer_shift" in loose.to_json()["criteria"] and "limits" not in loose.to_json()


@pytest.mark.parametrize("fraction", [0.0, -0.02, 1.5, math.nan])
def test_a_layer_shift_limit_outside_none_to_all_of_the_height_is_refused(
        fraction, assert_input_error):
    with pytest.raises(InputError) as info:
        Limits(layer_shift_fraction=fraction)
    assert_input_error(info.value, "criteria", "layer_shift_fraction")
    assert Limits(layer_shift_fraction=0.02).criteria()[-1].key == LAYER_SHIFT
    assert Limits(layer_shift_fraction=1.0).layer_shift_fraction == 1.0   # all of it: allowed
