"""What `wrapbench` prints per level (recommender/text.py): a level of a run that blew up later
is not reported as passed."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from recommender.text import (
    TIGHT_WRAP_HINT,
    conditions_text,
    g_text,
    level_result,
    program_summary,
    program_text,
    verdict_table,
)
from wrapenv.bench import BenchRun
from wrapenv.eumos import LevelVerdict, Verdict
from wrapenv.load import LoadUnit
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
