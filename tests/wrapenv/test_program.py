"""Specification of a spiral wrapper's program: the layers its web lays (against hand
computation), the web it uses and the time it takes.

Conventions of every hand computation below: heights from the sled surface, a 0.5 m web, the
web's position given by its lower edge; a revolution covers one web width; a spiral rising r
per turn lays, averaged round the load, w / r layers where its helix is complete."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wrapenv.load import LoadUnit
from wrapenv.material import MATERIALS
from wrapenv.program import (
    ROPE_HEIGHT_M,
    Band,
    Machine,
    Outline,
    Pass,
    Program,
    Reinforcement,
    cycle_time_s,
    pass_area_m2,
)
from wrapenv.wrap import UNHELD_HEAD, WrapFormat

W = 0.5
KRAFT, FILM = MATERIALS["kraft"], MATERIALS["lldpe"]


def program(**changes) -> Program:
    """Nothing but what a test names: no wraps, a touching spiral, no overhang."""
    base = {"bottom_wraps": 0, "bottom_tension_n": 100.0, "up_overlap": 0.0,
            "middle_tension_n": 100.0, "top_wraps": 0, "top_tension_n": 100.0,
            "top_overhang_m": 0.0}
    return Program(**{**base, **changes})


def laid(prog: Program, height_m: float = 2.0, material=KRAFT) -> WrapFormat:
    return WrapFormat.from_program(material, W, prog, height_m, "kraft")


def spiral_layers(z: float, s0: float, s1: float, rise: float) -> float:
    """Hand formula: a web whose lower edge rises from s0 to s1 covers height z while the edge
    is in [z - w, z]; per unit of edge travel there are 1 / rise turns."""
    return max(0.0, min(s1, z) - max(s0, z - W)) / rise


# --- layer map ---------------------------------------------------------------------------------


def test_bottom_wraps_lay_their_count_over_one_web_width_where_the_carriage_parks():
    wrap = laid(program(bottom_wraps=3, bottom_from_m=0.1, up_overlap=0.5), height_m=0.6)
    # load 0.6 m tall: top wraps' edge at 0.6 - 0.5 = 0.1, so the spiral has no travel
    assert [p.zone for p in wrap.passes] == ["bottom"]
    assert wrap.layers_at(0.05) == 0.0
    assert wrap.layers_at(0.1) == wrap.layers_at(0.35) == wrap.layers_at(0.599) == 3.0
    assert wrap.layers_over(0.1, 0.6) == pytest.approx(3.0)


def test_a_touching_spiral_lays_one_layer_where_it_is_complete():
    # 2 m load, no overhang: the spiral's edge rises from 0 to 1.5 m, 0.5 m per turn (3 turns)
    wrap = laid(program(up_overlap=0.0))
    (spiral,) = wrap.passes
    assert (spiral.start_m, spiral.end_m, spiral.turns) == (0.0, 1.5, pytest.approx(3.0))
    for z in (0.1, 0.25, 0.5, 0.9, 1.5, 1.75, 1.99):
        assert wrap.layers_at(z) == pytest.approx(spiral_layers(z, 0.0, 1.5, 0.5)), z
    assert wrap.layers_at(1.0) == pytest.approx(1.0)
    assert wrap.layers_at(0.25) == pytest.approx(0.5)  # half a web width into the first turn


def test_a_50_percent_overlap_lays_two_layers():
    wrap = laid(program(up_overlap=0.5))
    assert wrap.passes[0].rise_m == pytest.approx(0.25)
    assert wrap.passes[0].turns == pytest.approx(6.0)
    for z in (0.5, 0.8, 1.2, 1.5):
        assert wrap.layers_at(z) == pytest.approx(2.0)
    assert wrap.layers_over(0.5, 1.5) == pytest.approx(2.0)
    for z in (0.1, 0.3, 1.6, 1.9):
        assert wrap.layers_at(z) == pytest.approx(spiral_layers(z, 0.0, 1.5, 0.25)), z


def test_a_spiral_down_lays_its_own_layers_on_top_of_the_spiral_up():
    wrap = laid(program(up_overlap=0.5, down_overlap=0.5))
    assert [p.zone for p in wrap.passes] == ["spiral up", "spiral down"]
    assert wrap.layers_at(1.0) == pytest.approx(4.0)


def test_a_reinforcement_across_a_layer_joint_adds_its_wraps_and_splits_the_spiral_only():
    # 2-layer example: the joint between the bundle layers is at 0.144 + 0.33 = 0.474 m
    load = LoadUnit.from_toml("examples/pet_2layer_columnar.toml")
    h, joint = load.load_height_m, 0.144 + 0.33
    at = joint - W / 2
    plain = laid(program(bottom_wraps=2, up_overlap=0.5, top_wraps=1), h)
    reinforced = laid(program(bottom_wraps=2, up_overlap=0.5, top_wraps=1,
                              reinforcements=(Reinforcement(at, 2, 300.0),)), h)
    assert [p.zone for p in reinforced.passes] == [
        "bottom", "spiral up", "reinforcement", "spiral up", "top"]
    for z in np.linspace(0.0, h - 1e-6, 41):
        extra = 2.0 if at <= z < at + W else 0.0
        assert reinforced.layers_at(z) == pytest.approx(plain.layers_at(z) + extra), z
    assert reinforced.layers_at(joint) - plain.layers_at(joint) == pytest.approx(2.0)


def test_top_wraps_reach_the_overhang_and_the_web_above_the_load_is_not_a_layer():
    wrap = laid(program(top_wraps=3, top_overhang_m=0.05), height_m=1.0)
    top = wrap.passes[-1]
    assert top.zone == "top" and top.start_m == pytest.approx(1.0 + 0.05 - W)
    assert wrap.layers_at(0.6) == pytest.approx(3.0 + spiral_layers(0.6, 0.0, 0.55, 0.5))
    assert max(b.to_m for b in wrap.bands) == pytest.approx(1.0)  # folded over: no band


def test_roped_film_gathers_the_bottom_wraps_into_a_cord_with_all_their_web():
    wrap = laid(program(bottom_wraps=3, bottom_from_m=0.1, roping=True), 1.0, FILM)
    rope = wrap.bands[0]
    assert (rope.from_m, rope.to_m) == (0.1, pytest.approx(0.1 + ROPE_HEIGHT_M))
    assert rope.layer_metres(0.0, 1.0) == pytest.approx(3 * W)  # three web widths of film


def test_a_linear_band_averages_exactly():
    ramp = Band(0.0, 1.0, 0.0, 100.0, layers_to=2.0)
    assert ramp.layer_metres(0.0, 1.0) == pytest.approx(1.0)
    assert ramp.layer_metres(0.5, 1.0) == pytest.approx(0.75)
    assert ramp.layers_at(0.25) == pytest.approx(0.5)
    assert ramp.clipped(0.5) == Band(0.0, 0.5, 0.0, 100.0, layers_to=1.0)


def test_a_linear_band_off_the_origin_averages_from_its_own_foot():
    """From 1 layer at 0.2 m to 3 at 1.0 m (2.5 layers a metre): 1.5 layers at 0.4 m, 2.5 on
    average over its top 0.4 m (1.0 layer-metre), 2 over the whole 0.8 m band."""
    ramp = Band(0.2, 1.0, 1.0, 100.0, layers_to=3.0)
    assert ramp.layers_at(0.4) == pytest.approx(1.5)
    assert ramp.layer_metres(0.6, 1.0) == pytest.approx(1.0)
    assert ramp.layer_metres(0.0, 2.0) == pytest.approx(2.0 * 0.8)
    assert ramp.layer_metres(1.0, 2.0) == 0.0 and ramp.layers_at(1.0) == 0.0   # [from, to)
    assert ramp.clipped(0.6) == Band(0.2, 0.6, 1.0, 100.0, layers_to=pytest.approx(2.0))
    assert ramp.clipped(1.0) is ramp and ramp.clipped(0.2) is None


# --- material used -----------------------------------------------------------------------------


def test_material_of_a_parked_revolution_goes_round_the_pallet_then_the_load():
    outline = Outline(pallet_top_m=0.2, pallet_perimeter_m=4.0, load_perimeter_m=3.0)
    three = Pass("bottom", 0.0, 0.0, 3.0, 100.0)
    assert pass_area_m2(three, W, outline) == pytest.approx(3 * (0.2 * 4.0 + 0.3 * 3.0))


@pytest.mark.parametrize("pallet_top_m", [0.144, 0.6])
def test_material_of_a_spiral_is_its_helical_turns_times_the_web(pallet_top_m):
    """Against numerical integration: the web area of one turn whose edge is at e, averaged
    over the edge's travel, times the number of turns, times the helix's stretch. A turn's web
    changes with e where its upper edge, then its lower edge, passes the pallet's top: on a
    0.6 m pallet both within the spiral's travel."""
    outline = Outline(pallet_top_m=pallet_top_m, pallet_perimeter_m=4.0, load_perimeter_m=3.6)
    spiral = Pass("spiral up", 0.0, 1.2, 4.8, 100.0)  # rise 0.25 m
    edges = np.linspace(0.0, 1.2, 20001)
    per_turn = [outline.web_area_m2(e, e + W) for e in edges]
    helix = [math.hypot(a / W, 0.25) / (a / W) for a in per_turn]
    hand = 4.8 * float(np.mean(np.array(per_turn) * np.array(helix)))
    assert pass_area_m2(spiral, W, outline) == pytest.approx(hand, rel=1e-4)


def test_material_of_the_default_program_on_the_2_layer_example_within_1_percent():
    """3 bottom wraps, a 50 % spiral, 3 top wraps on a 0.804 m load, by hand."""
    load = LoadUnit.from_toml("examples/pet_2layer_columnar.toml")
    layout = load.layout()
    wrap = laid(program(bottom_wraps=3, up_overlap=0.5, top_wraps=3, top_overhang_m=0.05),
                load.load_height_m)
    p_pallet, p_load = 2 * (1.2 + 0.8), 2 * sum(layout.outline_m)
    bottom = 3 * (0.144 * p_pallet + 0.356 * p_load)
    top_edge = 0.804 + 0.05 - 0.5
    top = 3 * 0.5 * p_load  # entirely above the pallet, the overhang folded over
    turns = top_edge / 0.25
    # the spiral's edge from 0 to 0.354: on average 0.144 - 0.354 / 2 ... below the pallet top
    below = np.mean([max(0.0, 0.144 - e) for e in np.linspace(0, top_edge, 10001)])
    spiral = turns * (below * p_pallet + (0.5 - below) * p_load)
    used = wrap.material_used_on(layout)
    assert used.area_m2 == pytest.approx(bottom + top + spiral, rel=0.01)
    assert used.mass_kg == pytest.approx(used.area_m2 * 0.090)
    assert used.revolutions == pytest.approx(6 + turns)
    assert used.web_length_m == pytest.approx(used.area_m2 / W)


def test_film_from_the_roll_is_the_web_laid_over_one_plus_the_prestretch():
    layout = LoadUnit.from_toml("examples/pet_2layer_columnar.toml").layout()
    at_card = laid(program(bottom_wraps=2), 0.804, FILM).material_used_on(layout)
    assert at_card.roll_length_m == pytest.approx(at_card.web_length_m / 3.5)  # card: 250 %
    lower = laid(program(bottom_wraps=2, prestretch=1.0), 0.804, FILM).material_used_on(layout)
    assert lower.roll_length_m == pytest.approx(lower.web_length_m / 2.0)
    # the full web width laid: what is laid weighs what came off the roll, whose 20 µm film
    # weighs 920 kg/m³ x 20e-6 m = 18.4 g/m² (docs/materials.md, card 2a)
    for used in (at_card, lower):
        assert used.mass_kg == pytest.approx(used.roll_length_m * W * 0.0184)
    paper = laid(program(bottom_wraps=2), 0.804).material_used_on(layout)
    assert paper.roll_length_m == paper.web_length_m


def test_a_band_form_is_costed_as_full_width_revolutions():
    outline = Outline(0.2, 4.0, 3.0)
    narrow = WrapFormat(KRAFT, W, (Band(0.0, 0.3, 1, 100.0),), "kraft")
    assert narrow.material_used(outline).area_m2 == pytest.approx(0.2 * 4.0 + 0.3 * 3.0)
    tall = WrapFormat(KRAFT, W, (Band(0.0, 1.2, 2, 100.0),), "kraft")  # 3 stacks of 2 wraps
    assert [(p.start_m, p.end_m, p.turns) for p in tall.passes] == [
        (0.0, 0.0, 2.0), (0.5, 0.5, 2.0), (1.0, 1.0, 2.0)]           # one web width apart
    assert tall.material_used(outline).revolutions == 6
    assert tall.material_used(outline).area_m2 == pytest.approx(
        2 * (0.2 * 4.0 + 0.3 * 3.0) + 2 * 0.5 * 3.0 + 2 * 0.5 * 3.0)


def test_paper_bands_narrower_than_the_web_are_warned_about_film_ones_are_not():
    narrow = (Band(0.0, 0.3, 1, 100.0), Band(0.3, 0.9, 1, 100.0))
    warnings = WrapFormat(KRAFT, W, narrow, "kraft").warnings()
    assert len(warnings) == 1 and "band[0]" in warnings[0] and "no machine" in warnings[0]
    assert WrapFormat(FILM, W, narrow, "lldpe").warnings() == ()


def test_a_paper_program_without_a_bottom_wrap_is_warned_about():
    """Paper does not cling: without a parked first revolution nothing holds the web's head."""
    assert UNHELD_HEAD in laid(program(bottom_wraps=0)).warnings()
    assert UNHELD_HEAD not in laid(program(bottom_wraps=1)).warnings()
    assert UNHELD_HEAD not in laid(program(bottom_wraps=0), material=FILM).warnings()


def test_a_program_whose_web_does_not_close_somewhere_is_warned_about():
    """A touching spiral from 0 to 0.354 m on a 0.804 m load (0.71 of a turn) with one bottom
    wrap: above the bottom wrap's web (0.5 m) the layers fall from 0.71 to 0.1, part of a
    turn; a top wrap closes it."""
    open_ = laid(program(bottom_wraps=1, top_overhang_m=0.05), 0.804).warnings()
    assert len(open_) == 1 and "does not close" in open_[0] and "from 0.50 to 0.80 m" in open_[0]
    assert laid(program(bottom_wraps=1, top_wraps=1, top_overhang_m=0.05), 0.804).warnings() == ()


def test_each_stretch_where_the_web_does_not_close_is_named_on_its_own():
    """A touching spiral alone, its lower edge from 0 to 1.5 m on a 2 m load: the first half
    metre has z / 0.5 of a layer, the last (2 - z) / 0.5, one layer between. Until 2026-12-02
    the warning said the web did not close from 0.01 to 2.00 m, the closed metre included."""
    (said,) = [w for w in laid(program(bottom_wraps=1, up_overlap=0.0), 2.0).warnings()
               if "does not close" in w]
    assert "from 1.51 to 2.00 m (" in said and " and " not in said
    (said,) = [w for w in laid(program(up_overlap=0.0), 2.0).warnings() if "does not close" in w]
    assert "does not close round the load from 0.01 to 0.50 m and from 1.51 to 2.00 m (" in said


def test_a_program_whose_web_misses_the_pallet_or_lies_above_the_load_is_warned_about():
    """On the 2-layer example (pallet 0.144 m, load 0.804 m, a 0.5 m web): bottom wraps from
    0.3 m leave the pallet bare; an overhang of 0.39 m and a reinforcement from 0.6 m put 0.39
    and 0.296 m of their web above the load; a 1 m web's top wraps stand on the sled and reach
    0.196 m above it, whatever the overhang asked (a user, 2026-11-27: each taken silently)."""
    layout = LoadUnit.from_toml("examples/pet_2layer_columnar.toml").layout()

    def warned(web_m: float = W, **changes: object) -> str:
        prog = program(**{"bottom_wraps": 1, "top_wraps": 1, "top_overhang_m": 0.05, **changes})
        return " | ".join(WrapFormat.from_program(KRAFT, web_m, prog, 0.804).warnings(layout))

    assert warned() == ""
    assert ("program.bottom_from_m = 0.3 m: the web does not reach down to the pallet (its "
            "top at 0.144 m)") in warned(bottom_from_m=0.3)
    assert ("program.top_overhang_m = 0.39 m: the top wraps lay 0.39 m of their 0.5 m web "
            "above the load") in warned(top_overhang_m=0.39)
    assert ("program.reinforcement[0].from_m = 0.6 m: its wraps lay 0.30 m of their 0.5 m "
            "web above the load") in warned(reinforcements=(Reinforcement(0.6, 1, 100.0),))
    # one from 0.4 m lays 0.096 m above the load, less than half its web: no warning
    assert warned(reinforcements=(Reinforcement(0.4, 1, 100.0),)) == ""
    assert ("web_width_m = 1 m is more than the load's height (0.804 m) and "
            "program.top_overhang_m (0.05 m): the top wraps are laid from the sled and reach "
            "0.20 m above the load") in warned(web_m=1.0)


def test_a_spiral_the_carriage_cannot_rise_at_the_rpm_is_laid_at_the_overlap_it_can():
    """A 0.75 m web at 10 rpm, the carriage at 0.1 m/s: a touching spiral asks 0.75 m a
    revolution, the carriage rises 0.1 m/s x 6 s = 0.6 m, and the turntable does not wait:
    0.6 m a turn is 20 % overlap, 0.75 / 0.6 = 1.25 layers. A user's program was costed at
    0 % and timed at the carriage's speed (2026-11-27)."""
    prog = program(bottom_wraps=1, top_wraps=1)
    wrap = WrapFormat.from_program(KRAFT, 0.75, prog, 2.0, "kraft", Machine(rpm=10.0))
    (spiral,) = [p for p in wrap.passes if p.zone == "spiral up"]
    assert spiral.turns == pytest.approx(1.25 / 0.6)   # the top wraps at 2.0 - 0.75 m
    assert wrap.layers_at(1.0) == pytest.approx(1.25)
    (said,) = [w for w in wrap.warnings() if "up_overlap" in w]
    assert said.startswith("program.up_overlap = 0 asks the carriage to rise 0.750 m a "
                           "revolution; at 10 rpm it rises at most 0.600 m (0.1 m/s), so the "
                           "spiral is laid at 20 % overlap")
    at_12 = WrapFormat.from_program(KRAFT, W, prog, 2.0, "kraft", Machine())  # 0.5 m: as fast
    assert [p.turns for p in at_12.passes if p.zone == "spiral up"] == [pytest.approx(3.0)]
    assert not any("up_overlap" in w for w in at_12.warnings())


# --- cycle time --------------------------------------------------------------------------------


def test_cycle_time_of_the_default_program_by_hand():
    # 3 + 1.416 + 3 revolutions at 12 rpm (5 s each), the rotation's start and stop (3 s: half
    # of each 3 s ramp); the carriage returns 0.354 m at 0.1 m/s (3.5 s) while the 15 s
    # pallet change runs
    wrap = laid(program(bottom_wraps=3, up_overlap=0.5, top_wraps=3, top_overhang_m=0.05), 0.804)
    assert wrap.cycle_time_s == pytest.approx((6 + 0.354 / 0.25) * 5.0 + 3.0 + 15.0)


def test_a_program_s_own_rpm_times_its_revolutions():
    # the default program asking 6 rpm: 7.416 revolutions of 10 s, ramps 3 s, change 15 s
    wrap = laid(program(bottom_wraps=3, up_overlap=0.5, top_wraps=3, top_overhang_m=0.05,
                        rpm=6.0), 0.804)
    assert wrap.rpm == 6.0
    assert wrap.cycle_time_s == pytest.approx((6 + 1.416) * 10.0 + 3.0 + 15.0)


def test_the_carriage_returns_to_the_bottom_wraps_height():
    """Bottom wraps parked 0.1 m up, the top wraps at 0.354 m, no pallet change to hide the
    return: 3 + 1.016 + 3 revolutions of 5 s, 3 s of ramps, then 0.254 m down at 0.1 m/s."""
    prog = program(bottom_wraps=3, up_overlap=0.5, top_wraps=3, top_overhang_m=0.05,
                   bottom_from_m=0.1)
    wrap = WrapFormat.from_program(KRAFT, W, prog, 0.804, "kraft", Machine(handling_s=0.0))
    assert wrap.cycle_time_s == pytest.approx((6 + 1.016) * 5.0 + 3.0 + 0.254 / 0.1)


def test_a_spiral_faster_than_the_carriage_takes_the_carriage_s_time():
    spiral = Pass("spiral up", 0.0, 1.5, 3.0, 100.0)  # 0.5 m a turn
    fast = Machine(rpm=30.0, carriage_speed_mps=0.1, handling_s=0.0, ramp_s=0.0)
    # 3 turns at 30 rpm would take 6 s; the carriage needs 15 s for 1.5 m, then 15 s back
    assert cycle_time_s((spiral,), 0.0, 30.0, fast) == pytest.approx(15.0 + 15.0)


def test_the_carriage_travels_between_passes_that_do_not_join_and_back_home():
    """A band form's stacks: 2 turns parked at 0.1 m and 3 at 0.6 m (25 s at 12 rpm); the
    carriage climbs the 0.5 m between them at 0.1 m/s (5 s), then returns the 0.5 m home
    (5 s), which here takes longer than the 2 s pallet change and so sets the cycle."""
    low, high = Pass("band", 0.1, 0.1, 2.0, 100.0), Pass("band", 0.6, 0.6, 3.0, 100.0)
    machine = Machine(carriage_speed_mps=0.1, handling_s=2.0, ramp_s=0.0)
    assert cycle_time_s((low, high), 0.1, 12.0, machine) == pytest.approx(25.0 + 5.0 + 5.0)
    assert cycle_time_s((low, high), 0.6, 12.0, machine) == pytest.approx(25.0 + 5.0 + 2.0)


def test_the_rotation_starts_and_stops_once_a_cycle():
    """Two parked passes run in one rotation: 2 + 3 turns at 12 rpm (25 s), one start and one
    stop on 4 s ramps (each half of it lost: 4 s), then the 15 s pallet change; a program
    with no revolution has no ramp."""
    bottom, top = Pass("bottom", 0.0, 0.0, 2.0, 100.0), Pass("top", 0.0, 0.0, 3.0, 100.0)
    machine = Machine(ramp_s=4.0)
    assert cycle_time_s((bottom, top), 0.0, 12.0, machine) == pytest.approx(25.0 + 4.0 + 15.0)
    assert cycle_time_s((), 0.0, 12.0, machine) == pytest.approx(15.0)
