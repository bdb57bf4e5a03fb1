"""What `wrapbench` prints per level (recommender/text.py): a level of a run that blew up later
is not reported as passed."""

from __future__ import annotations

from dataclasses import replace

from recommender.text import level_result
from wrapenv.eumos import LevelVerdict, Verdict


def level(passed: bool, valid: bool = True) -> LevelVerdict:
    return LevelVerdict(0.3, passed, valid, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, (), {}, ())


def test_each_level_reads_pass_fail_invalid_or_void():
    good, bad, blown = level(True), level(False), level(False, valid=False)
    assert level_result(Verdict(0.8, (good, bad)), good) == "PASS"
    assert level_result(Verdict(0.8, (good, bad)), bad) == "FAIL"
    after_blow_up = Verdict(0.8, (good, replace(blown, level_g=0.4)))
    assert level_result(after_blow_up, good) == "VOID"
    assert level_result(after_blow_up, after_blow_up.levels[1]) == "INVALID"
