"""Specification of the sled profiles: the generated bench pulse, EUMOS levels, profile.csv."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from wrapenv.config import InputError
from wrapenv.profile import G, MeasuredProfile, PulseProfile, eumos_levels, target_warnings

DT = 1e-4


def sampled(profile, dt: float = DT) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Time, acceleration and velocity (trapezoidal integral) from before the start to after
    the end."""
    t = np.arange(-0.1, profile.duration_s + 0.2, dt)
    a = profile.accel(t)
    v = np.concatenate([[0.0], np.cumsum((a[1:] + a[:-1]) / 2 * dt)])
    return t, a, v


PULSES = [
    PulseProfile(0.2),
    PulseProfile(0.5),
    PulseProfile(1.0),
    PulseProfile(0.3, ramp_s=0.1, dwell_s=0.3, decel_ratio=0.5),
    PulseProfile(0.8, ramp_s=0.0, dwell_s=0.6, decel_ratio=1.0),
]
PULSE_IDS = [f"{p.level_g}g-ramp{p.ramp_s}-dwell{p.dwell_s}-decel{p.decel_ratio}" for p in PULSES]


# --- the generated pulse -------------------------------------------------------------------


@pytest.mark.parametrize("pulse", PULSES, ids=PULSE_IDS)
def test_pulse_reaches_the_level_at_the_end_of_the_ramp(pulse):
    assert pulse.peak_mps2 == pytest.approx(pulse.level_g * 9.81)
    assert float(pulse.accel(pulse.ramp_s + 1e-9)) == pytest.approx(pulse.level_g * 9.81)
    if pulse.ramp_s > 0:
        half = float(pulse.accel(pulse.ramp_s / 2))
        assert 0 < half < pulse.peak_mps2


@pytest.mark.parametrize("pulse", PULSES, ids=PULSE_IDS)
def test_pulse_holds_the_level_for_the_dwell(pulse):
    t = np.linspace(pulse.ramp_s + 1e-9, pulse.ramp_s + pulse.dwell_s - 1e-9, 200)
    assert np.allclose(pulse.accel(t), pulse.level_g * 9.81)


@pytest.mark.parametrize("pulse", PULSES, ids=PULSE_IDS)
def test_pulse_decelerates_at_decel_ratio_of_the_level_until_the_sled_stops(pulse):
    t, a, _ = sampled(pulse)
    decel = -pulse.decel_ratio * pulse.level_g * 9.81
    assert a.min() == pytest.approx(decel)
    # The last stretch before the stop is the constant deceleration.
    tail = (t > pulse.duration_s - 0.05) & (t < pulse.duration_s - 1e-6)
    assert np.allclose(a[tail], decel)
    assert a.min() >= decel - 1e-9


@pytest.mark.parametrize("pulse", PULSES, ids=PULSE_IDS)
def test_the_braking_ramp_has_the_jerk_of_the_ramp_up(pulse):
    """From the level a down to the deceleration -d at a / ramp_s: (a + d) ramp_s / a long."""
    a, d = pulse.peak_mps2, pulse.decel_ratio * pulse.peak_mps2
    start = pulse.ramp_s + pulse.dwell_s
    if pulse.ramp_s == 0:
        assert float(pulse.accel(start + 1e-9)) == pytest.approx(-d)
        return
    for share in (0.25, 0.5, 0.75):
        dt = share * pulse.ramp_s * (a + d) / a
        assert float(pulse.accel(start + dt)) == pytest.approx(a - a / pulse.ramp_s * dt)


@pytest.mark.parametrize("pulse", PULSES, ids=PULSE_IDS)
def test_sled_velocity_returns_to_rest_at_the_end_and_never_reverses(pulse):
    t, a, v = sampled(pulse)
    peak_v = v.max()
    assert peak_v > pulse.level_g * 9.81 * pulse.dwell_s * 0.99
    at_end = np.interp(pulse.duration_s, t, v)
    assert abs(at_end) < 1e-3 * peak_v
    assert v.min() > -1e-3 * peak_v
    # At rest after the end: no acceleration, velocity stays put.
    after = t > pulse.duration_s + 1e-6
    assert np.all(a[after] == 0.0)
    assert np.ptp(v[after]) < 1e-9


@pytest.mark.parametrize("pulse", PULSES, ids=PULSE_IDS)
def test_pulse_is_zero_before_it_starts(pulse):
    assert np.all(pulse.accel(np.array([-1.0, -0.01, -1e-9])) == 0.0)


def test_sled_stops_after_the_deceleration_phase():
    pulse = PulseProfile(0.5)
    # 0.25 x the level stops the sled in about 4 x the time spent at the level.
    stopping = pulse.duration_s - pulse.ramp_s - pulse.dwell_s
    assert 3.5 * pulse.dwell_s < stopping < 4.5 * pulse.dwell_s + 2 * pulse.ramp_s


def test_pulse_defaults_follow_eumos_and_the_estl_bench():
    pulse = PulseProfile(0.5)
    assert pulse.dwell_s >= 0.3
    assert pulse.ramp_s < pulse.dwell_s
    assert 0 < pulse.decel_ratio <= 1


@pytest.mark.parametrize("level", [0.01, 0.2, 1.0, 10.0 / 9.81])
def test_levels_up_to_the_bench_limit_of_10_mps2_are_accepted(level):
    assert PulseProfile(level).peak_mps2 <= 10.0 + 1e-9


@pytest.mark.parametrize("level", [0.0, -0.2, 1.03, 2.0, 5.0, math.nan, math.inf, -math.inf])
def test_levels_outside_the_bench_range_are_rejected(level, assert_input_error):
    with pytest.raises(InputError) as info:
        PulseProfile(level)
    assert_input_error(info.value, "profile", "level_g")


def test_level_range_quoted_in_the_message_is_accepted():
    with pytest.raises(InputError) as info:
        PulseProfile(5.0)
    upper = float(re.search(r"\(0, ([0-9.]+)\] g", str(info.value)).group(1))
    PulseProfile(upper)
    assert upper == 1.019          # 10 / 9.81 = 1.0194 g, rounded down


def test_a_level_given_in_mps2_is_named_as_such():
    """4.9 is no level in g, but 0.5 g in m/s²; 12 is neither, and gets no guess."""
    with pytest.raises(InputError, match=r"\(got 4\.9\): m/s²\? Levels are in g "
                                         r"\(4\.9 m/s² is 0\.50 g\)$"):
        PulseProfile(4.9)
    with pytest.raises(InputError, match=r"\(1\.5 m/s² is 0\.15 g\)$"):
        PulseProfile(1.5)
    with pytest.raises(InputError, match=r"\(got 12\.0\)$"):
        eumos_levels(12.0)


@pytest.mark.parametrize("dwell", [0.0, 0.1, 0.299, -1.0])
def test_dwell_shorter_than_eumos_minimum_is_rejected(dwell, assert_input_error):
    with pytest.raises(InputError) as info:
        PulseProfile(0.5, dwell_s=dwell)
    assert_input_error(info.value, "profile", "dwell_s")


def test_dwell_of_exactly_0_3_s_is_accepted():
    assert PulseProfile(0.5, dwell_s=0.3).dwell_s == 0.3


def test_nan_dwell_is_rejected():
    with pytest.raises(InputError):
        PulseProfile(0.5, dwell_s=math.nan)


@pytest.mark.parametrize("kwargs, field", [
    ({"ramp_s": -0.01}, "ramp_s"),
    ({"ramp_s": 0.6, "dwell_s": 0.5}, "ramp_s"),
    ({"decel_ratio": 0.0}, "decel_ratio"),
    ({"decel_ratio": 1.5}, "decel_ratio"),
])
def test_bad_ramp_or_deceleration_is_rejected(kwargs, field, assert_input_error):
    with pytest.raises(InputError) as info:
        PulseProfile(0.5, **kwargs)
    assert_input_error(info.value, "profile", field)


# --- EUMOS level sequence ------------------------------------------------------------------


def test_eumos_levels_default_from_0_2_g_in_steps_of_0_1_g():
    assert eumos_levels(0.5) == pytest.approx([0.2, 0.3, 0.4, 0.5])
    assert eumos_levels() == pytest.approx([0.2, 0.3, 0.4, 0.5])


def test_eumos_levels_from_0_3_g_up_to_0_8_g():
    assert eumos_levels(0.8, start_g=0.3) == pytest.approx([0.3, 0.4, 0.5, 0.6, 0.7, 0.8])


@pytest.mark.parametrize("target", [0.3, 0.4, 0.6, 0.7, 0.9, 1.0])
def test_eumos_levels_end_exactly_at_the_target(target):
    levels = eumos_levels(target)
    assert levels[0] == pytest.approx(0.2)
    assert levels[-1] == pytest.approx(target)
    assert np.allclose(np.diff(levels), 0.1)


def test_eumos_levels_end_at_a_target_between_steps():
    assert eumos_levels(0.45) == pytest.approx([0.2, 0.3, 0.4, 0.45])


def test_eumos_levels_every_level_can_be_run():
    for level in eumos_levels(1.0):
        peak = PulseProfile(level).peak_mps2
        assert peak == pytest.approx(level * 9.81) and peak <= 10.0


@pytest.mark.parametrize("target", [2.0, 1.1, 0.0, -0.5, math.nan])
def test_eumos_target_beyond_the_bench_is_rejected(target, assert_input_error):
    with pytest.raises(InputError) as info:
        eumos_levels(target)
    assert_input_error(info.value, "test sequence", "target_g")


@pytest.mark.parametrize("start", [0.0, 0.6, math.nan])
def test_eumos_start_outside_0_to_target_is_rejected(start, assert_input_error):
    with pytest.raises(InputError) as info:
        eumos_levels(0.5, start_g=start)
    assert_input_error(info.value, "test sequence", "start_g")


# --- measured profile.csv ------------------------------------------------------------------


def write_csv(tmp_path, text: str, name: str = "profile.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_profile_csv_with_time_and_acceleration_is_read(tmp_path):
    path = write_csv(tmp_path, "t_s,accel_mps2\n0.0,0.0\n0.1,2.0\n0.2,4.905\n0.3,0.0\n")
    profile = MeasuredProfile.from_csv(path)
    assert profile.t_s.tolist() == [0.0, 0.1, 0.2, 0.3]
    assert profile.accel_mps2.tolist() == [0.0, 2.0, 4.905, 0.0]
    assert profile.level_g == pytest.approx(4.905 / 9.81)
    assert profile.level_g == pytest.approx(0.5)
    assert profile.duration_s == pytest.approx(0.3)
    assert profile.source == str(path)


def test_a_profile_peaking_below_any_bench_level_is_suspected_to_be_in_g(tmp_path):
    """A 0.5 g test exported in g reads 0.5 m/s², 0.051 g: the file is taken as written, and
    the user is told why it looks wrong. A real 0.2 g test (1.96 m/s²) raises nothing."""
    in_g = MeasuredProfile.from_csv(write_csv(tmp_path, "t_s,accel_mps2\n0,0\n0.1,0.5\n0.6,0\n"))
    (warning,) = in_g.warnings()
    assert warning.startswith(str(tmp_path / "profile.csv"))
    assert "0.50 m/s² (0.051 g)" in warning and "in g?" in warning
    real = MeasuredProfile.from_csv(write_csv(tmp_path, "t_s,accel_mps2\n0,0\n0.1,1.962\n0.6,0\n",
                                              "real.csv"))
    assert real.warnings() == ()


def test_a_profile_that_brakes_harder_than_it_accelerates_is_questioned(tmp_path):
    """An accelerometer mounted the other way round turns a 0.5 g pulse into -4.9 m/s² and the
    gentle stop into the forward peak (1.2 m/s², reported as the level): the user is told."""
    path = write_csv(tmp_path, "t_s,accel_mps2\n0,0\n0.1,-4.9\n0.6,-4.9\n0.7,1.2\n2.7,1.2\n"
                               "2.8,0\n")
    (warning,) = MeasuredProfile.from_csv(path).warnings()
    assert warning.startswith(str(path))
    assert "brakes harder (4.90 m/s², 0.499 g) than it accelerates (1.20 m/s²)" in warning
    assert "negate the column" in warning


def test_a_profile_beyond_the_bench_s_10_m_s2_is_questioned_and_simulated_as_given(tmp_path):
    """The ESTL bench runs up to 10 m/s² (`--level` refuses more); a recording reaching 14.7
    (a spike, another bench) is warned about, not refused: up to twice that it may be real.
    A 1.0 g profile (9.81 m/s²) raises nothing."""
    path = write_csv(tmp_path, "t_s,accel_mps2\n0,0\n0.1,14.7\n0.6,14.7\n0.7,0\n")
    profile = MeasuredProfile.from_csv(path)
    (warning,) = profile.warnings()
    assert warning.startswith(str(path))
    assert "14.70 m/s², beyond the ESTL bench's 10 m/s²" in warning
    assert profile.level_g == pytest.approx(14.7 / G)
    top = MeasuredProfile.from_csv(write_csv(tmp_path, "t_s,accel_mps2\n0,0\n0.1,9.81\n0.6,0\n",
                                             "top.csv"))
    assert top.warnings() == ()


def test_profile_csv_with_velocity_and_position_columns_is_read(tmp_path):
    path = write_csv(tmp_path, "t_s,accel_mps2,vel_mps,pos_m\n"
                               "0.0,0.0,0.0,0.0\n0.5,3.0,0.75,0.19\n1.0,-1.0,1.25,0.7\n")
    profile = MeasuredProfile.from_csv(path)
    assert profile.accel_mps2.tolist() == [0.0, 3.0, -1.0]
    assert profile.level_g == pytest.approx(3.0 / G)


def test_profile_csv_columns_may_come_in_any_order_with_spaces(tmp_path):
    path = write_csv(tmp_path, "vel_mps, accel_mps2 , t_s\n0,0,0\n0,2.5,0.1\n0,0,0.2\n")
    profile = MeasuredProfile.from_csv(path)
    assert profile.t_s.tolist() == [0.0, 0.1, 0.2]
    assert profile.peak_mps2 == 2.5


def test_profile_csv_time_may_start_later_than_zero(tmp_path):
    path = write_csv(tmp_path, "t_s,accel_mps2\n2.0,0.0\n2.1,3.0\n2.2,0.0\n")
    profile = MeasuredProfile.from_csv(path)
    # The profile is replayed from its first sample: t = 0 is the first row.
    assert float(profile.accel(0.1)) == pytest.approx(3.0)
    assert float(profile.accel(0.05)) == pytest.approx(1.5)
    assert float(profile.accel(0.3)) == 0.0
    assert float(profile.accel(-0.1)) == 0.0
    assert profile.duration_s == pytest.approx(0.2)


def test_profile_csv_saved_by_excel_with_a_byte_order_mark_is_read(tmp_path):
    path = tmp_path / "profile.csv"
    path.write_bytes("\ufefft_s,accel_mps2\r\n0,0\r\n0.1,2.0\r\n0.2,0\r\n".encode())
    assert MeasuredProfile.from_csv(path).accel_mps2.tolist() == [0.0, 2.0, 0.0]


def test_profile_csv_blank_lines_are_skipped(tmp_path):
    path = write_csv(tmp_path, "t_s,accel_mps2\n0,0\n\n0.1,1.0\n0.2,0\n\n")
    assert len(MeasuredProfile.from_csv(path).t_s) == 3


def test_a_pulse_written_as_csv_reads_back_at_its_level(tmp_path):
    pulse = PulseProfile(0.4)
    t = np.arange(0.0, pulse.duration_s + 0.01, 0.001)
    rows = "".join(f"{ti:.4f},{ai:.6f}\n" for ti, ai in zip(t, pulse.accel(t), strict=True))
    profile = MeasuredProfile.from_csv(write_csv(tmp_path, "t_s,accel_mps2\n" + rows))
    assert profile.level_g == pytest.approx(0.4, abs=1e-5)


BAD_CSVS = {
    # id: (file text, expected field)
    "empty file": ("", ""),
    "header only": ("t_s,accel_mps2\n", "t_s"),
    "one sample": ("t_s,accel_mps2\n0,1.0\n", "t_s"),
    "missing acceleration column": ("t_s,vel_mps\n0,0\n0.1,1\n", "accel_mps2"),
    "missing time column": ("time,accel_mps2\n0,0\n0.1,1\n", "t_s"),
    "misspelt header": ("t_s,accel\n0,0\n0.1,1\n", "accel_mps2"),
    "no header": ("0.0,0.0\n0.1,1.0\n", "t_s"),
    "non-numeric row": ("t_s,accel_mps2\n0,0\n0.1,fast\n0.2,0\n", "line 3"),
    "short row": ("t_s,accel_mps2\n0,0\n0.1\n0.2,0\n", "line 3"),
    "time going back": ("t_s,accel_mps2\n0,0\n0.2,1\n0.1,0\n", "t_s"),
    "time repeated": ("t_s,accel_mps2\n0,0\n0.1,1\n0.1,0\n", "t_s"),
    "nan acceleration": ("t_s,accel_mps2\n0,0\n0.1,nan\n0.2,0\n", "accel_mps2"),
    "infinite acceleration": ("t_s,accel_mps2\n0,0\n0.1,inf\n0.2,0\n", "accel_mps2"),
    "no forward acceleration": ("t_s,accel_mps2\n0,0\n0.1,-1\n0.2,0\n", "accel_mps2"),
    "acceleration beyond any bench": ("t_s,accel_mps2\n0,0\n0.1,98.1\n0.2,0\n", "accel_mps2"),
    "times in milliseconds": ("t_s,accel_mps2\n0,0\n1500,4.9\n3000,0\n", "t_s"),
    "a logger left running 2.5 minutes": ("t_s,accel_mps2\n0,0\n0.5,4.9\n150,0\n", "t_s"),
    "a spike of 2.5 x the bench's peak": ("t_s,accel_mps2\n0,0\n0.1,25\n0.2,0\n",
                                           "accel_mps2"),
}


@pytest.mark.parametrize("text, field", BAD_CSVS.values(), ids=BAD_CSVS.keys())
def test_bad_profile_csv_is_rejected_naming_file_and_field(text, field, tmp_path,
                                                           assert_input_error):
    path = write_csv(tmp_path, text)
    with pytest.raises(InputError) as info:
        MeasuredProfile.from_csv(path)
    assert_input_error(info.value, str(path), field)


def test_a_logger_left_running_a_minute_is_a_measured_profile(tmp_path):
    """simulate --profile took 30 s, a recording's profile (`track`, `calibrate`) 120 s: the
    same file was refused by one command and taken by the other two. One bound now."""
    lines = ["t_s,accel_mps2", "0,0", "0.5,4.9", "1.0,0"] + [f"{t},0" for t in range(2, 61)]
    path = write_csv(tmp_path, "\n".join(lines) + "\n")
    assert MeasuredProfile.from_csv(path).t_s[-1] == 60
    # what counts is the span: a logger whose clock read 100 s at the first row
    late = write_csv(tmp_path, "\n".join(
        ["t_s,accel_mps2", "100,0", "100.5,4.9", "101.0,0", "160,0"]) + "\n")
    assert MeasuredProfile.from_csv(late).duration_s == pytest.approx(60.0)


def test_missing_profile_csv_is_rejected_naming_the_file(tmp_path, assert_input_error):
    path = tmp_path / "no_profile.csv"
    with pytest.raises(InputError, match="cannot read") as info:
        MeasuredProfile.from_csv(path)
    assert_input_error(info.value, str(path), "")


def test_nan_time_is_rejected(tmp_path):
    path = write_csv(tmp_path, "t_s,accel_mps2\n0,0\nnan,1\n0.2,0\n")
    with pytest.raises(InputError, match="NaN"):
        MeasuredProfile.from_csv(path)


def test_nan_time_is_reported_in_the_time_column(tmp_path, assert_input_error):
    path = write_csv(tmp_path, "t_s,accel_mps2\n0,0\nnan,1\n0.2,0\n")
    with pytest.raises(InputError) as info:
        MeasuredProfile.from_csv(path)
    assert_input_error(info.value, str(path), "t_s")


def test_a_target_below_the_usual_start_is_a_sequence_of_one_level():
    assert eumos_levels(0.1) == [0.1]
    assert eumos_levels(0.5) == [0.2, 0.3, 0.4, 0.5]


def test_a_target_below_the_standard_s_first_level_is_run_and_warned_of():
    """Its pass is no pass of EUMOS 40509 (a new user read one as such)."""
    assert target_warnings(0.1) == ("a target of 0.1 g lies below EUMOS 40509's first level "
                                    "(0.2 g): the sequence is that one level, a check short of "
                                    "the standard",)
    assert target_warnings(0.2) == target_warnings(0.5) == ()
