"""Specification of `wrapbench simulate`: exit status, one-line errors, the JSON and the plot."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
from importlib import metadata
from pathlib import Path

import numpy as np
import pytest

from recommender.cli import main
from recommender.search import VERIFY_SEED
from tests.cli import one_line, run
from tests.conftest import TINY_LOAD
from wrapenv.load import LoadUnit
from wrapenv.profile import PulseProfile
from wrapenv.uncertainty import Uncertainty

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"

#: One slender bundle (0.1 x 0.1 x 0.6 m) that cannot slide: it tips over well below 0.5 g
#: (half width / height = 0.17).
TALL_LOAD = {
    "name": "tall",
    "pallet": {"preset": "EUR"},
    "bundle": {"length_m": 0.1, "width_m": 0.1, "height_m": 0.6, "mass_kg": 5.0},
    "stack": {"layers": 1, "pattern": "explicit", "positions": [[0.0, 0.0]]},
    "friction": {"sled_pallet": {"static": 1.5, "kinetic": 1.4},
                 "pallet_bundle": {"static": 1.5, "kinetic": 1.4}},
}

LEVEL_KEYS = {"level_g", "passed", "elastic_max_m", "elastic_max_pct", "permanent_max_m",
              "permanent_max_pct", "permanent_low20_m", "pallet_slip_m", "damage", "criteria",
              "bodies"}
CRITERIA = {"permanent_5pct", "low20_4cm", "elastic_10pct", "no_damage"}


def written(tmp_path) -> list[str]:
    """Every file the run left in tmp_path apart from its inputs."""
    return sorted(p.name for p in tmp_path.iterdir() if p.suffix not in {".toml", ".csv"})


# --- bad input: exit 2, one line naming the file and the field, nothing written ----------------

BAD_LOADS = {
    # id: (changes to the base load of conftest, field named in the message)
    "typo mass_kgs": ({"bundle.mass_kgs": 9.3}, "bundle.mass_kgs"),
    "negative mass": ({"bundle.mass_kg": -1.0}, "bundle.mass_kg"),
    "layers two": ({"stack.layers": "two"}, "stack.layers"),
    "missing bundle": ({"bundle": None}, "bundle"),
    "kinetic above static": (
        {"friction.sled_pallet": {"static": 0.3, "kinetic": 0.4}}, "friction.sled_pallet.kinetic"),
    "unknown pattern": ({"stack.pattern": "spiral"}, "stack.pattern"),
    "overlapping bundles": (
        {"stack.pattern": "explicit", "stack.positions": [[0.0, 0.0], [0.0, 0.1]]},
        "stack.positions"),
    # impossible units (issue 17): taller or heavier than a pallet carries, a speck of a bundle
    "200 layers, 66 m tall": ({"stack.layers": 200}, "stack.layers"),
    "heavier than a pallet carries": ({"bundle.mass_kg": 50.0}, "bundle.mass_kg"),
    "a 1e-9 m bundle": ({"bundle.height_m": 1e-9}, "bundle.height_m"),
}


@pytest.mark.parametrize("changes, field", BAD_LOADS.values(), ids=BAD_LOADS.keys())
def test_bad_load_exits_2_with_one_line_and_writes_nothing(changes, field, load_file, tmp_path,
                                                           capsys):
    path = load_file(changes)
    code = run(["simulate", str(path), "--level", "0.2",
                "--json", str(tmp_path / "out.json"), "--plot", str(tmp_path / "out.png")])
    out, err = capsys.readouterr()
    assert code == 2
    line = one_line(err)
    assert str(path) in line
    assert f": {field}: " in line
    assert written(tmp_path) == []


def test_malformed_load_toml_exits_2_naming_the_file(load_file, tmp_path, capsys):
    path = load_file(text="[pallet\npreset = 'EUR'\n")
    code = run(["simulate", str(path), "--json", str(tmp_path / "out.json")])
    line = one_line(capsys.readouterr().err)
    assert code == 2
    assert str(path) in line and "malformed TOML" in line
    assert written(tmp_path) == []


def test_missing_load_file_exits_2_naming_the_file(tmp_path, capsys):
    path = tmp_path / "absent.toml"
    assert run(["simulate", str(path), "--level", "0.2"]) == 2
    assert str(path) in one_line(capsys.readouterr().err)


def test_load_file_that_is_not_utf8_exits_2(load_file, capsys):
    path = load_file(text=b"name = '\xff'\n")
    assert run(["simulate", str(path), "--level", "0.2"]) == 2
    assert str(path) in one_line(capsys.readouterr().err)


@pytest.mark.parametrize("level", ["nan", "inf", "fast"])
def test_level_that_is_not_a_finite_number_exits_2(level, load_file, capsys):
    code = run(["simulate", str(load_file()), "--level", level])
    assert code == 2
    assert "--level" in one_line(capsys.readouterr().err)


@pytest.mark.parametrize("level", ["5", "1.1", "0", "-0.3"])
def test_level_outside_the_bench_range_exits_2(level, load_file, tmp_path, capsys):
    code = run(["simulate", str(load_file()), "--level", level,
                "--json", str(tmp_path / "out.json")])
    assert code == 2
    assert "level" in one_line(capsys.readouterr().err)
    assert written(tmp_path) == []


def test_one_bad_level_among_several_exits_2_before_running_any(load_file, tmp_path, capsys):
    code = run(["simulate", str(load_file()), "--level", "0.2", "--level", "5",
                "--json", str(tmp_path / "out.json")])
    out, err = capsys.readouterr()
    assert code == 2
    one_line(err)
    assert out == ""
    assert written(tmp_path) == []


def test_a_target_below_the_first_eumos_level_runs_with_a_warning(load_file, capsys):
    assert run(["simulate", str(load_file()), "--target", "0.1"]) in (0, 1)
    out, err = capsys.readouterr()
    assert one_line(err).startswith("wrapbench simulate: warning: a target of 0.1 g lies below "
                                    "EUMOS 40509's first level (0.2 g)")
    assert "0.10 g" in out and "0.20 g" not in out


def test_eumos_target_beyond_the_bench_exits_2(load_file, capsys):
    assert run(["simulate", str(load_file()), "--eumos", "--target", "2.0"]) == 2
    assert "--target" in one_line(capsys.readouterr().err)


def pulse_csv(tmp_path, level_g: float):
    pulse = PulseProfile(level_g)
    t = np.arange(0.0, pulse.duration_s + 0.01, 0.002)
    path = tmp_path / "profile.csv"
    path.write_text("t_s,accel_mps2\n" + "".join(
        f"{ti:.4f},{ai:.6f}\n" for ti, ai in zip(t, pulse.accel(t), strict=True)))
    return path


def test_level_together_with_profile_exits_2(load_file, tmp_path, capsys):
    profile = pulse_csv(tmp_path, 0.2)
    code = run(["simulate", str(load_file()), "--level", "0.3", "--profile", str(profile)])
    assert code == 2
    assert "--profile" in one_line(capsys.readouterr().err)


def test_level_together_with_eumos_exits_2(load_file, capsys):
    assert run(["simulate", str(load_file()), "--level", "0.3", "--eumos"]) == 2
    one_line(capsys.readouterr().err)


def test_bad_profile_csv_exits_2_naming_the_file(load_file, tmp_path, capsys):
    profile = tmp_path / "profile.csv"
    profile.write_text("t_s,accel_mps2\n0,0\n0.1,oops\n")
    assert run(["simulate", str(load_file()), "--profile", str(profile)]) == 2
    line = one_line(capsys.readouterr().err)
    assert str(profile) in line and "line 3" in line


def test_a_calibrated_run_says_which_values_it_put_in_place(load_file, tmp_path, capsys):
    """The calibrated pair as simulated, the pairs it leaves out the load file's; the JSON
    names the file (a run on file must say it was calibrated)."""
    cal, out_json = tmp_path / "cal.json", tmp_path / "verdict.json"
    cal.write_text(json.dumps({"friction": {"pallet_bundle": {"static": 0.41, "kinetic": 0.35}},
                               "wrap": {"stiffness_scale": 1.2, "tension_scale": 0.9}}))
    assert run(["simulate", str(load_file(base=TINY_LOAD)), "--level", "0.2", "--calibration",
                str(cal), "--json", str(out_json)]) == 0
    out = capsys.readouterr().out
    assert (f"calibrated by {cal}: friction (static / kinetic) pallet_bundle 0.410 / 0.350"
            in out)
    assert "web stiffness" not in out, "an unwrapped unit has no web to scale"
    assert json.loads(out_json.read_text())["calibration"] == str(cal)


def test_a_pair_a_calibration_only_bounds_is_not_credited_to_it(load_file, tmp_path, capsys):
    """A pair that never slipped in the recordings keeps the load file's friction above the
    bound CAL.json gives (the default sled-pallet 0.45 / 0.34 here), and the bound where the
    load file's is lower."""
    cal = tmp_path / "cal.json"
    cal.write_text(json.dumps({"friction": {
        "sled_pallet": {"static": 0.1125, "kinetic": 0.1, "identified": False},
        "pallet_bundle": {"static": 0.9, "kinetic": 0.8, "identified": False}}}))
    assert run(["simulate", str(load_file(base=TINY_LOAD)), "--level", "0.2", "--calibration",
                str(cal)]) == 0
    out = capsys.readouterr().out
    assert ("sled_pallet 0.450 / 0.340 (not identified: the load file's, above CAL.json's "
            "bound 0.113)") in out
    assert "pallet_bundle 0.900 / 0.800 (not identified: CAL.json's lower bound)" in out


def test_bad_calibration_exits_2_naming_the_file_and_field(load_file, tmp_path, capsys):
    cal = tmp_path / "CAL.json"
    cal.write_text(json.dumps({"friction": {"sled_pallet": {"static": 0.3, "kinetic": 0.5}}}))
    assert run(["simulate", str(load_file()), "--calibration", str(cal), "--level", "0.2"]) == 2
    line = one_line(capsys.readouterr().err)
    assert str(cal) in line and "friction.sled_pallet.kinetic" in line


def test_malformed_calibration_exits_2_naming_the_file(load_file, tmp_path, capsys):
    cal = tmp_path / "CAL.json"
    cal.write_text("{not json")
    assert run(["simulate", str(load_file()), "--calibration", str(cal), "--level", "0.2"]) == 2
    assert str(cal) in one_line(capsys.readouterr().err)


@pytest.mark.parametrize("argv", [
    ["simulate", "LOAD", "--levle", "0.2"],
    ["simulate", "LOAD", "--orientation", "diagonal"],
    ["simulate"],
    ["simulat", "LOAD"],
    [],
    ["simulate", "LOAD", "--lev", "0.2"],
], ids=["unknown option", "bad orientation", "missing load", "unknown command", "no command",
        "abbreviated option (a script must not change meaning when a flag is added)"])
def test_usage_error_exits_2_with_one_line(argv, load_file, capsys):
    path = str(load_file())
    assert run([path if a == "LOAD" else a for a in argv]) == 2
    assert one_line(capsys.readouterr().err).startswith("wrapbench")


@pytest.mark.parametrize("argv, says", [
    (["--level", "0.2", "0.3"], "wrapbench simulate: error: unrecognized arguments: 0.3 "
                                "(--level takes one value: give the flag once for each value)"),
    (["--lev", "0.2"], "wrapbench simulate: error: unrecognized arguments: --lev 0.2"),
], ids=["two values after --level", "an abbreviated flag"])
def test_words_no_option_took_are_reported_by_their_command(argv, says, load_file, capsys):
    assert run(["simulate", str(load_file()), *argv]) == 2
    assert one_line(capsys.readouterr().err) == says


@pytest.mark.parametrize("argv, field", [
    (["--level", "0.2", "--target", "0.9"], "--target"),
    (["--level", "0.2", "--start", "0.6"], "--start"),
    (["--level", "0.2", "--hours-since-wrapping", "16"], "--hours-since-wrapping"),
], ids=["target with levels", "start with levels", "hours without a wrap"])
def test_a_flag_the_run_would_ignore_is_refused(argv, field, load_file, capsys):
    """Each used to be ignored without a word: the run looked like the one asked for."""
    assert run(["simulate", str(load_file()), *argv]) == 2
    err = one_line(capsys.readouterr().err)
    assert field in err


@pytest.mark.parametrize("argv, field", [
    (["--hours-since-wrapping", "-1"], "--hours-since-wrapping"),
    (["--hours-since-wrapping", "1e9"], "hours, not seconds or minutes"),
    (["--layer-shift-limit-pct", "0"], "--layer-shift-limit-pct"),
    (["--layer-shift-limit-pct", "101"], "--layer-shift-limit-pct"),
    (["--layer-shift-limit-pct", "nan"], "--layer-shift-limit-pct"),
])
def test_bad_hours_or_layer_shift_limit_exits_2_naming_the_flag(argv, field, load_file,
                                                                 tmp_path, capsys):
    out = tmp_path / "out.json"
    assert run(["simulate", str(load_file()), "--level", "0.2", *argv, "--json", str(out)]) == 2
    err = one_line(capsys.readouterr().err)
    assert field in err and not out.exists()


@pytest.mark.parametrize("argv, says", [
    (["simulate", "LOAD", "--level", "0.2", "--layer-shift-limit-pct", "0.02"],
     "(got 0.02): a fraction? The flag is in percent (vendors quote 2)"),
    (["recommend", "LOAD", "--margin", "20"], "(got 20.0): a fraction (0.2 for 20 %)"),
])
def test_a_fraction_given_for_a_percentage_or_the_other_way_is_named(argv, says, load_file,
                                                                     capsys):
    path = str(load_file())
    assert run([path if a == "LOAD" else a for a in argv]) == 2
    assert one_line(capsys.readouterr().err).endswith(says)


def test_a_single_level_is_not_described_as_a_sequence(load_file, capsys):
    assert run(["simulate", str(load_file(base=TINY_LOAD)), "--level", "0.2"]) == 0
    printed = capsys.readouterr().out
    assert "(one level, on the unit as stacked)" in printed    # unwrapped: not "and wrapped"
    assert "through the levels" not in printed


@pytest.mark.parametrize("fresh", [False, True], ids=["cumulative", "fresh"])
def test_repeated_levels_run_one_unit_unless_fresh_and_report_the_sequence(fresh, load_file,
                                                                           tmp_path, capsys):
    out = tmp_path / "verdict.json"
    argv = ["simulate", str(load_file(base=TINY_LOAD)), "--level", "0.2", "--level", "0.2",
            "--layer-shift-limit-pct", "2", "--json", str(out)] + (["--fresh"] if fresh else [])
    assert run(argv) == 0
    printed = capsys.readouterr().out
    verdict = json.loads(out.read_text())
    assert verdict["sequence"] == ("fresh" if fresh else "cumulative")
    assert f"sequence: {verdict['sequence']}" in printed
    assert "layer shift <= 9.5 mm (2 % of height)" in printed  # 2 % of 0.474 m
    for level in verdict["levels"]:
        assert {"permanent_total_max_m", "permanent_total_max_pct", "layer_shift_max_m",
                "layer_shift_max_pct"} <= set(level)
        assert set(level["criteria"]) == CRITERIA | {"layer_shift"}
        assert level["permanent_total_max_m"] >= 0 and level["layer_shift_max_m"] >= 0
    if fresh:  # the same fresh unit twice (the carried unit: tests/wrapenv/test_sequence.py)
        assert verdict["levels"][0] == verdict["levels"][1]


@pytest.mark.parametrize("flag, name", [("--json", "out.json"), ("--plot", "out.png")])
def test_output_into_a_missing_folder_exits_2(flag, name, load_file, tmp_path, capsys):
    target = tmp_path / "no" / "such" / "folder" / name
    code = run(["simulate", str(load_file()), "--level", "0.2", flag, str(target)])
    out, err = capsys.readouterr()
    assert code == 2
    line = one_line(err)
    assert flag in line and name in line
    assert out == "", "the check must come before any simulation"
    assert not (tmp_path / "no").exists()


def test_bad_input_as_a_separate_process_exits_2_without_traceback(load_file, tmp_path):
    path = load_file({"bundle.mass_kgs": 9.3})
    proc = subprocess.run(
        [sys.executable, "-m", "recommender.cli", "simulate", str(path), "--level", "0.2",
         "--json", str(tmp_path / "out.json")],
        capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert proc.returncode == 2
    line = one_line(proc.stderr)
    assert str(path) in line and "bundle.mass_kgs" in line
    assert proc.stdout == ""
    assert written(tmp_path) == []


def test_a_reader_that_stops_reading_ends_the_run_without_traceback(load_file, tmp_path):
    """`wrapbench simulate ... | head -2`: head closes the pipe, and the run used to end in a
    BrokenPipeError's traceback. It ends as a Unix tool does on SIGPIPE."""
    path = load_file(base=TINY_LOAD)
    proc = subprocess.Popen(
        [sys.executable, "-m", "recommender.cli", "simulate", str(path), "--level", "0.2"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=tmp_path)
    proc.stdout.close()     # the reader is gone before the table is printed
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + signal.SIGPIPE
    assert err == b""


def _idle_worker(parent_pid: int) -> None:
    """A worker waiting for work that never comes, with the signals of the pools' workers."""
    import time

    from wrapenv.pool import _worker_signals

    _worker_signals(parent_pid)
    while True:
        time.sleep(1)


def test_an_interrupted_command_leaves_no_worker_behind(monkeypatch, load_file, capsys):
    """Python joins every child process at exit: one left running kept an interrupted search
    waiting at its exit forever (seen once in the suite, an idle worker its pool had not
    stopped)."""
    import multiprocessing

    from recommender import recommend

    worker = multiprocessing.get_context("fork").Process(target=_idle_worker,
                                                           args=(os.getpid(),))

    def interrupted(args):
        worker.start()
        raise KeyboardInterrupt

    monkeypatch.setattr(recommend, "run_recommend", interrupted)
    assert main(["recommend", str(load_file())]) == 130
    assert not worker.is_alive() and worker.exitcode is not None
    assert "interrupted, nothing written" in capsys.readouterr().err


def test_version_is_the_installed_distribution_s(capsys):
    with pytest.raises(SystemExit) as stop:
        main(["--version"])
    assert stop.value.code == 0
    assert capsys.readouterr().out.strip() == f"wrapbench {metadata.version('wrapbench')}"


def test_usage_error_as_a_separate_process_exits_2_without_traceback(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "recommender.cli", "simulate", "--no-such-option"],
        capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert proc.returncode == 2
    one_line(proc.stderr)


# --- runs that complete: exit 0 on pass, 1 on failure; JSON and PNG as in CONTRACTS.md -----------


def test_passing_level_exits_0_and_writes_the_contract_json_and_a_png(load_file, tmp_path,
                                                                      capsys):
    path = load_file(base=TINY_LOAD)
    out_json, out_png = tmp_path / "verdict.json", tmp_path / "plot.png"
    code = run(["simulate", str(path), "--level", "0.2",
                "--json", str(out_json), "--plot", str(out_png)])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "tiny" in out
    assert out.splitlines()[-1] == f"wrote {out_json}, {out_png}"   # as synth and track say

    verdict = json.loads(out_json.read_text())
    assert {"valid", "load_height_m", "levels", "highest_passed_g"} <= set(verdict)
    assert verdict["orientation"] == "long"     # as the file lays it out: length along x
    assert verdict["wrapbench_version"] == metadata.version("wrapbench")
    assert verdict["valid"] is True
    assert verdict["load_height_m"] == pytest.approx(0.144 + 0.33)
    assert verdict["highest_passed_g"] == pytest.approx(0.2)
    assert len(verdict["levels"]) == 1
    level = verdict["levels"][0]
    assert LEVEL_KEYS <= set(level)
    assert level["level_g"] == pytest.approx(0.2)
    assert level["passed"] is True
    assert level["damage"] == []
    assert set(level["criteria"]) == CRITERIA
    assert all(v is True for v in level["criteria"].values())
    for key in ("elastic_max_m", "permanent_max_m", "permanent_low20_m", "pallet_slip_m",
                "elastic_max_pct", "permanent_max_pct"):
        assert isinstance(level[key], int | float) and level[key] >= 0, key
    assert level["permanent_max_m"] <= level["elastic_max_m"] + 1e-6
    assert sorted(b["name"] for b in level["bodies"]) == ["L1C1R1", "L1C2R1"]
    for body in level["bodies"]:
        assert {"name", "permanent_m", "elastic_max_m"} <= set(body)

    assert out_png.read_bytes()[:8] == PNG_MAGIC
    assert sorted(written(tmp_path)) == ["plot.png", "verdict.json"], "no temporary files left"


def test_measured_profile_is_reported_at_its_peak_level(load_file, tmp_path, capsys):
    path = load_file(base=TINY_LOAD)
    profile = pulse_csv(tmp_path, 0.2)
    out_json = tmp_path / "verdict.json"
    code = run(["simulate", str(path), "--profile", str(profile), "--json", str(out_json)])
    assert code == 0, capsys.readouterr().err
    levels = json.loads(out_json.read_text())["levels"]
    assert len(levels) == 1
    assert levels[0]["level_g"] == pytest.approx(0.2, abs=1e-3)


def test_load_that_tips_over_exits_1_and_reports_the_failure(load_file, tmp_path, capsys):
    path = load_file(base=TALL_LOAD)
    out_json = tmp_path / "verdict.json"
    code = run(["simulate", str(path), "--level", "0.5", "--json", str(out_json)])
    out, err = capsys.readouterr()
    assert code == 1, err
    assert err == ""
    verdict = json.loads(out_json.read_text())
    level = verdict["levels"][0]
    assert level["level_g"] == pytest.approx(0.5)
    assert level["passed"] is False
    assert not all(level["criteria"].values())
    assert verdict["highest_passed_g"] is None


def test_without_a_level_simulate_runs_the_eumos_sequence_to_its_first_failure(load_file,
                                                                               tmp_path):
    """0.2 g up by 0.1 g to the target (0.5 g), one unit through the levels, ending at the first
    level failed: the two bundles slide off at 0.4 g (static friction 0.30), so 0.5 g is not
    run."""
    path, out = load_file(base=TINY_LOAD), tmp_path / "verdict.json"
    assert run(["simulate", str(path), "--json", str(out)]) == 1
    verdict = json.loads(out.read_text())
    assert [v["level_g"] for v in verdict["levels"]] == pytest.approx([0.2, 0.3, 0.4])
    assert verdict["highest_passed_g"] == pytest.approx(0.3)
    assert verdict["sequence"] == "cumulative"
    # a target off the 0.1 g steps is the last level all the same
    assert run(["simulate", str(path), "--start", "0.15", "--target", "0.28", "--json",
                str(out)]) == 0
    assert [v["level_g"] for v in json.loads(out.read_text())["levels"]] == pytest.approx(
        [0.15, 0.25, 0.28])


# --- wrapped units: simulate --wrap ---------------------------------------------------------

WRAP_TEXT = """material = "kraft"
web_width_m = 0.5
[[band]]
from_m = 0.0
to_m = 0.45
layers = {layers}
tension_n = {tension}
"""

BAD_WRAPS = {
    # id: (band values, field named in the message)
    "band above the load": (dict(to_m=0.9), "band[0].to_m"),
    "layers not whole": (dict(layers=2.5), "band[0].layers"),
    "layers negative": (dict(layers=-1), "band[0].layers"),
    "tension zero": (dict(tension=0.0), "band[0].tension_n"),
    "tension beyond the web": (dict(tension=5000.0), "band[0].tension_n"),
}


def wrap_file(tmp_path, layers=2, tension=250.0, to_m=0.45):
    text = WRAP_TEXT.format(layers=layers, tension=tension).replace("to_m = 0.45",
                                                                    f"to_m = {to_m}")
    path = tmp_path / "wrap.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("values, field", BAD_WRAPS.values(), ids=BAD_WRAPS.keys())
def test_bad_wrap_exits_2_with_one_line_and_writes_nothing(values, field, load_file, tmp_path,
                                                           capsys):
    load = load_file(base=TINY_LOAD)  # 0.474 m tall
    wrap = wrap_file(tmp_path, **values)
    code = run(["simulate", str(load), "--wrap", str(wrap), "--level", "0.2",
                "--json", str(tmp_path / "out.json")])
    line = one_line(capsys.readouterr().err)
    assert code == 2
    assert str(wrap) in line and f": {field}: " in line
    assert written(tmp_path) == []


def test_missing_wrap_file_exits_2_naming_it(load_file, tmp_path, capsys):
    code = run(["simulate", str(load_file(base=TINY_LOAD)), "--wrap", str(tmp_path / "no.toml")])
    assert code == 2
    assert "no.toml" in one_line(capsys.readouterr().err)


def test_wrapped_run_reports_the_bands_and_the_web_a_machine_lays_for_them(load_file,
                                                                         tmp_path, capsys):
    load = load_file(base=TINY_LOAD)
    out_json = tmp_path / "verdict.json"
    code = run(["simulate", str(load), "--wrap", str(wrap_file(tmp_path)), "--level", "0.3",
                "--json", str(out_json)])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "material used" in out and "cycle time" in out
    assert "warning" in err and "band[0]" in err  # 0.45 m of paper on a 0.5 m web
    verdict = json.loads(out_json.read_text())
    assert verdict["format"]["material"] == "kraft"
    assert verdict["format"]["bands"][0]["layers"] == 2
    # 2 full-width revolutions: 0.144 m round the pallet (perimeter 4.0 m), then 0.356 m round
    # the two bundles (outline 0.68 x 0.19 m, perimeter 1.74 m; the web above the 0.474 m load
    # folds over its edge); kraft is 0.09 kg/m²
    used = verdict["material_used"]
    area = 2 * (0.144 * 4.0 + 0.356 * 1.74)
    assert used["area_m2"] == pytest.approx(area, rel=1e-3)
    assert used["mass_kg"] == pytest.approx(area * 0.09, rel=1e-3)
    assert used["revolutions"] == 2
    wrap = verdict["levels"][0]["wrap"]
    assert wrap["torn"] is False and 0 < wrap["peak_utilisation"] < 1


def test_a_program_is_simulated_as_the_bands_its_web_lays(load_file, tmp_path, capsys):
    load = load_file(base=TINY_LOAD)
    out_json = tmp_path / "verdict.json"
    code = run(["simulate", str(load), "--wrap", str(EXAMPLES / "program_kraft_default.toml"),
                "--level", "0.3", "--json", str(out_json)])
    out, err = capsys.readouterr()
    assert code in (0, 1) and err == ""  # (the paper tears at 800 N on this unit: issue 12)
    assert "wrapping program" in out and "spiral up" in out and "pallets/h" in out
    verdict = json.loads(out_json.read_text())
    assert verdict["format"]["program"]["bottom_wraps"] == 3
    assert verdict["format"]["bands"][0] == {"from_m": 0.0, "to_m": 0.474, "layers": 3,
                                             "tension_n": 800.0}
    assert verdict["material_used"]["revolutions"] == pytest.approx(6.0 + 0.024 / 0.25)
    assert verdict["cycle_time_s"] == pytest.approx(6.096 * 5 + 3.0 + 15.0)  # 3 s of ramps
    assert verdict["pallets_per_hour"] == pytest.approx(3600 / verdict["cycle_time_s"], rel=1e-3)


def test_a_wrapped_run_says_how_old_the_wrap_was_and_the_panel_s_pre_stretch(load_file,
                                                                             tmp_path, capsys):
    """16 h after wrapping LLDPE keeps 0.74 + 0.18 e^(-16/0.5) + 0.08 e^(-16/72) = 80.4 % of
    its tension (docs/materials.md, L5): the table says so, the JSON says it of the bands it
    simulated, and the program's header names the pre-stretch the operator sets (250 %)."""
    out_json = tmp_path / "verdict.json"
    code = run(["simulate", str(load_file(base=TINY_LOAD)), "--wrap",
                str(EXAMPLES / "program_lldpe_default.toml"), "--level", "0.2",
                "--hours-since-wrapping", "16", "--json", str(out_json)])
    out, err = capsys.readouterr()
    assert code == 0, err
    kept = 0.74 + 0.18 * math.exp(-16.0 / 0.5) + 0.08 * math.exp(-16.0 / 72.0)
    assert "LLDPE cast stretch film (applied), web 0.50 m, pre-stretch 250 %, 12 rpm" in out
    assert f"wrap tested 16 h after wrapping: its tension {kept:.0%} of what was laid" in out
    wrap = json.loads(out_json.read_text())["format"]
    assert wrap["hours_since_wrapping"] == 16 and wrap["tension_retained"] == round(kept, 4)
    laid = wrap["program"]["bottom_tension_n"]
    assert wrap["bands"][0]["tension_n"] == pytest.approx(laid * kept, abs=0.01)


def test_paper_asked_to_rope_exits_2_naming_the_field(load_file, tmp_path, capsys):
    text = (EXAMPLES / "program_kraft_default.toml").read_text() + "roping = true\n"
    wrap = tmp_path / "roped.toml"
    wrap.write_text(text)
    code = run(["simulate", str(load_file(base=TINY_LOAD)), "--wrap", str(wrap),
                "--json", str(tmp_path / "out.json")])
    assert code == 2 and ": program.roping: " in one_line(capsys.readouterr().err)
    assert not (tmp_path / "out.json").exists()


def test_nothing_passed_counts_only_slow_candidates_as_over_the_limit():
    """Candidates heavier than a pass are not simulated either; they are not slow."""
    from types import SimpleNamespace

    from recommender.recommend import _nothing_passed

    settings = SimpleNamespace(max_cycle_s=40.0, targets=(("long", 0.5),), margin_goal=0.2,
                               samples=3)
    history = [SimpleNamespace(cycle_s=c, passed=p)
               for c, p in ((35.0, (False,)), (38.0, ()), (45.0, ()))]
    state = SimpleNamespace(history=history, to_verify=lambda goal: [])
    text = _nothing_passed(state, settings, 1, 8)
    assert text.endswith("after 3 candidates x 3 samples, 1 of them over the cycle-time limit")


def test_a_search_pass_that_fails_a_verification_sample_is_not_recommended(monkeypatch):
    """With --samples 2 the search's pass held in its two samples and in 3 of the 8 of its
    verification, and was recommended, exit 0 (a user, 2026-11-26); a policy's proposal had to
    pass all 8. A search's must now too: the next pass is verified, and if none holds, the
    message says the search's passes failed their verification."""
    from types import SimpleNamespace

    from recommender import search
    from recommender.recommend import _nothing_passed, _verified
    from wrapenv.uncertainty import PassProbability

    def holding(problem, wrap, samples, workers=1):
        # the fragile pass fails a sample (no nominal run fails), the sturdy one holds
        sturdy = search.Verification({}, PassProbability(samples, samples), None)
        return {"fragile": None, "sturdy": sturdy}[wrap]

    monkeypatch.setattr(search, "holding", holding)
    problem = SimpleNamespace(settings=SimpleNamespace(margin_goal=0.2))
    fragile, sturdy = SimpleNamespace(wrap="fragile"), SimpleNamespace(wrap="sturdy")
    both = SimpleNamespace(to_verify=lambda goal: [fragile, sturdy])
    assert _verified(problem, both, 8, 1)[0] is sturdy
    alone = SimpleNamespace(to_verify=lambda goal: [fragile], history=[fragile])
    assert _verified(problem, alone, 8, 1) is None
    settings = SimpleNamespace(margin_goal=0.2, max_cycle_s=40.0, targets=(("long", 0.5),),
                               samples=2)
    assert _nothing_passed(alone, settings, 1, 8).startswith(
        "no program recommended: the 1 lightest of the 1 programs that passed the search's 2 "
        "samples failed their verification")


@pytest.mark.parametrize("command, flags", [
    ("simulate", ["--level", "0.2", "--json", "X", "--plot", "X"]),
    ("recommend", ["--json", "X", "--wrap-out", "X"]),
])
def test_two_outputs_on_one_file_are_refused_before_any_simulation(command, flags, load_file,
                                                                  tmp_path, capsys):
    same = str(tmp_path / "same")
    assert run([command, str(load_file()), *[same if f == "X" else f for f in flags]]) == 2
    err = one_line(capsys.readouterr().err)
    assert "is also --json" in err and not (tmp_path / "same").exists()


@pytest.mark.parametrize("flag", ["--json", "--wrap-out"])
@pytest.mark.parametrize("where, says", [
    ("LOAD", "is an input"),
    ("FOLDER", "is a folder"),
    ("MISSING", "the folder to write into does not exist"),
])
def test_each_output_of_recommend_is_refused_before_any_simulation(flag, where, says, load_file,
                                                                   tmp_path, capsys):
    """Each output is checked under its own flag before the search starts: the load file itself
    (which the answer would overwrite), a folder, a folder that does not exist (and --json's
    checkpoint, kept beside it, is not the one named)."""
    load = load_file()
    path = {"LOAD": load, "FOLDER": tmp_path, "MISSING": tmp_path / "no" / "out"}[where]
    before = load.read_bytes()
    assert run(["recommend", str(load), flag, str(path)]) == 2
    out, err = capsys.readouterr()
    line = one_line(err)
    assert f": {flag}: {says}" in line and out == ""
    assert load.read_bytes() == before and not (tmp_path / "no").exists()


def test_a_report_folder_that_is_a_file_is_refused_before_any_simulation(load_file, tmp_path,
                                                                        capsys):
    notes = tmp_path / "notes.txt"
    notes.write_text("my lab notes\n")
    assert run(["recommend", str(load_file()), "--report", str(notes)]) == 2
    out, err = capsys.readouterr()
    assert ": --report: exists and is not a folder" in one_line(err) and out == ""
    assert notes.read_text() == "my lab notes\n"


def test_a_checkpoint_path_holding_a_user_s_file_is_refused_before_any_simulation(
        load_file, tmp_path, capsys):
    """The search would overwrite it, then remove it once it answered."""
    notes = tmp_path / "notes.txt"
    notes.write_text("my lab notes\n")
    assert run(["recommend", str(load_file()), "--checkpoint", str(notes)]) == 2
    err = one_line(capsys.readouterr().err)
    assert "notes.txt" in err and "--checkpoint" in err and "not a wrapbench checkpoint" in err
    assert notes.read_text() == "my lab notes\n"


# --- --samples: the levels asked, in samples of what the bench does not know -----------------

#: One PET bundle (0.33 m tall) on a pallet held by the stop bar, pallet-bundle static 0.50:
#: every sample draws it within 5 standard deviations (0.03) of that, 0.35-0.65, but for one
#: in 1.7 million.
ONE_BUNDLE = {
    "name": "one bundle",
    "pallet": {"preset": "EUR"},
    "bundle": {"preset": "PET6x1.5L"},
    "stack": {"layers": 1, "pattern": "explicit", "positions": [[0.0, 0.0]]},
    "friction": {"pallet_bundle": {"static": 0.5, "kinetic": 0.42}},
    "fixture": {"pallet_stopper": True},
}


def samples_json(load_file, tmp_path, level: str, *flags: str) -> tuple[int, dict]:
    out = tmp_path / f"samples-{level}-{'-'.join(flags)}.json"
    code = run(["simulate", str(load_file(base=ONE_BUNDLE)), "--level", level,
                "--samples", "3", "--json", str(out), *flags])
    return code, json.loads(out.read_text())


def test_samples_below_every_drawn_friction_all_pass_and_above_it_all_fail(load_file, tmp_path,
                                                                        capsys):
    """At 0.3 g the pallet passes the bundle 0.3 g, below every drawn static coefficient
    (>= 0.35): it sticks in every sample. At 0.8 g, above every one (<= 0.65), it slides in
    every sample, at least 0.15 g relative to the pallet (kinetic <= static) through the
    0.5 s hold: >= 0.5 x 1.47 m/s² x (0.5 s)² = 0.18 m, past 5 % of its 0.33 m height."""
    code, low = samples_json(load_file, tmp_path, "0.3")
    assert code == 0
    assert low["samples"]["pass_probability"] | {"low95": 0, "high95": 0} == {
        "estimate": 1.0, "passed": 3, "samples": 3, "low95": 0, "high95": 0}
    code, high = samples_json(load_file, tmp_path, "0.8")
    assert code == 1
    assert high["samples"]["pass_probability"]["passed"] == 0
    worst = high["samples"]["worst"]
    assert worst["margin"] < 0 and worst["level"]["permanent_max_m"] > 0.0165
    drawn = worst["sample"]["friction"]["pallet_bundle"]
    assert 0.35 < drawn["static"] < 0.65 and drawn["kinetic"] <= drawn["static"]
    printed = capsys.readouterr().out
    # Wilson's 95 % interval of 3 passes in 3: centre (1 + z²/6) / (1 + z²/3) = 0.719, half
    # z / (1 + z²/3) x sqrt(z²/36) = 0.281 (z = 1.96), so 44 %-100 %; of none in 3, 0 %-56 %
    assert ("samples: passes in 3 of 3 samples of what the bench does not know (friction, "
            "bundle mass; seed 0): pass probability 100%, 95 % interval 44%-100%") in printed
    assert ("samples: passes in 0 of 3 samples of what the bench does not know (friction, "
            "bundle mass; seed 0): pass probability 0%, 95 % interval 0%-56%") in printed


def test_samples_are_the_same_for_a_seed_however_many_workers_run_them(load_file, tmp_path):
    _, first = samples_json(load_file, tmp_path, "0.5", "--workers", "1")
    _, again = samples_json(load_file, tmp_path, "0.5", "--workers", "2")
    _, other = samples_json(load_file, tmp_path, "0.5", "--seed", "1")
    assert first == again
    assert first["samples"]["seed"] == 0 and other["samples"]["seed"] == 1
    assert other["samples"]["worst"]["sample"] != first["samples"]["worst"]["sample"]
    # recommend's verification draws its k-th sample from VERIFY_SEED + seed + k: so do these
    load = LoadUnit.from_dict(ONE_BUNDLE)
    assert [Uncertainty.of(None, 0.0).draw(load, VERIFY_SEED + 1 + k).to_json()
            for k in range(3)].count(other["samples"]["worst"]["sample"]) == 1
    # the nominal run is the run without samples
    nominal = tmp_path / "nominal.json"
    run(["simulate", str(load_file(base=ONE_BUNDLE)), "--level", "0.5", "--json", str(nominal)])
    assert {k: v for k, v in first.items() if k != "samples"} == json.loads(nominal.read_text())


def test_levels_given_all_run_after_one_fails_in_the_nominal_run_and_in_each_sample(load_file,
                                                                                  tmp_path):
    """--level runs the levels named, each one (only the EUMOS sequence ends at its first
    failure): a fresh bundle falls off at 0.8 g and another meets 0.3 g, in the nominal run and
    in one sample, whose record is of the last level it ran."""
    out = tmp_path / "out.json"
    assert run(["simulate", str(load_file(base=ONE_BUNDLE)), "--level", "0.8", "--level", "0.3",
                "--fresh", "--samples", "1", "--json", str(out)]) == 1
    verdict = json.loads(out.read_text())
    assert [(v["level_g"], v["passed"]) for v in verdict["levels"]] == [(0.8, False),
                                                                       (0.3, True)]
    assert verdict["samples"]["pass_probability"]["samples"] == 1
    assert verdict["samples"]["worst"]["level"]["level_g"] == 0.3


@pytest.mark.parametrize("argv, field", [
    (["--samples", "0"], "--samples"),
    (["--samples", "2", "--workers", "0"], "--workers"),
    (["--seed", "1"], "--seed"),
    (["--workers", "2"], "--workers"),
], ids=["no samples", "no workers", "seed without samples", "workers without samples"])
def test_bad_sampling_flags_exit_2_naming_the_flag_before_any_simulation(argv, field, load_file,
                                                                         tmp_path, capsys):
    out = tmp_path / "out.json"
    assert run(["simulate", str(load_file()), "--level", "0.2", *argv, "--json", str(out)]) == 2
    assert field in one_line(capsys.readouterr().err) and not out.exists()


def test_samples_are_drawn_about_a_calibration_within_its_spreads(load_file, tmp_path):
    """A calibrated pair is drawn about the calibration's value within its standard deviation
    (0.002 here, where the documented default is 0.03); the wrap's scales about its own."""
    cal = tmp_path / "cal.json"
    cal.write_text(json.dumps({
        "friction": {"pallet_bundle": {"static": 0.41, "kinetic": 0.35, "static_std": 0.002,
                                       "kinetic_std": 0.002}},
        "wrap": {"stiffness_scale": 1.2, "stiffness_scale_std": 0.01, "tension_scale": 0.9,
                 "tension_scale_std": 0.01}}))
    wrap = tmp_path / "wrap.toml"
    wrap.write_text("material = 'kraft'\nweb_width_m = 0.5\n[program]\nbottom_wraps = 1\n"
                    "bottom_tension_n = 300.0\nup_overlap = 0.0\nmiddle_tension_n = 300.0\n"
                    "top_wraps = 1\ntop_tension_n = 300.0\n")
    out = tmp_path / "out.json"
    assert run(["simulate", str(load_file(base=ONE_BUNDLE)), "--wrap", str(wrap), "--level",
                "0.2", "--calibration", str(cal), "--samples", "2", "--json", str(out)]) == 0
    drawn = json.loads(out.read_text())["samples"]["worst"]["sample"]
    assert drawn["friction"]["pallet_bundle"]["static"] == pytest.approx(0.41, abs=0.01)
    assert drawn["friction"]["pallet_bundle"]["kinetic"] == pytest.approx(0.35, abs=0.01)
    assert drawn["stiffness_scale"] == pytest.approx(1.2, abs=0.05)
    assert drawn["tension_scale"] == pytest.approx(0.9, abs=0.05)
