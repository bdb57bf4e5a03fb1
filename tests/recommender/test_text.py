"""What `wrapbench` prints per level (recommender/text.py): a level of a run that blew up later
is not reported as passed."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from recommender.text import (
    TIGHT_WRAP_HINT,
    age_text,
    calibration_text,
    conditions_text,
    g_text,
    level_result,
    orientation_tested,
    program_summary,
    program_text,
    rerun_note,
    sample_figures,
    sequence_text,
    verdict_table,
)
from wrapenv.bench import BenchRun
from wrapenv.calibrated import Calibration
from wrapenv.eumos import LevelVerdict, Verdict
from wrapenv.load import LoadUnit
from wrapenv.material import MATERIALS, NO_RELAXATION
from wrapenv.profile import MeasuredProfile, PulseProfile
from wrapenv.program import Program, Reinforcement
from wrapenv.wrap import WrapFormat
from wrapenv.wrap_report import WrapReport


def level(passed: bool, valid: bool = True) -> LevelVerdict:
    return LevelVerdict(0.3, passed, valid, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, (), {}, ())


def test_each_level_reads_pass_fail_invalid_or_void():
    good, bad, blown = level(True), level(False), level(False, valid=False)
    assert level_result(Verdict(0.8, (good, bad)), good) == "PASS"
    assert level_result(Verdict(0.8, (good, bad)), bad) == "FAIL"
    after_blow_up = Verdict(0.8, (good, replace(blown, level_g=0.4)))
    assert level_result(after_blow_up, good) == "VOID"
    assert level_result(after_blow_up, after_blow_up.levels[1]) == "INVALID"


def test_levels_two_decimals_would_merge_keep_a_third():
    """0.495 g passed and 0.5 g failed: a table reading "0.50 PASS, 0.50 FAIL" and "highest
    level passed: 0.50 g" said the opposite (a user, 2026-11-27)."""
    assert [g_text(g) for g in (0.2, 0.5, 0.495, 0.499, 0.8)] == [
        "0.20", "0.50", "0.495", "0.499", "0.80"]
    unit = LoadUnit.from_toml("examples/pet_2layer_columnar.toml")
    run = BenchRun(Verdict(0.804, (replace(level(True), level_g=0.495),
                                   replace(level(False), level_g=0.5))), (), 20)
    lines = verdict_table(unit, run, None).splitlines()
    assert lines[-3].lstrip().startswith("0.495 g  PASS")
    assert lines[-2].lstrip().startswith("0.50 g  FAIL")
    assert lines[-1] == "highest level passed: 0.495 g"
    assert all(line == line.rstrip() for line in lines), "no trailing blanks to copy along"


def test_a_level_that_ended_before_rest_says_why_on_its_line():
    unit = LoadUnit.from_toml("examples/pet_3layer_columnar.toml")
    fell = replace(level(False), criteria={"no_damage": False}, damage=("L3C1R3 fallen",),
                   stopped_early="L3C1R3 fell off the sled")
    table = verdict_table(unit, BenchRun(Verdict(1.134, (fell,)), (), 20), None)
    row = table.splitlines()[-2]
    assert row.lstrip().startswith("0.30 g  FAIL")
    assert row.endswith("damage, L3C1R3 fell off the sled; 1 damaged: L3C1R3 fallen")


def test_a_wrapped_run_that_blew_up_points_at_the_wrap_s_squeeze():
    """README, "What it cannot hold": light bundles under a tight wrap blow the bench up."""
    unit = LoadUnit.from_toml("examples/pet_3layer_columnar.toml")
    blown = replace(level(False, valid=False), invalid_reason="a body exceeded 6.4 m/s")
    wrapped = replace(blown, wrap=WrapReport((), 0.5, 0.0))
    for v, hinted in ((blown, False), (wrapped, True)):
        last = verdict_table(unit, BenchRun(Verdict(1.134, (v,)), (), 20), None).splitlines()[-1]
        assert "simulation became unphysical" in last
        assert (TIGHT_WRAP_HINT in last) == hinted


def test_a_spiral_step_gives_the_carriage_speed_a_panel_may_ask_for():
    """A 0.5 m web at 50 % overlap rises 0.25 m a revolution: at 12 rpm the carriage travels
    0.25 x 12 = 3.0 m/min; at 0 % overlap 6.0 m/min (the machine's fastest, 0.1 m/s)."""
    layout = LoadUnit.from_toml("examples/pet_2layer_columnar.toml").layout()
    wrap = WrapFormat.from_toml("examples/program_kraft_default.toml", layout.load_height_m)
    assert wrap.program is not None and wrap.program.up_overlap == 0.5 and wrap.rpm == 12
    spiral = next(line for line in program_text(wrap, layout).splitlines()
                  if "spiral up" in line)
    assert "at 3.0 m/min" in spiral
    untouching = WrapFormat.from_program(wrap.material, 0.5, replace(wrap.program,
                                                                     up_overlap=0.0),
                                         layout.load_height_m)
    assert "at 6.0 m/min" in program_text(untouching, layout)


def test_a_failed_level_names_its_criteria_as_the_limits_line_does():
    failed = replace(level(False), criteria={"elastic_10pct": True, "permanent_5pct": False,
                                             "low20_4cm": False, "no_damage": True})
    row = verdict_table(LoadUnit.from_toml("examples/pet_2layer_columnar.toml"),
                        BenchRun(Verdict(0.804, (failed,)), (), 20), None).splitlines()[-2]
    assert row.endswith("permanent max, lowest 20 cm permanent")


def test_the_test_conditions_name_the_sled_s_motion_the_settling_and_the_solve():
    """What a lab report states besides its figures: the pulse (EUMOS 40509 asks the level to
    be held at least 0.3 s; the bench holds 0.5 s), or the measured profile driven."""
    run = BenchRun(Verdict(0.804, (level(True),)), (), 50)
    pulses = conditions_text([PulseProfile(0.2), PulseProfile(0.3)], run)
    assert pulses == ("sled: the level reached in 0.05 s, held 0.5 s, then braked at 0.25 of it "
                      "to a stop; the unit first settles 0.3 s on the still sled; bench: "
                      "PyBullet, time step 1/240 s, 50 solver iterations")
    measured = MeasuredProfile(np.array([0.0, 0.5, 1.0]), np.array([0.0, 4.905, 0.0]),
                               "lab/profile.csv")
    assert conditions_text([measured], run).startswith(
        "sled: the sled's measured profile lab/profile.csv (1.00 s, peak 0.500 g);")


def test_a_program_s_one_line_summary_names_every_zone_in_the_order_it_is_laid():
    """The benchmarks' tables (benchmarks/programs.py, ppo_vs_cmaes.py) read a program so."""
    program = Program(bottom_wraps=2, bottom_tension_n=300.4, up_overlap=0.25,
                      middle_tension_n=250.0, top_wraps=1, top_tension_n=280.0,
                      down_overlap=0.5, roping=True,
                      reinforcements=(Reinforcement(from_m=0.47, wraps=2, tension_n=320.0),))
    assert program_summary(program) == (
        "2 bottom wraps at 300 N (roped), spiral up 25 % at 250 N, 2 at 0.47 m at 320 N, "
        "1 top wraps at 280 N, spiral down 50 %")


def test_a_sequence_that_passed_no_level_says_none():
    unit = LoadUnit.from_toml("examples/pet_2layer_columnar.toml")
    run = BenchRun(Verdict(unit.load_height_m, (level(False),)), (), 20)
    assert verdict_table(unit, run, None).splitlines()[-1] == "highest level passed: none"


def test_a_program_is_printed_as_an_operator_enters_it_step_by_step():
    """The reinforced film program on the 2-layer unit (0.804 m): the roped bottom wraps at
    0.10 m, spirals at 40 % overlap rising 0.5 x 0.6 = 0.30 m a revolution (3.6 m/min at
    12 rpm), 2 reinforcement wraps at 0.224 m, top wraps whose web ends 0.05 m above the load
    (0.354 + 0.5 = 0.854 m), and the spiral down at 0 % (6.0 m/min). Film pre-stretched 250 %
    leaves the roll 3.5 times shorter than it is laid (32.3 / 3.5 = 9.2 m); 60 s a cycle is
    60 pallets an hour."""
    layout = LoadUnit.from_toml("examples/pet_2layer_columnar.toml").layout()
    wrap = WrapFormat.from_toml("examples/program_lldpe_reinforced.toml", layout.load_height_m)
    used, cycle = wrap.material_used_on(layout), wrap.cycle_time_s
    assert used.roll_length_m == pytest.approx(used.web_length_m / 3.5)
    assert round(3600 / cycle) == 60
    assert program_text(wrap, layout).splitlines() == [
        "wrapping program: LLDPE cast stretch film (applied), web 0.50 m, pre-stretch 250 %, "
        "12 rpm",
        "step  zone           wraps  overlap  carriage (web's lower edge)        tension N",
        "   1  bottom             3        -  0.100 m (roped)                        90.0",
        "   2  spiral up       0.41     40 %  0.100 -> 0.224 m at 3.6 m/min          70.0",
        "   3  reinforcement      2        -  0.224 m                                80.0",
        "   4  spiral up       0.43     40 %  0.224 -> 0.354 m at 3.6 m/min          70.0",
        "   5  top                2        -  0.354 m (web 0.05 m above the load)     80.0",
        "   6  spiral down     0.51      0 %  0.354 -> 0.100 m at 6.0 m/min          70.0",
        f"material used: {used.area_m2:.2f} m² of web ({used.mass_kg:.3f} kg), 32.3 m laid, "
        "9.2 m from the roll, 8.4 revolutions",
        "cycle time: 60 s, 60 pallets/h (12 rpm, 3 s to start and to stop, carriage up to "
        "0.1 m/s, 15 s to change pallets)",
    ]
    # a web of paper is laid as it leaves the roll, and bands are listed as revolutions
    bands = WrapFormat.from_toml("examples/wrap_kraft_2layer.toml", layout.load_height_m)
    text = program_text(bands, layout).splitlines()
    assert text[0] == "bands, laid as: kraft stretch paper, web 0.50 m, 12 rpm"
    assert "from the roll" not in text[-2]


def test_a_level_row_gives_each_figure_in_mm_and_percent_of_the_load_height():
    """12.3 mm elastic on a 0.804 m load is 1.5 %; the row's columns: elastic, permanent
    (this level's, then since the unit was put on), the lowest 20 cm, the layer shift, the
    pallet's slip; five damaged bundles are named four at most."""
    unit = LoadUnit.from_toml("examples/pet_2layer_columnar.toml")
    damaged = tuple(f"L2C{k}R1 toppled" for k in range(1, 6))
    v = LevelVerdict(0.5, False, True, 0.0123, 1.53, 0.0041, 0.51, 0.0, 0.002, damaged,
                     {"no_damage": False}, (), permanent_total_max_m=0.0061,
                     permanent_total_max_pct=0.76, layer_shift_max_m=0.0052,
                     layer_shift_max_pct=0.65)
    row = verdict_table(unit, BenchRun(Verdict(0.804, (v,)), (), 20), None).splitlines()[-2]
    assert row == (" 0.50 g  FAIL      12.3 ( 1.5 %)     4.1    6.1 ( 0.8 %)     0.0     5.2 "
                   "( 0.6 %)     2.0  damage; 5 damaged: L2C1R1 toppled, L2C2R1 toppled, "
                   "L2C3R1 toppled, L2C4R1 toppled, ...")


def test_the_sequence_is_told_in_words():
    one, two = level(True), (level(True), replace(level(True), level_g=0.4))
    wrapped = replace(level(True), wrap=WrapReport((), 0.5, 0.0))
    assert sequence_text(Verdict(0.8, (one,))) == "one level, on the unit as stacked"
    assert sequence_text(Verdict(0.8, (wrapped,))) == (
        "one level, on the unit as stacked and wrapped")
    assert sequence_text(Verdict(0.8, two)) == (
        "one unit through the levels, each from where the last left it")
    assert sequence_text(Verdict(0.8, two, sequence="fresh")) == "a fresh unit for every level"


def test_the_table_names_the_side_of_the_pallet_that_faced_the_motion_and_any_tear():
    """The EUR pallet (1.2 x 0.8 m) as the load file lays it runs along its long side; turned,
    along its short one; a level whose wrap tore is listed."""
    unit = LoadUnit.from_toml("examples/pet_2layer_columnar.toml")
    torn = replace(level(False), wrap=WrapReport((0.4,), 1.0, 0.02))
    run = BenchRun(Verdict(0.804, (level(True), replace(torn, level_g=0.4))), (), 20)
    for orientation, side in ((None, "long side (1.200 m)"), ("short", "short side (0.800 m)")):
        lines = verdict_table(unit, run, orientation).splitlines()
        assert lines[1].endswith(f"motion along the pallet's {side}")
    assert "wrap torn at: 0.40 g" in verdict_table(unit, run, None).splitlines()
    assert orientation_tested(unit, None) == "long"


def test_the_table_counts_one_layer_as_one():
    unit = LoadUnit.from_toml("examples/pet_1layer_columnar.toml")
    first = verdict_table(unit, BenchRun(Verdict(0.474, (level(True),)), (), 20), None)
    assert ": 16 bundles, 1 layer (columnar), load height" in first.splitlines()[0]


def test_the_wrap_s_age_says_what_its_tension_kept():
    """LLDPE keeps 80 % of its laid tension after 24 h (its card's relaxation law); a card
    without a law keeps it all, and says so; 0 h points at the option a lab's test needs."""
    film = MATERIALS["lldpe"]
    assert age_text(film, 24.0) == ("wrap tested 24 h after wrapping: its tension 80% of what "
                                    "was laid (LLDPE cast stretch film (applied) relaxes)")
    rigid = replace(film, name="custom", relaxation=NO_RELAXATION)
    assert age_text(rigid, 24.0).endswith("100% of what was laid (custom does not relax, by "
                                          "its card)")
    assert "--hours-since-wrapping" in age_text(film, 0.0)


def test_a_calibration_names_the_values_it_put_in_place():
    unit = LoadUnit.from_toml("examples/pet_2layer_columnar.toml")
    cal = Calibration({}, stiffness_scale=1.2, tension_scale=0.9, give_scale=0.5)
    assert calibration_text("CAL.json", cal, unit, wrapped=True) == (
        "calibrated by CAL.json: no friction pair; web stiffness x 1.20, laid tension x 0.90; "
        "the load's give x 0.50")
    same_give = replace(cal, give_scale=1.0)
    assert calibration_text("CAL.json", same_give, unit, wrapped=False) == (
        "calibrated by CAL.json: no friction pair")


def test_a_worst_sample_gives_its_two_figures_and_none_that_a_blown_up_run_lacks():
    """A sample whose level blew up has no figures (null in its JSON): "n/a", as the HTML
    report writes it; it printed 0.0 mm, the figure of a unit that did not move."""
    assert sample_figures({"elastic_max_m": 0.0123, "permanent_max_m": 0.0}) == (
        "elastic 12.3 mm, permanent 0.0 mm")
    assert sample_figures({"elastic_max_m": None, "permanent_max_m": None}) == (
        "elastic n/a, permanent n/a")


def test_a_run_made_again_with_more_iterations_says_why_each_count_fell_short():
    run = BenchRun(Verdict(0.804, (level(True),)), (), 200,
                   ((50, "left bodies inside each other"),
                    (100, "crept on under static friction")))
    assert rerun_note(run) == (
        "solved with 200 solver iterations: the squeezed stack (a wrap many times the bundles' "
        "weight) was not solved with fewer (at 50 it left bodies inside each other, at 100 it "
        "crept on under static friction)")
    assert rerun_note(replace(run, unsolved_at=())) == ""
